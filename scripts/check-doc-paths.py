#!/usr/bin/env python3
"""Fails when a Markdown file names a repository path that does not exist.

    check-doc-paths.py REPO_ROOT DOC.md [DOC.md ...]

DOC paths are taken relative to REPO_ROOT unless absolute. Three kinds of token are checked, in prose,
in backticks and in code blocks alike:

  - a repository path: a token that starts with a top-level folder of the repository (core/, expr/,
    scene/, analysis/, ..., docs/, scripts/; the fixed list below plus every top-level folder present),
    e.g. `scene/input/json_input.cc`, scripts/fuzz.sh, server/web/. It must exist relative to REPO_ROOT
    (a directory when it ends in '/'). `*` is a glob that must match something; from a `<placeholder>` or
    `{a,b}` on, only the folder before it is checked (fuzz/corpus/<corpus>: fuzz/corpus/).
  - an include path: `moreau/<part>/<name>.h` (or `moreau/<name>.h`), which must be <top>/include/<token>
    for some top-level folder, e.g. moreau/scene/scene.h -> scene/include/moreau/scene/scene.h.
  - a bare file name in backticks with a source or documentation extension, e.g. `lagrangian_compiler.cc`:
    a file of that name must exist somewhere in the repository (build trees, .git and node_modules aside).

Not checked: URLs and anything else preceded by '/', ':' or a word character (so JSON pointers such as
/integrator/h or /scene/integrator/h are never taken for paths), and build artefacts (build/...).
Exit status: 0 when every path exists, 1 when one does not (each listed with its line), 2 on bad usage.
"""
import glob
import os
import re
import sys

# Top-level folders a document may name, whether or not they exist now: a folder that is removed or
# renamed must still be caught. Every top-level folder present is added at run time.
KNOWN_TOP = {
    ".ci", "analysis", "bench", "campaigns", "client", "clients", "cmake", "core", "docker", "docs", "expr",
    "fuzz", "messages", "platform", "python", "render", "scene", "scenes", "scripts", "server", "tests",
}
# Extensions of files a bare backticked name is checked for (longest first: .cc.in before .in).
FILE_EXTENSIONS = (".cc.in", ".h", ".hpp", ".cc", ".cpp", ".py", ".sh", ".mjs", ".js", ".md", ".cmake", ".lcm", ".supp", ".in")
SKIP_DIRS = {".git", "node_modules", "__pycache__"}

PATH_CHARS = r"[A-Za-z0-9_.\-/*<>{},+]"


def top_level_folders(root):
    found = set()
    for entry in os.scandir(root):
        if entry.is_dir() and not entry.name.startswith("build") and entry.name not in SKIP_DIRS:
            found.add(entry.name)
    return KNOWN_TOP | found


def repository_files(root):
    """Every file's path relative to root, with '/' separators (build trees, .git and node_modules aside)."""
    files = []
    for dirpath, dirnames, filenames in os.walk(root):
        rel = os.path.relpath(dirpath, root)
        dirnames[:] = [d for d in dirnames if d not in SKIP_DIRS and not (rel == "." and d.startswith("build"))]
        prefix = "" if rel == "." else rel.replace(os.sep, "/") + "/"
        files.extend(prefix + name for name in filenames)
    return files


def strip_token(token):
    # Punctuation after a path: "see docs/api.md." or "(scene/input/, run/)"; a closing > or } only when
    # the token has no opening one.
    while token:
        if token[-1] in ".,;:)" or (token[-1] == ">" and "<" not in token) or (token[-1] == "}" and "{" not in token):
            token = token[:-1]
        else:
            break
    return token


def check_repo_path(root, token):
    """None when the path exists, else why not."""
    cut = len(token)
    for mark in "<{":
        if mark in token:
            cut = min(cut, token.index(mark))
    if cut < len(token):
        prefix = token[:cut]
        folder = prefix[: prefix.rfind("/") + 1] if "/" in prefix else prefix
        return None if os.path.isdir(os.path.join(root, folder)) else "no such folder " + folder
    if "*" in token:
        return None if glob.glob(os.path.join(root, token)) else "matches nothing"
    full = os.path.join(root, token)
    if token.endswith("/"):
        return None if os.path.isdir(full) else "no such folder"
    return None if os.path.exists(full) else "no such file or folder"


