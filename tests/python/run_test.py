"""moreau.load / Scene.run / moreau.run: the in-process run against the command line's (an independent
path through the same scene: its CSV, written as shortest round-trip text, read back), zero copy, the
errors and their pointers, the overrides."""

import json
import pathlib
import subprocess

import numpy as np
import pytest

import moreau

# One scene of each scheme and system type: abl, moreau-jean (impacts), a Lur'e system, a tracking run
# (signals), a URDF robot.
SCENES = ["manipulator.json", "bouncing-ball-e0.5.json", "lure-relay.json", "manipulator-tracking-digital.json",
          "iiwa14-coulomb-rest.json"]


def cli_table(cli, scene, tmp_path, *sets):
    out = tmp_path / "trajectory.csv"
    args = [str(cli), "run", str(scene), "--out", str(out), "--json", "--progress", "never"]
    for s in sets:
        args += ["--set", s]
    run = subprocess.run(args, capture_output=True, text=True)
    assert run.returncode in (0, 1), run.stderr
    lines = out.read_text().splitlines()
    header = lines[0].split(",")
    table = np.array([[float(x) for x in line.split(",")] for line in lines[1:]], dtype=float)
    return header, table, json.loads(run.stdout)


@pytest.mark.parametrize("name", SCENES)
def test_a_run_in_process_is_the_command_lines_run_bit_for_bit(cli, source_dir, tmp_path, name):
    path = source_dir / "scenes" / name
    header, table, report = cli_table(cli, path, tmp_path)
    r = moreau.run(path)
    assert r.columns == header
    assert r.table.shape == table.shape
    assert np.array_equal(r.table, table), "largest difference %g" % np.max(np.abs(r.table - table))
    # The report's numbers are the command line's, but for the wall time it measured.
    for key in ("status", "steps", "t_final", "final", "converged_step", "energy", "guarantees"):
        assert r.report.get(key) == report.get(key), key
    assert r.report_text.startswith("Moreau: ")


def test_the_arrays_are_views_of_the_runs_own_table(source_dir):
    r = moreau.run(source_dir / "scenes" / "manipulator.json")
    base = r.table.base
    assert type(base).__name__ == "TrajectoryTable"  # the C++ table itself, not a copy of it
    assert base.rows == len(r) and base.columns == r.table.shape[1]
    for view in (r.t, r.h, r.q, r.v, r.energy, r.signals):
        assert np.shares_memory(view, r.table) or view.size == 0
        assert view.base is r.table or view.base is base
    assert not r.table.flags.writeable
    # The views stay valid once the result is gone: the memory belongs to the table.
    q = r.q
    first = q.copy()
    del r
    assert np.array_equal(q, first)


def test_columns_names_and_closed_form_quantities(source_dir):
    r = moreau.run(source_dir / "scenes" / "manipulator.json")
    assert r.position_names == ["x1", "th2"] and r.velocity_names == ["x1_dot", "th2_dot"]
    assert r.t[0] == 0.0 and r.t[-1] == pytest.approx(10.0, abs=1e-12)
    # The positions follow the explicit update Q^{k+1} = Q^k + h V^k of (0.2), exactly as computed.
    assert np.array_equal(r.q[1:], r.q[:-1] + r.h[1:, None] * r.v[:-1])
    # The paper's manipulator comes to rest exactly (Theorem 4.3's finite-step convergence): v == 0.0.
    assert r.converged and np.all(r.v[-100:] == 0.0)
    assert r.status == "completed"
    assert any(g["claim"].startswith("each step of (0.2)") for g in r.guarantees)


def test_overrides_in_python_syntax_are_the_command_lines_set(cli, source_dir, tmp_path):
    path = source_dir / "scenes" / "manipulator.json"
    _, table, _ = cli_table(cli, path, tmp_path, "integrator.h=0.002", "integrator.t_end=3")
    a = moreau.run(path, integrator={"h": 0.002, "t_end": 3})
    b = moreau.run(path, set={"integrator.h": 0.002, "integrator.t_end": 3})
    c = moreau.load(path).run(set=["integrator.h=0.002", "/integrator/t_end=3"])
    for r in (a, b, c):
        assert np.array_equal(r.table, table)
    assert a.report["h"] == 0.002


