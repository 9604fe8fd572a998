"""python/moreau/client.py against a real moreau-server on 127.0.0.1, with pytest.

What the client returns is compared with what the server sends, read independently here with urllib and
the csv module (the trajectory's columns against the CSV, the report against the stored report's bytes),
and with properties that do not depend on the client (a PNG's size in its IHDR chunk, event ids in order).

Run by CTest (tests/client/CMakeLists.txt) as
    MOREAU_SERVER_BINARY=BIN MOREAU_SOURCE_DIR=DIR PYTHONPATH=DIR/python python3 -m pytest THIS_FILE
The servers it starts listen on 127.0.0.1 and are stopped when their tests end.
"""

from __future__ import annotations

import ast
import csv
import io
import json
import math
import os
import pathlib
import socket
import struct
import sys
import time
import urllib.request
from typing import Iterator, List, Optional

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("MOREAU_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
SERVER_BINARY = os.environ.get("MOREAU_SERVER_BINARY")
sys.path.insert(0, str(SOURCE_DIR / "python"))
sys.path.insert(0, str(SOURCE_DIR / "tests" / "support"))

import moreau.client as moreau_client  # noqa: E402
from moreau.client import Client, Job, MoreauError  # noqa: E402
from moreau.errors import (HypothesisFailed, RunFailed, SceneError, ServerError, ServerSceneError,  # noqa: E402
                           ServerUnreachable)
from server_process import ServerProcess  # noqa: E402

SCENES = SOURCE_DIR / "scenes"
TOKEN = "python-client-test-token"

if not SERVER_BINARY:
    pytest.skip("MOREAU_SERVER_BINARY is not set (CTest sets it: ctest -R ServerPythonClient)", allow_module_level=True)


def raw_get(url: str, token: Optional[str] = None) -> bytes:
    req = urllib.request.Request(url, headers={"Authorization": "Bearer " + token} if token else {})
    with urllib.request.urlopen(req, timeout=60) as r:
        return r.read()


def as_list(column) -> list:
    return [None if (isinstance(x, float) and math.isnan(x)) else x for x in list(column)]


def csv_table(text: str):
    """The CSV's header and its rows as floats (the shortest round-trip text reads back as the very
    double written)."""
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], [[float(x) for x in r] for r in rows[1:]]


@pytest.fixture(scope="module")
def server() -> Iterator[ServerProcess]:
    with ServerProcess(SERVER_BINARY, str(SCENES), ["--token", TOKEN]) as s:
        yield s


@pytest.fixture(scope="module")
def client(server: ServerProcess) -> Client:
    return Client(server.url, token=TOKEN)


def test_the_modules_parse_under_the_python_3_9_grammar():
    # (The grammar only: the modules also avoid 3.10+ library calls, which this cannot check.)
    for name in ("client.py", "errors.py", "result.py"):
        with open(SOURCE_DIR / "python" / "moreau" / name, encoding="utf-8") as f:
            ast.parse(f.read(), feature_version=(3, 9))


def test_run_a_shipped_scene_with_overrides(client: Client, server: ServerProcess):
    seen: List[Job] = []
    job = client.run_job("manipulator", overrides={"integrator.t_end": 0.5}, timeout=60, progress=seen.append)
    assert job.state == "done"
    assert job.report["steps"] == 500
    assert seen, "the progress callback was never called"
    assert seen[-1].state == "done"
    fractions = [j.progress["fraction"] for j in seen]
    assert fractions == sorted(fractions), "progress went backwards"
    # The report, against the stored report.json read without the client.
    stored = json.loads(raw_get("%s/v1/jobs/%s/report" % (server.url, job.id), TOKEN))
    assert client.report(job.id) == stored
    assert job.report["final"] == stored["final"]


def test_set_and_patch_are_overrides(client: Client):
    # set={dotted path: value}, a nested patch of the scene (merge patch), and the older overrides: the
    # patch first, then set, then overrides.
    assert client.run_job("manipulator", set={"integrator.t_end": 0.2}, timeout=60).report["steps"] == 200
    assert client.run_job("manipulator", integrator={"t_end": 0.3}, timeout=60).report["steps"] == 300
    job = client.run_job("manipulator", integrator={"t_end": 0.3, "h": 0.01}, set={"integrator.t_end": 0.5}, timeout=60)
    assert job.report["steps"] == 50
    job = client.run_job("manipulator", ["integrator.t_end=0.1"], set={"integrator.t_end": 0.5}, timeout=60)
    assert job.report["steps"] == 100
    with pytest.raises(ValueError, match="remove the member"):
        client.submit("manipulator", integrator={"h": None})


