"""moreau.study and moreau.campaign against the command line's `moreau study --json` and `moreau
campaign`: the same numbers and the same files."""

import json
import pathlib
import subprocess

import numpy as np
import pytest

import moreau


def test_a_study_has_the_command_lines_errors_and_orders(cli, source_dir):
    path = source_dir / "scenes" / "coulomb-oscillator.json"
    args = ["--h", "1e-2,5e-3,2.5e-3", "--schemes", "abl,explicit", "--repeats", "1"]
    cli_out = json.loads(subprocess.run([str(cli), "study", str(path), *args, "--json"], capture_output=True, text=True,
                                        check=True).stdout)
    s = moreau.study(path, h=[1e-2, 5e-3, 2.5e-3], schemes=["abl", "explicit"], repeats=1)
    assert len(s.rows) == len(cli_out["rows"]) == 6
    for mine, theirs in zip(s.rows, cli_out["rows"]):
        for key, value in theirs.items():
            if "time" in key or "seconds" in key:
                continue  # wall time
            assert mine[key] == value, key
    assert s.table["h"].dtype == float and len(s.table["h"]) == 6
    assert s["orders"] == cli_out["orders"]


def test_a_study_option_error_names_the_option(source_dir):
    with pytest.raises(moreau.SceneError) as e:
        moreau.study(source_dir / "scenes" / "coulomb-oscillator.json", h=[1e-2, -1.0])
    assert e.value.pointer.startswith("/h")


def test_a_sampling_study_of_a_tracking_scene(cli, source_dir):
    path = source_dir / "scenes" / "manipulator-tracking-digital.json"
    cli_out = json.loads(subprocess.run([str(cli), "study", str(path), "--periods", "1e-2,5e-3", "--laws", "implicit", "--json"],
                                        capture_output=True, text=True, check=True).stdout)
    s = moreau.study(path, periods=[1e-2, 5e-3], laws=["implicit"])
    assert [r["error_final"] for r in s.rows] == [r["error_final"] for r in cli_out["rows"]]


def test_a_campaign_writes_the_command_lines_files(cli, source_dir, tmp_path):
    spec = source_dir / "campaigns" / "manipulator-robust.json"
    doc = json.loads(spec.read_text())
    doc["samples"] = 16
    doc["scene"] = str((spec.parent / doc["scene"]).resolve()) if isinstance(doc["scene"], str) else doc["scene"]
    spec_file = tmp_path / "spec.json"
    spec_file.write_text(json.dumps(doc))
    subprocess.run([str(cli), "campaign", str(spec_file), "--out", str(tmp_path / "cli"), "-j", "2", "--quiet"],
                   capture_output=True, check=True)
    calls = []
    c = moreau.campaign(spec_file, out=tmp_path / "py", jobs=2, progress=lambda done, total: calls.append((done, total)))
    assert c.ran == 16 and c.summary is not None
    assert calls and calls[-1] == (16, 16)
    cli_summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    for key in cli_summary:
        if "time" not in key and "seconds" not in key:
            assert c.summary[key] == cli_summary[key], key
    assert sorted(p.name for p in c.figures) == sorted(p.name for p in (tmp_path / "cli" / "figures").iterdir())
    assert len(c.samples) == 16
    # Run again: every sample is there already, nothing is run.
    again = moreau.campaign(spec_file, out=tmp_path / "py", jobs=1)
    assert again.ran == 0 and again.skipped == 16