def test_a_parameter_sweep_binds_values_into_the_scene_compiled_once_bit_for_bit(cli, source_dir, tmp_path):
    path = source_dir / "scenes" / "manipulator.json"
    scene = moreau.load(path)
    for m1 in (0.5, 2.0):
        _, table, _ = cli_table(cli, path, tmp_path, "parameters.m1=%r" % m1)
        assert np.array_equal(scene.run(parameters={"m1": m1}).table, table)
        assert np.array_equal(scene.run(set={"parameters.m1": m1}).table, table)


def test_numpy_numbers_are_taken_as_the_numbers_they_are(source_dir):
    path = source_dir / "scenes" / "manipulator.json"
    scene = moreau.load(path)
    assert np.array_equal(scene.run(parameters={"m1": np.float64(2.0)}).table, scene.run(parameters={"m1": 2.0}).table)
    assert np.array_equal(scene.run(parameters={"m1": np.int64(2)}).table, scene.run(parameters={"m1": 2.0}).table)
    assert np.array_equal(scene.run(initial={"q": np.array([1.0, 0.5])}).table, scene.run(set={"initial.q": [1.0, 0.5]}).table)


def test_a_scene_as_a_dict_and_its_document(source_dir):
    path = source_dir / "scenes" / "manipulator.json"
    doc = json.loads(path.read_text())
    a, b = moreau.run(doc), moreau.run(path)
    assert np.array_equal(a.table, b.table)
    scene = moreau.load(str(path))
    assert scene.document["name"] == doc["name"] and scene.dof == 2 and scene.scheme == "abl"


def test_an_invalid_scene_raises_scene_error_naming_the_field(source_dir):
    path = source_dir / "scenes" / "manipulator.json"
    with pytest.raises(moreau.SceneError) as e:
        moreau.load(path, integrator={"h": -1})
    assert e.value.pointer == "/integrator/h" and e.value.exit_code == 2
    assert isinstance(e.value, ValueError) and isinstance(e.value, moreau.MoreauError)
    with pytest.raises(moreau.SceneError) as e:
        moreau.load({"name": "x", "system": {"type": "lagrangian", "coordinates": ["q"], "mass": [[1]], "potential": "q^"}})
    assert e.value.pointer.startswith("/system")
    with pytest.raises(moreau.SceneError) as e:
        moreau.load(source_dir / "scenes" / "no-such-scene.json")
    assert "no-such-scene.json" in str(e.value)
    with pytest.raises(TypeError):
        moreau.load(42)
    # A NaN or an infinity is not JSON: refused before it reaches the scene, naming where it is.
    with pytest.raises(moreau.SceneError) as e:
        moreau.load(path, integrator={"h": float("nan")})
    assert e.value.pointer == "/integrator/h"
    with pytest.raises(moreau.SceneError) as e:
        moreau.load(path).run(set={"initial.q.1": float("inf")})
    assert e.value.pointer == "/initial/q/1"
    with pytest.raises(moreau.SceneError) as e:
        moreau.load(path).run(parameters={"m1": float("-inf")})
    assert e.value.pointer == "/parameters/m1"
    # Nested beyond any scene, in Python or in the JSON the module parses: an error, not a crash.
    deep = {}
    for _ in range(100000):
        deep = {"a": deep}
    with pytest.raises(moreau.SceneError):
        moreau.load(path, system=deep)
    with pytest.raises(moreau.SceneError):
        moreau.load(path, set=["system.x=" + "[" * 100000 + "]" * 100000])


def test_a_failed_run_raises_run_failed_with_its_result(cli, tmp_path):
    # M(q) = 1 - q^2 is positive definite only for |q| < 1: from q = 0 at v = 1 the run reaches |q| = 1 and
    # stops there; the command line exits 1 on it.
    doc = {"system": {"type": "lagrangian", "coordinates": ["x"], "mass": [["1 - x^2"]]},
           "initial": {"q": [0.0], "v": [1.0]}, "integrator": {"h": 1e-3, "t_end": 5.0}}
    (tmp_path / "losing.json").write_text(json.dumps(doc))
    assert subprocess.run([str(cli), "run", str(tmp_path / "losing.json")], capture_output=True).returncode == 1
    with pytest.raises(moreau.RunFailed) as e:
        moreau.run(doc)
    assert e.value.exit_code == 1 and e.value.result.status == "failed" and len(e.value.result) > 0
    assert np.all(np.abs(e.value.result.q[:-1]) < 1.0)
    r = moreau.run(doc, check=False)
    assert r.status == "failed" and np.array_equal(r.table, e.value.result.table)