def test_trajectory_columns_are_the_csv(client: Client, server: ServerProcess):
    job = client.run_job("manipulator", overrides=["integrator.t_end=0.3"], timeout=60)
    text = raw_get("%s/v1/jobs/%s/trajectory?format=csv" % (server.url, job.id), TOKEN).decode()
    rows = list(csv.reader(io.StringIO(text)))
    header, body = rows[0], rows[1:]
    for numpy, format in ((False, None), (None, None), (None, "json"), (None, "npy")):
        cols = client.trajectory(job.id, numpy=numpy, format=format)
        assert list(cols) == header
        for i, name in enumerate(header):
            assert as_list(cols[name]) == [float(r[i]) for r in body], (name, numpy, format)
    assert client.trajectory_csv(job.id) == text
    # The last row is the report's final state.
    final = job.report["final"]
    cols = client.trajectory(job.id, numpy=False)
    assert [cols[c][-1] for c in ("x1", "th2")] == final["q"]
    assert [cols[c][-1] for c in ("x1_dot", "th2_dot")] == final["v"]
    # A window: the rows with 0.1 <= t <= 0.2, every third one.
    t = [float(r[0]) for r in body]
    kept = [x for x in t if 0.1 <= x <= 0.2][::3]
    assert len(kept) > 5
    assert client.trajectory(job.id, start=0.1, stop=0.2, every=3, numpy=False)["t"] == kept
    assert client.trajectory(job.id, start=0.1, stop=0.2, every=3)["t"].tolist() == kept


def test_npy_trajectory_is_the_csv_bit_for_bit(client: Client, server: ServerProcess):
    np = pytest.importorskip("numpy")
    # A tracking run: signals after the energy, negative and tiny values.
    job = client.run_job("manipulator-tracking", set={"integrator.t_end": 0.5, "output.every": 1}, timeout=60)
    for window in ({}, {"from": 0.1, "to": 0.3}, {"every": 7}, {"from": 100}):
        query = "".join("&%s=%s" % kv for kv in window.items())
        header, values = csv_table(raw_get("%s/v1/jobs/%s/trajectory?format=csv%s" % (server.url, job.id, query), TOKEN).decode())
        table, columns = client.trajectory_array(job.id, window.get("from"), window.get("to"), window.get("every"))
        assert columns == header
        assert table.dtype == np.float64 and table.flags.c_contiguous and table.flags.writeable
        assert table.shape == (len(values), len(header))
        expected = np.array(values, dtype=np.float64).reshape(len(values), len(header))
        assert table.view(np.uint64).tolist() == expected.view(np.uint64).tolist(), window
    # The bytes as served: an .npy file numpy's own reader takes, the names in the Moreau-Columns header.
    req = urllib.request.Request("%s/v1/jobs/%s/trajectory?format=npy" % (server.url, job.id),
                                 headers={"Authorization": "Bearer " + TOKEN})
    with urllib.request.urlopen(req, timeout=60) as r:
        assert r.headers["Content-Type"] == "application/octet-stream"
        names = r.headers["Moreau-Columns"].split(",")
        loaded = np.load(io.BytesIO(r.read()), allow_pickle=False)
    assert names[:2] == ["t", "h"] and "energy" in names and "e_x1" in names
    assert loaded.tolist() == client.trajectory_array(job.id)[0].tolist()


def test_result_fields_and_arrays(client: Client):
    np = pytest.importorskip("numpy")
    from moreau.result import Result
    r = client.run("manipulator-tracking", set={"integrator.t_end": 0.3}, timeout=60)
    assert isinstance(r, Result)
    assert isinstance(r.job, Job) and r.job.state == "done"
    assert r.status == "completed"
    assert r.report == client.report(r.job.id)
    assert r.position_names == ["x1", "th2"]
    assert r.velocity_names == ["x1_dot", "th2_dot"]
    assert r.signal_names and all(any(s.startswith(p) for p in ("qd_", "e_", "sigma_", "u_")) for s in r.signal_names)
    table, columns = client.trajectory_array(r.job.id)
    assert r.columns == columns
    assert r.table.tolist() == table.tolist()
    assert len(r) == r.report["steps"] // 10 + 1
    assert r.q.shape == (len(r), 2) and r.v.shape == (len(r), 2) and r.signals.shape == (len(r), len(r.signal_names))
    assert r.t[0] == 0.0 and r.t[-1] == pytest.approx(0.3)
    assert r.q[-1].tolist() == r.report["final"]["q"]
    assert r.v[-1].tolist() == r.report["final"]["v"]
    assert np.array_equal(r.column("th2_dot"), r.v[:, 1])
    png = r.figure("tracking", "png", 640, 600)
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", png[16:24]) == (640, 600)
    assert b"<svg" in r.figure("energy", "svg")
    # The same Result for a job run earlier, by id.
    again = client.result(r.job.id)
    assert again.table.tolist() == r.table.tolist() and again.report == r.report


