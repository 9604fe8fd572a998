#!/usr/bin/env python3
"""Fails when a report excerpt in the documentation is not what its command prints.

    check-doc-reports.py [--moreau PATH] [--root DIR] [DOC.md ...]

Every sentence of the documentation that says what a report prints (`moreau run`, `moreau study`,
`moreau campaign`, `moreau stress`, `moreau inspect`) is written next to a checked excerpt: an HTML
comment naming the command, immediately followed by a fenced block of lines copied from its output,

    <!-- checked: moreau run scenes/damped-relay.json -->
    ```text
    ...
      status        completed: ...
    ```

This script runs each such command and checks the block against what it prints. DOCs default to
README.md and docs/*.md under --root (the repository root, default: the folder above this script's).

  - The command is split as a shell would split it (shlex) but run without a shell, with the repository
    root as working directory; its first word must be `moreau`, which stands for --moreau PATH (default
    ROOT/build/client/moreau). `{tmp}` in an argument stands for a fresh empty temporary directory,
    removed afterwards (for commands that must write somewhere, such as `moreau campaign --out`).
    Each command has 120 s; a command named twice runs once.
  - The command must exit 0, or with N for `<!-- checked(exit=N): ... -->` (an expected failure).
  - Every non-blank line of the block must match a whole line of the command's output (its stdout, then
    its stderr: apart, so that a buffered stdout cannot be cut mid-line by a message on stderr), in
    order: each line a later output line than the previous one's match, so
    an excerpt may leave out lines anywhere. Runs of whitespace compare equal to one space, and leading
    and trailing whitespace is ignored. `...` inside a line matches any text (for wall-clock times, paths
    and the parts of a line that are not the point); a line that is exactly `...` marks left-out lines
    for the reader and matches nothing itself.

Exit status: 0 when every excerpt matches (the count of excerpts and commands is printed); 1 when one
does not (each mismatch with its file, line, command, the excerpt line not found and the closest output
lines), when a command exits otherwise than allowed or runs out of time, or when a `<!-- checked`
comment is malformed or not followed by a fenced block; 2 on bad usage.
"""
import argparse
import difflib
import glob
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

TIMEOUT_SECONDS = 120
COMMENT_RE = re.compile(r"^\s*<!--\s*checked(?:\(exit=(\d+)\))?:\s*(.*?)\s*-->\s*$")
FENCE_RE = re.compile(r"^\s{0,3}(`{3,}|~{3,})")
WHITESPACE_RE = re.compile(r"\s+")


class Excerpt:
    def __init__(self, doc, line, command, exit_code, lines):
        self.doc = doc            # the document's path relative to the root
        self.line = line          # line number of the comment
        self.command = command    # the command as written
        self.exit_code = exit_code
        self.lines = lines        # [(line number, text)] of the block's non-blank lines


def normalize(text):
    return WHITESPACE_RE.sub(" ", text).strip()


def pattern_of(excerpt_line):
    """The regular expression a whole (normalized) output line must match."""
    parts = normalize(excerpt_line).split("...")
    return re.compile(".*".join(re.escape(p) for p in parts), re.DOTALL)


def parse_doc(root, doc):
    """The excerpts of one document and the errors of its `<!-- checked` comments."""
    excerpts, errors = [], []
    with open(os.path.join(root, doc), encoding="utf-8") as f:
        lines = f.read().split("\n")
    i = 0
    while i < len(lines):
        line = lines[i]
        if "<!-- checked" not in line:
            i += 1
            continue
        number = i + 1
        m = COMMENT_RE.match(line)
        if not m or not m.group(2):
            errors.append(f"{doc}:{number}: malformed comment (expected `<!-- checked: moreau ... -->` or "
                          f"`<!-- checked(exit=N): moreau ... -->` on one line): {line.strip()}")
            i += 1
            continue
        exit_code = int(m.group(1)) if m.group(1) else 0
        command = m.group(2)
        fence = FENCE_RE.match(lines[i + 1]) if i + 1 < len(lines) else None
        if not fence:
            errors.append(f"{doc}:{number}: `<!-- checked: {command} -->` is not immediately followed by a "
                          f"fenced block (``` on the next line)")
            i += 1
            continue
        marker = fence.group(1)
        body, j = [], i + 2
        while j < len(lines):
            closing = FENCE_RE.match(lines[j])
            if closing and closing.group(1)[0] == marker[0] and len(closing.group(1)) >= len(marker) \
                    and not lines[j].strip()[len(closing.group(1)):].strip():
                break
            if lines[j].strip():
                body.append((j + 1, lines[j]))
            j += 1
        if j == len(lines):
            errors.append(f"{doc}:{number}: the fenced block after `<!-- checked: {command} -->` is not closed")
            break
        if not [text for _, text in body if normalize(text) != "..."]:
            errors.append(f"{doc}:{number}: the fenced block after `<!-- checked: {command} -->` checks nothing")
        excerpts.append(Excerpt(doc, number, command, exit_code, body))
        i = j + 1
    return excerpts, errors


