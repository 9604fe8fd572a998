#!/usr/bin/env python3
"""clients/python/moreau_client.py against a real moreau-server on 127.0.0.1.

What the client returns is compared with what the server sends, read independently here with urllib and
the csv module (the trajectory's columns against the CSV, the report against the stored report's bytes),
and with properties that do not depend on the client (a PNG's size in its IHDR chunk, event ids in order).

Usage: python_client_test.py --server BIN --source-dir DIR [unittest options]
"""

import argparse
import ast
import csv
import io
import json
import math
import os
import struct
import sys
import time
import unittest
import urllib.request

ap = argparse.ArgumentParser()
ap.add_argument("--server", required=True)
ap.add_argument("--source-dir", required=True)
args, unittest_args = ap.parse_known_args()

sys.path.insert(0, os.path.join(args.source_dir, "clients", "python"))
sys.path.insert(0, os.path.join(args.source_dir, "tests", "support"))
import moreau_client  # noqa: E402
from moreau_client import Client, MoreauError  # noqa: E402
from server_process import ServerProcess  # noqa: E402

SCENES = os.path.join(args.source_dir, "scenes")
TOKEN = "python-client-test-token"


def raw_get(url, token=None):
    req = urllib.request.Request(url, headers={"Authorization": "Bearer " + token} if token else {})
    with urllib.request.urlopen(req, timeout=60) as r:
        return r.read()


def as_list(column):
    return [None if (isinstance(x, float) and math.isnan(x)) else x for x in list(column)]


