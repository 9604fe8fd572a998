"""The GIL is released while a scene integrates (threads run scenes at once), and Ctrl-C stops a run in
process cleanly. Both are checked on state, not on time: what another thread did while a run went on,
and what a child process printed once its run had started."""

import json
import signal
import subprocess
import sys
import threading

import numpy as np

import moreau

# The manipulator over 10,000,000 steps (half a second or more), every 1000th state recorded.
LONG = {"integrator": {"t_end": 10000.0, "max_steps": 20000000}, "output": {"every": 1000}}


def test_python_runs_in_another_thread_while_a_scene_integrates(source_dir):
    # A thread counts as fast as it can. The run's progress callback (under the GIL, about every 50 ms)
    # reads the count: it can have moved between two callbacks only if the run let go of the GIL.
    count = 0
    stop = False

    def counter():
        nonlocal count
        while not stop:
            count += 1

    seen = []
    t = threading.Thread(target=counter)
    t.start()
    try:
        moreau.run(source_dir / "scenes" / "manipulator.json", progress=lambda _t: seen.append(count), **LONG)
    finally:
        stop = True
        t.join()
    moved = [b - a for a, b in zip(seen, seen[1:])]
    assert len(moved) >= 3, "the run took too little time to check (%d callbacks)" % len(seen)
    assert sum(d > 0 for d in moved) >= len(moved) // 2 + 1, moved


def test_two_threads_run_two_scenes_and_get_the_single_threaded_results(source_dir):
    path = source_dir / "scenes" / "manipulator.json"
    scene = moreau.load(path)
    alone = [scene.run(parameters={"m1": m}).table for m in (1.0, 3.0)]
    results = [None, None]

    def work(i, m):
        results[i] = scene.run(parameters={"m1": m}).table

    threads = [threading.Thread(target=work, args=(i, m)) for i, m in enumerate((1.0, 3.0))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(alone, results):
        assert np.array_equal(a, b)


CHILD = r"""
import sys, moreau
started = False
def progress(t):
    global started
    if not started:
        started = True
        print("started", flush=True)
try:
    moreau.run(sys.argv[1], integrator={"t_end": 1e6, "max_steps": 2000000000}, output={"every": 1000}, progress=progress)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    r = moreau.run(sys.argv[1])          # the module works on after it
    print("then", r.status, flush=True)
"""


def interrupted_child(code, *args):
    """Runs `code` in a child Python, sends it SIGINT once it has printed "started" (its work has begun),
    and returns (exit code, the rest of its output, its error output). The child is killed if it hangs."""
    child = subprocess.Popen([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "started"
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    return child.returncode, out, err


def test_ctrl_c_stops_a_run_with_keyboard_interrupt(source_dir):
    code, out, err = interrupted_child(CHILD, source_dir / "scenes" / "manipulator.json")
    assert code == 0, err
    assert out.split() == ["interrupted", "then", "completed"], (out, err)


CAMPAIGN_CHILD = r"""
import sys, moreau
printed = False
def progress(done, total):
    global printed
    if not printed:
        printed = True
        print("started", flush=True)
try:
    moreau.campaign(sys.argv[1], out=sys.argv[2], jobs=1, progress=progress)
except KeyboardInterrupt:
    print("interrupted", flush=True)
"""


def test_ctrl_c_stops_a_campaign_with_every_finished_sample_kept_and_the_same_call_goes_on(source_dir, tmp_path):
    spec = source_dir / "campaigns" / "manipulator-robust.json"
    doc = json.loads(spec.read_text())
    # 128 samples of 100,000 steps each: a few seconds, stopped after the first has been recorded.
    doc["samples"] = 128
    scene = json.loads((spec.parent / doc["scene"]).read_text())
    scene["integrator"]["t_end"] = 100.0
    doc["scene"] = scene
    spec_file = tmp_path / "spec.json"
    spec_file.write_text(json.dumps(doc))
    code, out, err = interrupted_child(CAMPAIGN_CHILD, spec_file, tmp_path / "stopped")
    assert code == 0 and out.split() == ["interrupted"], (out, err)
    # Whole records only, each a line of JSON; no summary yet.
    records = (tmp_path / "stopped" / "samples.jsonl").read_text().splitlines()
    assert all(json.loads(line)["index"] >= 0 for line in records)
    assert not (tmp_path / "stopped" / "summary.json").exists()
    # The same call goes on, and ends where a campaign never stopped ends.
    resumed = moreau.campaign(spec_file, out=tmp_path / "stopped", jobs=1)
    assert resumed.skipped == len(records) and resumed.ran == 128 - len(records) and len(records) < 128
    whole = moreau.campaign(spec_file, out=tmp_path / "whole", jobs=2)
    for key in whole.summary:
        if "time" not in key and "seconds" not in key:
            assert resumed.summary[key] == whole.summary[key], key