def test_numpy_arrays_when_numpy_is_installed_lists_otherwise(client: Client, monkeypatch: pytest.MonkeyPatch):
    job = client.run_job("manipulator", overrides=["integrator.t_end=0.1"], timeout=60)
    lists = client.trajectory(job.id, numpy=False)
    assert isinstance(lists["t"], list)
    np = pytest.importorskip("numpy", reason="numpy is not installed (python3-numpy, scripts/install-deps.sh)")
    arrays = client.trajectory(job.id)
    assert isinstance(arrays["t"], np.ndarray)
    assert arrays["t"].dtype == np.float64
    for name in lists:
        assert arrays[name].tolist() == lists[name], name
    # Without numpy (as on a bare Python): lists from the JSON form, and numpy=True or npy say why they cannot.
    monkeypatch.setattr(moreau_client, "_numpy", lambda: None)
    assert client.trajectory(job.id) == lists
    with pytest.raises(ImportError):
        client.trajectory(job.id, numpy=True)
    with pytest.raises(ImportError):
        client.trajectory_array(job.id)


def test_figures(client: Client):
    job = client.run_job("manipulator", overrides=["integrator.t_end=0.2"], timeout=60)
    png = client.figure(job.id, kind="phase", width=320, height=200)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert png[12:16] == b"IHDR"
    assert struct.unpack(">II", png[16:24]) == (320, 200)
    svg = client.figure(job.id, kind="energy", format="svg").decode()
    assert "<svg" in svg


def test_errors_carry_the_pointer(client: Client, server: ServerProcess):
    with pytest.raises(MoreauError) as e:
        client.submit("manipulator", overrides={"integrator.h": 0})
    assert (e.value.status, e.value.pointer, e.value.where) == (400, "/integrator/h", "scene")
    assert "/integrator/h" in str(e.value)
    with pytest.raises(MoreauError) as e:
        client.submit("no-such-scene")
    assert (e.value.status, e.value.pointer, e.value.where) == (400, "/scene", "request")
    with pytest.raises(MoreauError) as e:
        client.job("0123456789abcdef0123456789abcdef")
    assert e.value.status == 404
    with pytest.raises(MoreauError) as e:
        Client(server.url, token="").jobs()
    assert e.value.status == 401
    assert "MOREAU_TOKEN" in str(e.value)
    with pytest.raises(MoreauError) as e:
        Client(server.url, token="wrong").jobs()
    assert "not accepted" in str(e.value)


def test_a_scene_error_is_a_scene_error_with_its_pointer(client: Client):
    with pytest.raises(SceneError) as e:
        client.run("manipulator", set={"integrator.h": -1}, timeout=60)
    assert isinstance(e.value, ServerSceneError) and isinstance(e.value, ServerError)
    assert isinstance(e.value, ValueError)
    assert (e.value.status, e.value.pointer, e.value.where, e.value.exit_code) == (400, "/integrator/h", "scene", 2)
    assert e.value.reason and "> 0" in e.value.reason
    # One about the request is a ServerError only.
    with pytest.raises(ServerError) as e:
        client.submit("no-such-scene")
    assert not isinstance(e.value, SceneError)


def test_server_unreachable_on_a_closed_port():
    with socket.socket() as s:  # a port nothing listens on: bound, then closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    c = Client("http://127.0.0.1:%d" % port, token=TOKEN, timeout=5)
    with pytest.raises(ServerUnreachable) as e:
        c.health()
    assert isinstance(e.value, ConnectionError) and isinstance(e.value, MoreauError)
    assert not hasattr(e.value, "status")
    assert e.value.url == "http://127.0.0.1:%d" % port
    with pytest.raises(ConnectionError):
        c.run("manipulator")


def test_server_unreachable_when_it_does_not_answer():
    # A listener that accepts and never answers: the request times out.
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        c = Client("http://127.0.0.1:%d" % s.getsockname()[1], token=TOKEN, timeout=0.5)
        started = time.monotonic()
        with pytest.raises(ServerUnreachable, match="timed out"):
            c.health()
        assert time.monotonic() - started < 10


