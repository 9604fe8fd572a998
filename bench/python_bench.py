#!/usr/bin/env python3
"""The Python module's figures (docs/python.md, "Performance"), each against its reference:

  run        moreau.run of the paper's manipulator (10,000 steps): the best of N runs of a loaded scene, and
             of load + run, against the integrate phase `moreau run --json` reports (its best of N)
  remote     the same run end to end through the HTTP client (moreau.Client(url).run: submit, wait, the
             report and the .npy trajectory) on a moreau-server on 127.0.0.1, against moreau.run
  table      a 1,000,000-row trajectory in process: the whole call against the run's own integrate phase
             (what is left is the cost of handing the table to numpy)
  threads    two runs on two threads against one run alone (wall time)
  sweep      1,000 values of a parameter in a Python loop against `moreau campaign --scene --vary -j 1`

Run it from the source tree after building:
    PYTHONPATH=build/python python3 bench/python_bench.py --moreau build/client/moreau \
        --server build/server/moreau-server
It prints one line per figure. Timing uses time.perf_counter and the best of several repeats.
"""

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import tempfile
import sys
import threading
import time

import moreau

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests" / "support"))
from server_process import ServerProcess  # noqa: E402  (a server on 127.0.0.1, stopped at the end)


def best(fn, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--moreau", default="build/client/moreau")
    p.add_argument("--source-dir", default=".")
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--server", default="build/server/moreau-server")
    p.add_argument("--only", default="run,remote,table,threads,sweep")
    a = p.parse_args()
    src = pathlib.Path(a.source_dir)
    manipulator = src / "scenes" / "manipulator.json"
    only = a.only.split(",")

    if "run" in only:
        cli = []
        for _ in range(a.repeats):
            out = subprocess.run([a.moreau, "run", str(manipulator), "--json", "--progress", "never"], capture_output=True, check=True)
            cli.append(dict(json.loads(out.stdout)["phase_seconds"])["integrate"])
        scene = moreau.load(manipulator)
        loaded = best(scene.run, a.repeats)
        whole = best(lambda: moreau.run(manipulator), a.repeats)
        print("run      manipulator, 10,000 steps: moreau.run %.3f ms (loaded scene: %.3f ms); the CLI's integrate phase %.3f ms; ratio %.2f"
              % (whole * 1e3, loaded * 1e3, min(cli) * 1e3, loaded / min(cli)))

    if "remote" in only:
        local = best(lambda: moreau.run(manipulator), a.repeats)
        with ServerProcess(a.server, str(src / "scenes")) as server:
            client = moreau.Client(server.url)
            client.run(manipulator)  # the first: connections, the server's scene cache
            remote = best(lambda: client.run(manipulator), a.repeats)
            long = {"integrator": {"t_end": 1000.0, "max_steps": 2000000}}
            local_long = best(lambda: moreau.run(manipulator, **long), 3)
            remote_long = best(lambda: client.run(manipulator, **long), 3)
        print("remote   manipulator end to end: moreau.run %.3f ms; moreau.Client(url).run %.1f ms; %.0fx"
              % (local * 1e3, remote * 1e3, remote / local))
        print("remote   the same over 1,000,000 steps (1,000,001 rows): moreau.run %.1f ms; moreau.Client(url).run %.1f ms; %.0fx"
              % (local_long * 1e3, remote_long * 1e3, remote_long / local_long))

    if "table" in only:
        scene = moreau.load(manipulator, integrator={"t_end": 1000.0, "max_steps": 2000000})
        totals, beyond = [], []
        for _ in range(max(3, a.repeats // 4)):
            t = time.perf_counter()
            r = scene.run()
            q = r.q  # the numpy view, as a user takes it
            total = time.perf_counter() - t
            integrate = dict(r.report["phase_seconds"])["integrate"]
            totals.append(total)
            beyond.append(total - integrate)
            del r, q
        print("table    %d rows x %d columns to numpy: the call %.1f ms, of which %.2f ms beyond the integrate phase (best)"
              % (1000001, 7, min(totals) * 1e3, min(beyond) * 1e3))

    if "threads" in only:
        scene = moreau.load(manipulator, integrator={"t_end": 100.0})
        one = best(scene.run, 5)

        def two():
            ts = [threading.Thread(target=scene.run) for _ in range(2)]
            for t in ts:
                t.start()
            for t in ts:
                t.join()
        both = best(two, 5)
        print("threads  100,000 steps: one run %.1f ms; two runs on two threads %.1f ms (%.2fx one run; %d cores)"
              % (one * 1e3, both * 1e3, both / one, os.cpu_count()))

    if "sweep" in only:
        values = [0.5 + 1.5 * i / 999 for i in range(1000)]
        scene = moreau.load(manipulator)

        def loop():
            for m in values:
                scene.run(parameters={"m1": m}, check=False)
        loop_s = best(loop, 3)
        tmp = tempfile.mkdtemp()
        try:
            def campaign():
                out = os.path.join(tmp, "sweep")
                shutil.rmtree(out, ignore_errors=True)
                subprocess.run([a.moreau, "campaign", "--scene", str(manipulator), "--vary", "parameters.m1=0.5:2:1000", "--out", out,
                                "-j", "1", "--quiet"], capture_output=True, check=True)
            campaign_s = best(campaign, 3)
        finally:
            shutil.rmtree(tmp)
        print("sweep    1,000 values of m1: a Python loop %.3f s; moreau campaign --vary -j 1 %.3f s; ratio %.2f"
              % (loop_s, campaign_s, loop_s / campaign_s))


if __name__ == "__main__":
    main()
