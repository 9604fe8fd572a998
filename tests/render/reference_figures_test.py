#!/usr/bin/env python3
"""Each figure kind, drawn by `moreau` for a mechanical, an impacting, a Lur'e, a URDF, a tracking and a
campaign scene, against its reference image in tests/render/reference/: a layout regression (a panel
lost, an axis label moved, a legend over the data, a series drawn in another colour) changes many pixels
and fails; anti-aliasing and sub-pixel differences change few and pass.

    reference_figures_test.py MOREAU SOURCE_DIR            check (exit 1 naming each figure that differs)
    reference_figures_test.py MOREAU SOURCE_DIR --update   write the references anew (look at them first)

A figure differs when more than 0.2 % of its pixels differ by more than 64 (of 255) in some channel, or
its size differs. With MOREAU_FIGURE_DIFF_DIR set, the figures drawn and their differences are written
there for a person to look at.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image

SIZE = "600x400"
# (scene, kinds): each scene's figures at SIZE.
RUNS = [
    ("manipulator-fig6.4.json", ["state", "energy", "step", "phase"]),  # mechanical, with units
    ("bouncing-ball-e0.5.json", ["state", "energy"]),                    # impacts: the mechanical energy's staircase
    ("lure-relay-2state.json", ["state", "phase"]),                      # Lur'e: outputs, the switching line
    ("iiwa14-joint-limit.json", ["state"]),                              # URDF
    ("manipulator-tracking-digital.json", ["tracking"]),                 # tracking
]
THRESHOLD, MAX_FRACTION = 64, 0.002


def draw(moreau, source, out):
    """Draws every figure of RUNS and the campaign's convergence CDF into `out`: {name: path}."""
    paths = {}
    for scene, kinds in RUNS:
        args = [moreau, "run", str(source / "scenes" / scene), "--progress", "never", "--size", SIZE]
        for kind in kinds:
            path = out / ("%s-%s.png" % (scene[:-5], kind))
            args += ["--figure", "%s=%s" % (kind, path)]
            paths[path.name] = path
        subprocess.run(args, check=True, capture_output=True)
    # A campaign: 32 samples of the manipulator's robustness spec.
    spec = json.loads((source / "campaigns" / "manipulator-robust.json").read_text())
    spec["samples"] = 32
    spec["scene"] = str((source / "campaigns" / spec["scene"]).resolve())
    (out / "spec.json").write_text(json.dumps(spec))
    subprocess.run([moreau, "campaign", str(out / "spec.json"), "--out", str(out / "campaign"), "-j", "1", "--quiet"],
                   check=True, capture_output=True)
    cdf = out / "campaign" / "figures" / "convergence-cdf.png"
    small = out / "campaign-convergence-cdf.png"
    Image.open(cdf).convert("RGB").resize((600, 400), Image.LANCZOS).save(small)  # the campaign's own size, scaled
    paths[small.name] = small
    return paths


def pixels(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)


def main():
    moreau, source = sys.argv[1], pathlib.Path(sys.argv[2])
    update = "--update" in sys.argv[3:]
    reference_dir = source / "tests" / "render" / "reference"
    diff_dir = os.environ.get("MOREAU_FIGURE_DIFF_DIR")
    with tempfile.TemporaryDirectory(prefix="moreau-figures-") as tmp:
        paths = draw(moreau, source, pathlib.Path(tmp))
        if update:
            reference_dir.mkdir(parents=True, exist_ok=True)
            for name, path in sorted(paths.items()):
                shutil.copy(path, reference_dir / name)
            print("wrote %d references in %s" % (len(paths), reference_dir))
            return 0
        failures = []
        for name, path in sorted(paths.items()):
            reference = reference_dir / name
            if not reference.exists():
                failures.append("%s: no reference image (run with --update)" % name)
                continue
            a, b = pixels(path), pixels(reference)
            if a.shape != b.shape:
                failures.append("%s: %dx%d, the reference is %dx%d" % (name, a.shape[1], a.shape[0], b.shape[1], b.shape[0]))
                continue
            far = (np.abs(a - b).max(axis=2) > THRESHOLD)
            fraction = float(far.mean())
            if fraction > MAX_FRACTION:
                failures.append("%s: %.2f %% of the pixels differ by more than %d" % (name, 100 * fraction, THRESHOLD))
            if diff_dir:
                os.makedirs(diff_dir, exist_ok=True)
                shutil.copy(path, os.path.join(diff_dir, name))
                Image.fromarray((far * 255).astype(np.uint8)).save(os.path.join(diff_dir, "diff-" + name))
        checked = len(paths)
    for f in failures:
        print("figure differs: " + f)
    print("%d passed, %d failed" % (checked - len(failures), len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