def test_events_in_order_and_resumed(client: Client):
    job = client.run_job("manipulator", overrides=["integrator.t_end=0.2"], timeout=60)
    events = list(client.events(job.id))
    ids = [e.id for e in events]
    assert ids == sorted(ids)
    assert len(set(ids)) == len(ids)
    assert (events[-1].name, events[-1].data["state"]) == ("state", "done")
    resumed = list(client.events(job.id, last_event_id=ids[-2]))
    assert [(e.id, e.name, e.data) for e in resumed] == [(events[-1].id, events[-1].name, events[-1].data)]


def test_scene_dict_path_and_name(client: Client):
    scene = client.scene("manipulator")
    scene["integrator"]["t_end"] = 0.1
    assert client.run_job(scene, timeout=60).report["steps"] == 100
    job = client.run_job(pathlib.Path(SCENES) / "manipulator.json", overrides=["integrator.t_end=0.05"], timeout=60)
    assert job.report["steps"] == 50
    # A str is a shipped scene's name; one that looks like a path is refused here, before any request.
    assert client.run_job("manipulator", set={"integrator.t_end": 0.05}, timeout=60).report["steps"] == 50
    for path_like in (str(SCENES / "manipulator.json"), "manipulator.json", "scenes/manipulator"):
        with pytest.raises(ValueError, match=r"pathlib\.Path"):
            client.submit(path_like)
    with pytest.raises(TypeError):
        client.submit(42)  # type: ignore[arg-type]
    names = [s["name"] for s in client.scenes()]
    assert "manipulator" in names


def test_strict_failure_is_hypothesis_failed(client: Client):
    # The manipulator at h = 1 with a large initial velocity breaks (4.2) of Theorem 4.1 from its first
    # step (tests/server/server_api_test.cc, StrictJobFailsWhenARelieduponHypothesisFails).
    breaking = {"integrator.h": 1, "initial.v": [10, 10], "integrator.t_end": 20}
    with pytest.raises(HypothesisFailed) as e:
        client.run("manipulator", set=breaking, strict=True, timeout=60)
    assert e.value.exit_code == 3
    assert "Theorem 4.1" in str(e.value)
    assert not isinstance(e.value, RunFailed)
    if e.value.result is not None:  # the run's own trajectory, to look at why
        assert e.value.result.job.strict_failure
    with pytest.raises(HypothesisFailed) as e:
        client.run_job("manipulator", set=breaking, strict=True, timeout=60)
    assert isinstance(e.value.result, Job) and e.value.result.state == "failed"
    # Without strict the same run completes; its report says the theorem fails.
    r = client.run("manipulator", set=breaking, timeout=60)
    assert r.status == "completed"
    assert r.guarantees[0]["verdict"] == "fails"


def test_a_failed_run_raises_run_failed_with_what_it_computed():
    with ServerProcess(SERVER_BINARY, str(SCENES), ["--token", TOKEN, "--max-job-seconds", "0.5"]) as s:
        c = Client(s.url, token=TOKEN)
        with pytest.raises(RunFailed) as e:
            c.run("manipulator", set={"integrator.t_end": 1e5, "output.every": 1000}, timeout=60)
        assert e.value.exit_code == 1
        assert not isinstance(e.value, HypothesisFailed)
        partial = e.value.result
        assert partial is not None and partial.job.state == "failed"
        assert 0 < len(partial) and partial.t[-1] < 1e5
        with pytest.raises(RunFailed) as e:
            c.run_job("manipulator", set={"integrator.t_end": 1e5, "output.every": 1000}, timeout=60)
        assert e.value.result.state == "failed"


def test_study(client: Client):
    study = client.run_study("manipulator", overrides=["integrator.t_end=0.5"], h="1e-2,1e-3",
                             schemes=["abl", "explicit"], repeats=1, timeout=120)
    assert study.state == "done"
    rows = study.result["rows"]
    assert sorted((r["scheme"], r["h"]) for r in rows) == sorted((s, h) for s in ("abl", "explicit") for h in (1e-2, 1e-3))
    table = list(csv.DictReader(io.StringIO(client.study_table_csv(study.id))))
    assert len(table) == len(rows)
    png = client.study_figure(study.id, kind="order")
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_campaign(client: Client):
    spec = {"inputs": [{"path": "/parameters/m2", "distribution": {"type": "uniform", "low": 0.8, "high": 1.2}},
                       {"path": "/initial/q/0", "distribution": {"type": "uniform", "low": 2, "high": 4}}],
            "sampler": "sobol", "samples": 12, "seed": 3, "full_report": False}
    seen: List[int] = []
    campaign = client.run_campaign("manipulator-fig6.4", spec, overrides=["integrator.t_end=3"], timeout=120,
                                   progress=lambda c: seen.append(c.progress["samples"]))
    assert campaign.state == "done"
    assert campaign.kind == "campaign"
    assert campaign.summary["samples"] == 12
    records = client.campaign_samples(campaign.id)
    assert sorted(r["index"] for r in records) == list(range(12))
    # The summary counts what the records say.
    assert campaign.summary["successes"] == sum(1 for r in records if r["success"])
    assert len(list(csv.DictReader(io.StringIO(client.campaign_samples_csv(campaign.id))))) == 12
    assert client.campaign_figure(campaign.id, kind="success-map")[:8] == b"\x89PNG\r\n\x1a\n"
    assert seen
    with pytest.raises(MoreauError) as e:
        client.submit_campaign("manipulator-fig6.4", dict(spec, samples=0))
    assert e.value.status == 400
    assert e.value.pointer == "/campaign/samples"