def test_strict_raises_hypothesis_failed_where_the_command_line_exits_3(cli, source_dir):
    # The arm at rest under Coulomb friction: a hypothesis its run relies on fails, and `moreau run
    # --strict` exits 3 on it; the manipulator's run relies on none that fails, and exits 0.
    path = source_dir / "scenes" / "iiwa14-coulomb-rest.json"
    assert subprocess.run([str(cli), "run", str(path), "--strict", "--progress", "never"], capture_output=True).returncode == 3
    with pytest.raises(moreau.HypothesisFailed) as e:
        moreau.run(path, strict=True)
    assert e.value.exit_code == 3 and e.value.result.status == "completed"
    assert any(g["relied_on"] and g["verdict"] == "fails" for g in e.value.result.guarantees)
    assert moreau.run(path).status == "completed"  # not strict: the result, as the command line's warning
    manipulator = source_dir / "scenes" / "manipulator.json"
    assert subprocess.run([str(cli), "run", str(manipulator), "--strict", "--progress", "never"], capture_output=True).returncode == 0
    assert moreau.run(manipulator, strict=True).status == "completed"


def test_figures_are_png_and_svg_from_the_command_lines_renderer(cli, source_dir, tmp_path):
    path = source_dir / "scenes" / "manipulator.json"
    r = moreau.run(path)
    png = r.figure("state", width=600, height=400)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert int.from_bytes(png[16:20], "big") == 600 and int.from_bytes(png[20:24], "big") == 400
    svg = r.figure("phase", format="svg")
    assert svg.startswith(b"<?xml") or svg.startswith(b"<svg")
    with pytest.raises(ValueError):
        r.figure("no-such-kind")


def test_notebook_reprs(source_dir):
    r = moreau.run(source_dir / "scenes" / "manipulator.json")
    html = r._repr_html_()
    assert html.startswith("<pre>") and "Moreau: manipulator" in html and "<" not in html[5:-6]
    assert r._repr_png_()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "manipulator" in repr(r)


def test_to_pandas(source_dir):
    import pandas
    r = moreau.run(source_dir / "scenes" / "manipulator.json")
    frame = r.to_pandas()
    assert isinstance(frame, pandas.DataFrame)
    assert list(frame.columns) == r.columns[1:] and np.array_equal(frame.index.to_numpy(), r.t)
    assert np.array_equal(frame["th2"].to_numpy(), r.q[:, 1])


@pytest.mark.parametrize("name,kind", [("bouncing-ball-e0.5.json", "state"), ("manipulator-tracking-digital.json", "tracking"),
                                       ("lure-relay.json", "phase")])
def test_a_figure_is_the_command_lines_figure_byte_for_byte(cli, source_dir, tmp_path, name, kind):
    # SVG is text: the same drawing (labels with the scene's /units, impacts, the rest time) gives the same bytes.
    path = source_dir / "scenes" / name
    svg = tmp_path / "figure.svg"
    subprocess.run([str(cli), "run", str(path), "--figure", "%s=%s" % (kind, svg), "--progress", "never"], capture_output=True)
    assert svg.exists()
    assert moreau.run(path).figure(kind, format="svg") == svg.read_bytes()


def test_a_robust_y_figure_is_the_command_lines_robust_y_figure(cli, source_dir, tmp_path):
    path = source_dir / "scenes" / "iiwa14-joint-limit.json"
    svg = tmp_path / "state.svg"
    subprocess.run([str(cli), "run", str(path), "--figure", "state=%s" % svg, "--robust-y", "--progress", "never"], capture_output=True)
    robust = moreau.run(path).figure("state", format="svg", robust_y=True)
    assert robust == svg.read_bytes()
    assert b"beyond the axis" in robust  # the joint-limit impacts' spikes, clipped and counted