class ClientAgainstServer(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = ServerProcess(args.server, SCENES, ["--token", TOKEN]).__enter__()
        cls.client = Client(cls.server.url, token=TOKEN)

    @classmethod
    def tearDownClass(cls):
        cls.server.__exit__(None, None, None)

    def test_the_module_parses_under_the_python_3_9_grammar(self):
        # (The grammar only: the module also avoids 3.10+ library calls, which this cannot check.)
        with open(moreau_client.__file__, encoding="utf-8") as f:
            ast.parse(f.read(), feature_version=(3, 9))

    def test_run_a_shipped_scene_with_overrides(self):
        seen = []
        job = self.client.run("manipulator", overrides={"integrator.t_end": 0.5}, timeout=60, progress=seen.append)
        self.assertEqual(job.state, "done")
        self.assertEqual(job.report["steps"], 500)
        self.assertTrue(seen, "the progress callback was never called")
        self.assertEqual(seen[-1].state, "done")
        fractions = [j.progress["fraction"] for j in seen]
        self.assertEqual(fractions, sorted(fractions), "progress went backwards")
        # The report, against the stored report.json read without the client.
        stored = json.loads(raw_get("%s/v1/jobs/%s/report" % (self.server.url, job.id), TOKEN))
        self.assertEqual(self.client.report(job.id), stored)
        self.assertEqual(job.report["final"], stored["final"])

    def test_trajectory_columns_are_the_csv(self):
        job = self.client.run("manipulator", overrides=["integrator.t_end=0.3"], timeout=60)
        text = raw_get("%s/v1/jobs/%s/trajectory?format=csv" % (self.server.url, job.id), TOKEN).decode()
        rows = list(csv.reader(io.StringIO(text)))
        header, body = rows[0], rows[1:]
        for numpy in (False, None):
            cols = self.client.trajectory(job.id, numpy=numpy)
            self.assertEqual(list(cols), header)
            for i, name in enumerate(header):
                self.assertEqual(as_list(cols[name]), [float(r[i]) for r in body], name)
        self.assertEqual(self.client.trajectory_csv(job.id), text)
        # The last row is the report's final state.
        final = job.report["final"]
        cols = self.client.trajectory(job.id, numpy=False)
        self.assertEqual([cols[c][-1] for c in ("x1", "th2")], final["q"])
        self.assertEqual([cols[c][-1] for c in ("x1_dot", "th2_dot")], final["v"])
        # A window: the rows with 0.1 <= t <= 0.2, every third one.
        window = self.client.trajectory(job.id, start=0.1, stop=0.2, every=3, numpy=False)
        t = [float(r[0]) for r in body]
        kept = [x for x in t if 0.1 <= x <= 0.2][::3]
        self.assertEqual(window["t"], kept)
        self.assertGreater(len(kept), 5)

    def test_numpy_arrays_when_numpy_is_installed_lists_otherwise(self):
        job = self.client.run("manipulator", overrides=["integrator.t_end=0.1"], timeout=60)
        lists = self.client.trajectory(job.id, numpy=False)
        self.assertIsInstance(lists["t"], list)
        if moreau_client._numpy() is None:
            self.skipTest("numpy is not installed (python3-numpy, scripts/install-deps.sh)")
        import numpy
        arrays = self.client.trajectory(job.id)
        self.assertIsInstance(arrays["t"], numpy.ndarray)
        self.assertEqual(arrays["t"].dtype, numpy.float64)
        for name in lists:
            self.assertEqual(arrays[name].tolist(), lists[name], name)
        # Without numpy (as on a bare Python): lists, and numpy=True says why it cannot.
        real = moreau_client._numpy
        moreau_client._numpy = lambda: None
        try:
            self.assertEqual(self.client.trajectory(job.id), lists)
            with self.assertRaises(ImportError):
                self.client.trajectory(job.id, numpy=True)
        finally:
            moreau_client._numpy = real

    def test_figures(self):
        job = self.client.run("manipulator", overrides=["integrator.t_end=0.2"], timeout=60)
        png = self.client.figure(job.id, kind="phase", width=320, height=200)
        self.assertEqual(png[:8], b"\x89PNG\r\n\x1a\n")
        self.assertEqual(png[12:16], b"IHDR")
        self.assertEqual(struct.unpack(">II", png[16:24]), (320, 200))
        svg = self.client.figure(job.id, kind="energy", format="svg").decode()
        self.assertIn("<svg", svg)

    def test_errors_carry_the_pointer(self):
        with self.assertRaises(MoreauError) as e:
            self.client.submit("manipulator", overrides={"integrator.h": 0})
        self.assertEqual((e.exception.status, e.exception.pointer, e.exception.where), (400, "/integrator/h", "scene"))
        self.assertIn("/integrator/h", str(e.exception))
        with self.assertRaises(MoreauError) as e:
            self.client.submit("no-such-scene")
        self.assertEqual((e.exception.status, e.exception.pointer, e.exception.where), (400, "/scene", "request"))
        with self.assertRaises(MoreauError) as e:
            self.client.job("0123456789abcdef0123456789abcdef")
        self.assertEqual(e.exception.status, 404)
        with self.assertRaises(MoreauError) as e:
            Client(self.server.url, token="").jobs()
        self.assertEqual(e.exception.status, 401)
        self.assertIn("MOREAU_TOKEN", str(e.exception))
        with self.assertRaises(MoreauError) as e:
            Client(self.server.url, token="wrong").jobs()
        self.assertIn("not accepted", str(e.exception))

    def test_events_in_order_and_resumed(self):
        job = self.client.run("manipulator", overrides=["integrator.t_end=0.2"], timeout=60)
        events = list(self.client.events(job.id))
        ids = [e.id for e in events]
        self.assertEqual(ids, sorted(ids))
        self.assertEqual(len(set(ids)), len(ids))
        self.assertEqual((events[-1].name, events[-1].data["state"]), ("state", "done"))
        resumed = list(self.client.events(job.id, last_event_id=ids[-2]))
        self.assertEqual([(e.id, e.name, e.data) for e in resumed], [(events[-1].id, events[-1].name, events[-1].data)])

    def test_scene_dict_and_file(self):
        scene = self.client.scene("manipulator")
        scene["integrator"]["t_end"] = 0.1
        job = self.client.run(scene, timeout=60)
        self.assertEqual(job.report["steps"], 100)
        import pathlib
        job = self.client.run(pathlib.Path(SCENES) / "manipulator.json", overrides=["integrator.t_end=0.05"], timeout=60)
        self.assertEqual(job.report["steps"], 50)
        names = [s["name"] for s in self.client.scenes()]
        self.assertIn("manipulator", names)

    def test_study(self):
        study = self.client.run_study("manipulator", overrides=["integrator.t_end=0.5"], h="1e-2,1e-3",
                                      schemes=["abl", "explicit"], repeats=1, timeout=120)
        self.assertEqual(study.state, "done")
        rows = study.result["rows"]
        self.assertEqual(sorted((r["scheme"], r["h"]) for r in rows),
                         sorted((s, h) for s in ("abl", "explicit") for h in (1e-2, 1e-3)))
        table = list(csv.DictReader(io.StringIO(self.client.study_table_csv(study.id))))
        self.assertEqual(len(table), len(rows))
        png = self.client.study_figure(study.id, kind="order")
        self.assertEqual(png[:8], b"\x89PNG\r\n\x1a\n")

    def test_campaign(self):
        spec = {"inputs": [{"path": "/parameters/m2", "distribution": {"type": "uniform", "low": 0.8, "high": 1.2}},
                           {"path": "/initial/q/0", "distribution": {"type": "uniform", "low": 2, "high": 4}}],
                "sampler": "sobol", "samples": 12, "seed": 3, "full_report": False}
        seen = []
        campaign = self.client.run_campaign("manipulator-fig6.4", spec, overrides=["integrator.t_end=3"], timeout=120,
                                            progress=lambda c: seen.append(c.progress["samples"]))
        self.assertEqual(campaign.state, "done")
        self.assertEqual(campaign.kind, "campaign")
        self.assertEqual(campaign.summary["samples"], 12)
        records = self.client.campaign_samples(campaign.id)
        self.assertEqual(sorted(r["index"] for r in records), list(range(12)))
        # The summary counts what the records say.
        self.assertEqual(campaign.summary["successes"], sum(1 for r in records if r["success"]))
        self.assertEqual(len(list(csv.DictReader(io.StringIO(self.client.campaign_samples_csv(campaign.id))))), 12)
        self.assertEqual(self.client.campaign_figure(campaign.id, kind="success-map")[:8], b"\x89PNG\r\n\x1a\n")
        self.assertTrue(seen)
        with self.assertRaises(MoreauError) as e:
            self.client.submit_campaign("manipulator-fig6.4", dict(spec, samples=0))
        self.assertEqual(e.exception.status, 400)
        self.assertEqual(e.exception.pointer, "/campaign/samples")

    def test_cancel(self):
        job = self.client.submit("manipulator", overrides=["integrator.t_end=1e4", "output.every=1000"])
        cancelled = self.client.cancel(job.id)
        self.assertIn(cancelled.state, ("cancelled", "cancelling"))
        final = self.client.wait(job.id, timeout=60)
        self.assertEqual(final.state, "cancelled")
        self.assertIn(job.id, [j.id for j in self.client.jobs(state="cancelled")])

    def test_list_pages_and_purge(self):
        ids = [self.client.run("manipulator", overrides=["integrator.t_end=0.05"], timeout=60).id for _ in range(3)]
        listed = [j.id for j in self.client.iter_jobs(scene="manipulator", page_size=2)]
        self.assertEqual(len(set(listed)), len(listed))
        # Newest first: the three just run lead, in reverse order of submission.
        self.assertEqual(listed[:3], ids[::-1])
        self.assertEqual(self.client.purge(ids[0]), {"id": ids[0], "deleted": True})
        with self.assertRaises(MoreauError) as e:
            self.client.job(ids[0])
        self.assertEqual(e.exception.status, 404)
        self.assertNotIn(ids[0], [j.id for j in self.client.iter_jobs(page_size=2)])

    def test_wait_times_out(self):
        job = self.client.submit("manipulator", overrides=["integrator.t_end=1e5", "output.every=100000"])
        try:
            with self.assertRaises(TimeoutError):
                self.client.wait(job.id, timeout=0.2)
        finally:
            self.client.cancel(job.id)
        # Following the event stream for progress, on a job that sends none (queued behind two long ones,
        # on the server's two workers): the server's keep-alive comes only every 15 s, and the wait must
        # not run on until then.
        long_jobs = [self.client.submit("manipulator", overrides=["integrator.t_end=1e5", "output.every=100000"]) for _ in range(2)]
        queued = self.client.submit("manipulator", overrides=["integrator.t_end=0.1"])
        try:
            self.assertEqual(self.client.job(queued.id).state, "queued")
            started = time.monotonic()
            with self.assertRaises(TimeoutError):
                self.client.wait(queued.id, timeout=0.5, progress=lambda j: None)
            self.assertLess(time.monotonic() - started, 10.0)
        finally:
            for j in long_jobs + [queued]:
                try:
                    self.client.cancel(j.id)
                except MoreauError:
                    pass  # already finished


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0]] + unittest_args, verbosity=2)