def check_include_path(root, tops, token):
    for top in tops:
        if os.path.isfile(os.path.join(root, top, "include", token)):
            return None
    return "no <part>/include/" + token


def scan(root, doc_path):
    tops = top_level_folders(root)
    top_alt = "|".join(sorted((re.escape(t) for t in tops), key=len, reverse=True))
    # A repository path: a top-level folder and '/', not preceded by anything that makes it part of a
    # longer path, a URL or a JSON pointer.
    repo_re = re.compile(r"(?<![A-Za-z0-9_./\-~:$@])((?:%s)/%s*)" % (top_alt, PATH_CHARS))
    top_re = re.compile(r"^(?:%s)/" % top_alt)
    include_re = re.compile(r"(?<![A-Za-z0-9_./\-~:$@])(moreau/(?:[A-Za-z0-9_]+/)*[A-Za-z0-9_]+\.h)\b")
    # A file named in backticks without its top-level folder: `lagrangian_compiler.cc`, `models/manipulator.h`.
    bare_re = re.compile(r"`([A-Za-z0-9_\-][A-Za-z0-9_\-./]*\.[A-Za-z0-9_]+)`")
    # A list item that opens with a folder in bold (- **scene/** ...) makes that folder the context of the
    # item: the files it names without a folder must be inside it. An indented item may name a folder
    # inside its parent's (  - **input/** under - **scene/**).
    item_re = re.compile(r"^(\s*)[-*+]\s+(?:\*\*`?([A-Za-z0-9_.\-/]+/)`?\*\*)?")
    files = None
    missing, checked = [], 0
    outer = context = None
    with open(doc_path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    for number, line in enumerate(lines, 1):
        item = item_re.match(line)
        if not line.strip() or line.startswith("#"):
            outer = context = None
        elif item:
            indented, folder = bool(item.group(1)), item.group(2)
            folder = folder.rstrip("/") if folder else None
            if folder and top_re.match(folder + "/"):
                context = folder
                if not indented:
                    outer = folder
            elif folder and indented and outer:
                context = outer + "/" + folder
            else:
                context = outer if indented else None
                if not indented:
                    outer = None
        for m in repo_re.finditer(line):
            token = strip_token(m.group(1))
            if "/" not in token:
                continue
            checked += 1
            why = check_repo_path(root, token)
            if why:
                missing.append((number, token, why))
        for m in include_re.finditer(line):
            checked += 1
            why = check_include_path(root, tops, m.group(1))
            if why:
                missing.append((number, m.group(1), why))
        for m in bare_re.finditer(line):
            name = m.group(1)
            if not name.endswith(FILE_EXTENSIONS) or top_re.match(name) or name.startswith("moreau/"):
                continue
            if files is None:
                files = repository_files(root)
            checked += 1
            scope = context + "/" if context else ""
            if not any(f.startswith(scope) and (f == scope + name or f.endswith("/" + name)) for f in files):
                missing.append((number, name, ("no such file under " + scope) if scope else "no file of this name in the repository"))
    return checked, missing


def main(argv):
    if len(argv) < 3:
        print(__doc__.strip().split("\n\n")[1], file=sys.stderr)
        return 2
    root = os.path.abspath(argv[1])
    if not os.path.isdir(root):
        print(f"check-doc-paths: {root} is not a folder", file=sys.stderr)
        return 2
    status = 0
    for doc in argv[2:]:
        path = doc if os.path.isabs(doc) else os.path.join(root, doc)
        try:
            checked, missing = scan(root, path)
        except OSError as e:
            print(f"check-doc-paths: cannot read {doc}: {e.strerror}", file=sys.stderr)
            return 2
        if checked == 0:
            print(f"{doc}: names no repository path (nothing to check)", file=sys.stderr)
            status = 1
        for number, token, why in missing:
            print(f"{doc}:{number}: {token}: {why}")
        if missing:
            status = 1
        print(f"{doc}: {checked} paths checked, {len(missing)} missing", file=sys.stderr if missing else sys.stdout)
    return status


if __name__ == "__main__":
    sys.exit(main(sys.argv))