def test_jobs_lists_runs_studies_and_campaigns(client: Client):
    run = client.run_job("manipulator", set={"integrator.t_end": 0.05}, timeout=60)
    study = client.run_study("manipulator", set={"integrator.t_end": 0.2}, h="1e-2", schemes=["abl"], repeats=1, timeout=120)
    spec = {"inputs": [{"path": "/initial/q/0", "distribution": {"type": "uniform", "low": 2, "high": 4}}],
            "samples": 2, "seed": 1, "full_report": False}
    campaign = client.run_campaign("manipulator", spec, set={"integrator.t_end": 0.1}, timeout=120)
    every = client.jobs()
    kinds = {j.id: j.kind for j in every}
    assert (kinds[run.id], kinds[study.id], kinds[campaign.id]) == ("run", "study", "campaign")
    created = [j.raw["created"] for j in every]
    assert created == sorted(created), "oldest first"
    assert [j.id for j in client.jobs(limit=3)] == [run.id, study.id, campaign.id]
    assert {j.kind for j in client.jobs(kind="study")} == {"study"}
    assert {j.kind for j in client.jobs(kind="run")} == {"run"}
    listed = [j.id for j in client.iter_jobs(page_size=2)]
    assert listed[:3] == [campaign.id, study.id, run.id], "newest first"
    assert len(set(listed)) == len(listed) == len(every)
    with pytest.raises(ValueError):
        client.jobs(kind="job")


def test_cancel(client: Client):
    job = client.submit("manipulator", overrides=["integrator.t_end=1e4", "output.every=1000"])
    cancelled = client.cancel(job.id)
    assert cancelled.state in ("cancelled", "cancelling")
    final = client.wait(job.id, timeout=60)
    assert final.state == "cancelled"
    assert job.id in [j.id for j in client.jobs(state="cancelled")]


def test_list_pages_and_purge(client: Client):
    ids = [client.run_job("manipulator", overrides=["integrator.t_end=0.05"], timeout=60).id for _ in range(3)]
    listed = [j.id for j in client.iter_jobs(scene="manipulator", page_size=2, kind="run")]
    assert len(set(listed)) == len(listed)
    # Newest first: the three just run lead, in reverse order of submission.
    assert listed[:3] == ids[::-1]
    assert client.purge(ids[0]) == {"id": ids[0], "deleted": True}
    with pytest.raises(MoreauError) as e:
        client.job(ids[0])
    assert e.value.status == 404
    assert ids[0] not in [j.id for j in client.iter_jobs(page_size=2)]


def test_wait_times_out(client: Client):
    job = client.submit("manipulator", overrides=["integrator.t_end=1e5", "output.every=100000"])
    try:
        with pytest.raises(TimeoutError):
            client.wait(job.id, timeout=0.2)
    finally:
        client.cancel(job.id)
    # Following the event stream for progress, on a job that sends none (queued behind two long ones,
    # on the server's two workers): the server's keep-alive comes only every 15 s, and the wait must
    # not run on until then.
    long_jobs = [client.submit("manipulator", overrides=["integrator.t_end=1e5", "output.every=100000"]) for _ in range(2)]
    queued = client.submit("manipulator", overrides=["integrator.t_end=0.1"])
    try:
        assert client.job(queued.id).state == "queued"
        started = time.monotonic()
        with pytest.raises(TimeoutError):
            client.wait(queued.id, timeout=0.5, progress=lambda j: None)
        assert time.monotonic() - started < 10.0
    finally:
        for j in long_jobs + [queued]:
            try:
                client.cancel(j.id)
            except MoreauError:
                pass  # already finished
