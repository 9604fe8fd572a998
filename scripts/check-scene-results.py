#!/usr/bin/env python3
"""Runs every shipped scene (scenes/*.json) with `moreau run` and compares what it produces with the
reference results checked in under tests/scene/results/: the report, apart from its wall-clock timings,
and the SHA-256 of the trajectory CSV (numbers written shortest-round-trip, so equal hashes mean equal
doubles, bit for bit).

The references were produced by the code as it was before a change; a change meant to keep behaviour
(a refactor, an optimisation) must leave them all equal. A change meant to alter results regenerates
them with --update and says why in its commit.

  scripts/check-scene-results.py [--moreau build/client/moreau] [--update] [SCENE ...]

Exit status 0 when every scene matches, 1 when one differs (each difference is printed, as JSON
pointers), 2 on a usage error or when `moreau` fails.
"""
import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REFERENCE_DIR = os.path.join(ROOT, "tests", "scene", "results")

# Report fields that measure the machine rather than the result: left out of the comparison.
TIMING_KEYS = {"phase_seconds", "wall_seconds"}


def without_timings(value):
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k not in TIMING_KEYS}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def differences(expected, actual, pointer=""):
    """JSON pointers where the two values differ (floats compared exactly: same bits or not)."""
    if isinstance(expected, dict) and isinstance(actual, dict):
        out = []
        for k in sorted(set(expected) | set(actual)):
            p = pointer + "/" + k.replace("~", "~0").replace("/", "~1")
            if k not in actual:
                out.append(f"{p}: missing (expected {json.dumps(expected[k])[:80]})")
            elif k not in expected:
                out.append(f"{p}: new field ({json.dumps(actual[k])[:80]})")
            else:
                out += differences(expected[k], actual[k], p)
        return out
    if isinstance(expected, list) and isinstance(actual, list):
        if len(expected) != len(actual):
            return [f"{pointer}: {len(actual)} entries, expected {len(expected)}"]
        out = []
        for i, (e, a) in enumerate(zip(expected, actual)):
            out += differences(e, a, f"{pointer}/{i}")
        return out
    if type(expected) is not type(actual) or expected != actual:
        return [f"{pointer or '/'}: {json.dumps(actual)[:80]}, expected {json.dumps(expected)[:80]}"]
    return []


def run_scene(moreau, scene_path, work_dir):
    csv_path = os.path.join(work_dir, "trajectory.csv")
    proc = subprocess.run([moreau, "run", scene_path, "--json", "--progress", "never", "--out", csv_path],
                          capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f"moreau run {scene_path} exited {proc.returncode}: {proc.stderr.strip()}")
    report = json.loads(proc.stdout)
    with open(csv_path, "rb") as f:
        data = f.read()
    return {
        "report": without_timings(report),
        "trajectory": {"sha256": hashlib.sha256(data).hexdigest(), "rows": data.count(b"\n") - 1},
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moreau", default=os.path.join(ROOT, "build", "client", "moreau"))
    ap.add_argument("--update", action="store_true", help="write the references instead of comparing")
    ap.add_argument("scenes", nargs="*", help="scene files (default: every scenes/*.json)")
    args = ap.parse_args()
    if not os.access(args.moreau, os.X_OK):
        print(f"check-scene-results: no moreau binary at {args.moreau}", file=sys.stderr)
        return 2
    scenes = args.scenes or sorted(
        os.path.join(ROOT, "scenes", n) for n in os.listdir(os.path.join(ROOT, "scenes")) if n.endswith(".json"))

    failed = 0
    with tempfile.TemporaryDirectory() as work_dir:
        for scene in scenes:
            name = os.path.splitext(os.path.basename(scene))[0]
            ref_path = os.path.join(REFERENCE_DIR, name + ".json")
            try:
                actual = run_scene(args.moreau, scene, work_dir)
            except (RuntimeError, ValueError, subprocess.TimeoutExpired) as e:
                print(f"{name}: {e}", file=sys.stderr)
                return 2
            if args.update:
                os.makedirs(REFERENCE_DIR, exist_ok=True)
                with open(ref_path, "w") as f:
                    json.dump(actual, f, indent=1, sort_keys=True)
                    f.write("\n")
                print(f"{name}: reference written ({actual['trajectory']['rows']} rows)")
                continue
            if not os.path.exists(ref_path):
                print(f"{name}: no reference {os.path.relpath(ref_path, ROOT)} (run with --update to make one)")
                failed += 1
                continue
            with open(ref_path) as f:
                expected = json.load(f)
            diff = differences(expected, actual)
            if diff:
                failed += 1
                print(f"{name}: DIFFERS from {os.path.relpath(ref_path, ROOT)}")
                for d in diff[:20]:
                    print("  " + d)
                if len(diff) > 20:
                    print(f"  ... and {len(diff) - 20} more")
            else:
                print(f"{name}: same report and trajectory ({actual['trajectory']['rows']} rows)")
    if not args.update:
        print(f"{len(scenes) - failed} of {len(scenes)} scenes match their references")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
