#!/usr/bin/env python3
"""Times a long trajectory's download with the Python client: as JSON (lists, then numpy arrays) and as
.npy (read straight into one array), each up to the numpy arrays a caller uses.

    PYTHONPATH=python python3 scripts/trajectory-download-time.py build/server/moreau-server [--rows N] [--repeat K]
        [--json-baseline OTHER-moreau-server]

It starts its own moreau-server on 127.0.0.1 (a free port, a temporary data directory; stopped at the
end), runs scenes/manipulator.json with h = 1e-3 for N - 1 steps, every step recorded (N rows of 7
columns), then downloads the trajectory K times each way and prints the best time of each, the bytes
sent and the ratio. It also checks that both ways give the same doubles. With --json-baseline it also
times the JSON download from that server binary (one built before .npy existed, say), the same run.
docs/python-client.md quotes its output.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "support"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))

import numpy as np  # noqa: E402

from moreau.client import Client  # noqa: E402
from server_process import ServerProcess  # noqa: E402


def best_of(k: int, f):
    times, value = [], None
    for _ in range(k):
        start = time.perf_counter()
        value = f()
        times.append(time.perf_counter() - start)
    return min(times), value


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("server", help="the moreau-server binary")
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json-baseline", metavar="SERVER", help="also time the JSON download from this moreau-server binary")
    args = ap.parse_args()
    scenes = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes")
    steps = args.rows - 1
    overrides = {"integrator.h": 1e-3, "integrator.t_end": steps * 1e-3, "output.every": 1}
    server_args = ["--max-samples", str(args.rows + 2)]

    def as_json(c, job_id):
        cols = c.trajectory(job_id, format="json")  # JSON text, lists, then numpy arrays
        return np.column_stack(list(cols.values()))

    t_baseline = None
    if args.json_baseline:
        with ServerProcess(args.json_baseline, scenes, server_args) as srv:
            c = Client(srv.url, timeout=600)
            job = c.run_job("manipulator", set=overrides, timeout=3600)
            t_baseline, a_baseline = best_of(args.repeat, lambda: as_json(c, job.id))
    with ServerProcess(args.server, scenes, server_args) as srv:
        c = Client(srv.url, timeout=600)
        started = time.perf_counter()
        job = c.run_job("manipulator", set=overrides, timeout=3600)
        print("run: %d steps in %.1f s (server side)" % (job.report["steps"], time.perf_counter() - started))

        def as_npy():
            return c.trajectory_array(job.id)[0]

        t_json, a_json = best_of(args.repeat, lambda: as_json(c, job.id))
        t_npy, a_npy = best_of(args.repeat, as_npy)
        assert a_json.shape == a_npy.shape == (args.rows, 7), (a_json.shape, a_npy.shape)
        assert np.array_equal(a_json.view(np.uint64), a_npy.view(np.uint64)), "the two ways differ"
        if t_baseline is not None:
            assert np.array_equal(a_baseline.view(np.uint64), a_npy.view(np.uint64)), "the baseline's run differs"
        json_bytes = len(c._bytes("/v1/jobs/%s/trajectory" % job.id))
        npy_bytes = len(c._bytes("/v1/jobs/%s/trajectory" % job.id, {"format": "npy"}))
        print("rows: %d, columns: %d" % a_npy.shape)
        print("json: %.2f s (%.1f MB)" % (t_json, json_bytes / 1e6))
        print("npy:  %.2f s (%.1f MB)" % (t_npy, npy_bytes / 1e6))
        print("npy is %.1f times faster" % (t_json / t_npy))
        if t_baseline is not None:
            print("json from %s: %.2f s; npy is %.1f times faster" % (args.json_baseline, t_baseline, t_baseline / t_npy))
    return 0


if __name__ == "__main__":
    sys.exit(main())