def run(moreau, root, command):
    """(exit status or None, output lines, error) of one command."""
    try:
        argv = shlex.split(command)
    except ValueError as e:
        return None, [], f"cannot split the command: {e}"
    if not argv or argv[0] != "moreau":
        return None, [], "the command must start with `moreau`"
    tmp = None
    if any("{tmp}" in a for a in argv):
        tmp = tempfile.mkdtemp(prefix="check-doc-reports-")
        argv = [a.replace("{tmp}", tmp) for a in argv]
    argv[0] = moreau
    try:
        done = subprocess.run(argv, cwd=root, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, timeout=TIMEOUT_SECONDS)
    except subprocess.TimeoutExpired:
        return None, [], f"did not finish within {TIMEOUT_SECONDS} s"
    except OSError as e:
        return None, [], f"cannot run {moreau}: {e.strerror}"
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    output = done.stdout.decode("utf-8", "replace").split("\n") + done.stderr.decode("utf-8", "replace").split("\n")
    return done.returncode, output, None


def check(excerpt, output):
    """None when the excerpt matches the output, else the message."""
    normalized = [normalize(line) for line in output]
    position = 0  # the first output line the next excerpt line may match
    for number, text in excerpt.lines:
        if normalize(text) == "...":
            continue
        pattern = pattern_of(text)
        found = next((k for k in range(position, len(normalized)) if pattern.fullmatch(normalized[k])), None)
        if found is not None:
            position = found + 1
            continue
        where = "after the output line matched by the excerpt line before it" if position else "in the output"
        message = [f"{excerpt.doc}:{number}: not found {where}",
                   f"  command: {excerpt.command}",
                   f"  excerpt: {normalize(text)}"]
        candidates = [line for line in normalized[position:] if line] or [line for line in normalized if line]
        close = difflib.get_close_matches(normalize(text), candidates, n=3, cutoff=0.0)
        for line in close:
            message.append(f"  closest: {line}")
        if not close:
            message.append("  (the command printed nothing)")
        return "\n".join(message)
    return None


def main(argv):
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.strip().split("\n\n")[0])
    parser.add_argument("--moreau", help="the moreau binary (default: ROOT/build/client/moreau)")
    parser.add_argument("--root", default=os.path.dirname(here), help="the repository root")
    parser.add_argument("docs", nargs="*", help="documents relative to the root (default: README.md docs/*.md)")
    args = parser.parse_args(argv[1:])
    root = os.path.abspath(args.root)
    moreau = os.path.abspath(args.moreau) if args.moreau else os.path.join(root, "build", "client", "moreau")
    if not os.path.isdir(root):
        print(f"check-doc-reports: {root} is not a folder", file=sys.stderr)
        return 2
    if not os.access(moreau, os.X_OK):
        print(f"check-doc-reports: {moreau} is not an executable (give --moreau PATH)", file=sys.stderr)
        return 2
    docs = args.docs or (["README.md"] if os.path.isfile(os.path.join(root, "README.md")) else []) + \
        sorted(os.path.relpath(p, root) for p in glob.glob(os.path.join(root, "docs", "*.md")))

    excerpts, failures = [], []
    for doc in docs:
        try:
            found, errors = parse_doc(root, doc)
        except OSError as e:
            print(f"check-doc-reports: cannot read {doc}: {e.strerror}", file=sys.stderr)
            return 2
        excerpts += found
        failures += errors

    results = {}  # command -> (exit status, output lines, error)
    for excerpt in excerpts:
        if excerpt.command not in results:
            results[excerpt.command] = run(moreau, root, excerpt.command)
        status, output, error = results[excerpt.command]
        if error:
            failures.append(f"{excerpt.doc}:{excerpt.line}: {excerpt.command}: {error}")
            continue
        if status != excerpt.exit_code:
            tail = "\n".join("  | " + line for line in output[-6:] if line.strip())
            failures.append(f"{excerpt.doc}:{excerpt.line}: {excerpt.command}: exit status {status}, "
                            f"expected {excerpt.exit_code}\n{tail}")
            continue
        mismatch = check(excerpt, output)
        if mismatch:
            failures.append(mismatch)

    for failure in failures:
        print(failure)
    files = len({e.doc for e in excerpts})
    print(f"check-doc-reports: {len(excerpts)} excerpts in {files} documents, {len(results)} commands run: "
          + (f"{len(failures)} failed" if failures else "every excerpt is what its command prints"))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
