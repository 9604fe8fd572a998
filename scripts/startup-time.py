#!/usr/bin/env python3
"""Whole-process start-up of `moreau`: each command 20 times, the median (min to max) wall time and the
peak resident size (/usr/bin/time). Run from the source tree:

  python3 scripts/startup-time.py [build/client/moreau]

Results: README.md, "Performance".
"""
import statistics
import subprocess
import sys
import tempfile
import time
binary = sys.argv[1] if len(sys.argv) > 1 else "build/client/moreau"
def measure(args, n=20):
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        subprocess.run([binary] + args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        ts.append((time.perf_counter() - t) * 1e3)
    return statistics.median(ts), min(ts), max(ts)
def rss(args):
    r = subprocess.run(["/usr/bin/time", "-f", "%M", binary] + args, capture_output=True, text=True)
    return int(r.stderr.strip().splitlines()[-1]) / 1024
for name, args in [("--version", ["--version"]),
                   ("run damped-relay (no figure)", ["run", "scenes/damped-relay.json"]),
                   ("run manipulator (no figure)", ["run", "scenes/manipulator.json"]),
                   ("run manipulator + PNG figure", ["run", "scenes/manipulator.json", "--figure", "state=" + tempfile.gettempdir() + "/moreau-startup-figure.png"])]:
    med, lo, hi = measure(args)
    print(f"| {name} | {med:.1f} ms | {lo:.1f} to {hi:.1f} ms | {rss(args):.1f} MiB |")
