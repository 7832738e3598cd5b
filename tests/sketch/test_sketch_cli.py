"""`umbra sketch ...`: one session over separate calls, snapshot files, user errors exit 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

from umbra.runtime.cli.main import main as umbra_main


def _umbra(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "sketch", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.fixture
def run_json(capsys):
    """`umbra sketch ... --json` in this process (the CLI's own main; no start-up cost)."""

    def run(*args: str) -> dict:
        code = umbra_main(["sketch", *args, "--json"])
        out, err = capsys.readouterr()
        assert code == 0, err
        return json.loads(out)

    return run


def test_cli_session_snapshot_place_plan_play(tmp_path: Path, run_json):
    _json = run_json
    s = str(tmp_path / "s")
    _json("new", s, "--seed", "3")
    _json("aim", s, "--at", "pipe_center", "--zoom", "0.3")
    snap = _json("snapshot", s)
    image = cv2.imread(str(tmp_path / "s" / snap["images"][0]))
    assert image.shape == (480, 640, 3)
    models = json.loads((tmp_path / "s" / "snap1.json").read_text())
    assert models["a"]["zoom"] == 0.3 and len(models["b"]["T_base_camera"]) == 4
    line = _json("place", s, "line", "--truth", "pipe", "--noise", "0.3")
    assert line["primitive"] == "line1" and "grab_pipe" in line["macros"]
    # scene 3's pipe runs 10 deg from image b's epipolar lines: flagged, its sigma says so
    assert "within 10.4 deg of the epipolar lines" in line["warnings"][0]
    assert 15.0 < max(line["largest_sigma_mm"]) < 30.0, line["largest_sigma_mm"]
    plan = _json("plan", s, "grab_pipe", "line1")
    assert plan["ok"] and plan["checks"]["peak_tool_speed"] <= 0.08
    played = _json("play", s, "path1", "--script", "0:play 2:pause 2.5:back 3.5:play@0.5")
    assert played["mode"] == "done" and played["success"], played


def test_cli_user_errors_exit_2_without_traceback(tmp_path: Path, run_json, capsys):
    done = _umbra("snapshot", str(tmp_path / "none"))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "expected a session folder with session.json" in done.stderr
    s = str(tmp_path / "s")
    run_json("new", s)
    capsys.readouterr()
    assert umbra_main(["sketch", "place", s, "line", "--a", "1,2", "--b", "3"]) == 2
    assert "expected pixels as U,V, got '3'" in capsys.readouterr().err
    assert umbra_main(["sketch", "plan", s, "grab_pipe", "line9"]) == 2
    assert "no primitive 'line9'" in capsys.readouterr().err


def test_cli_bad_input_exits_2_says_what_was_expected_and_keeps_the_session(
    tmp_path: Path, run_json, capsys
):
    s = str(tmp_path / "s")
    run_json("new", s, "--seed", "3")
    run_json("aim", s, "--at", "pipe_center", "--zoom", "0.3")
    run_json("snapshot", s)
    run_json("place", s, "line", "--truth", "pipe")
    run_json("plan", s, "grab_pipe", "line1")
    capsys.readouterr()
    state = (tmp_path / "s" / "session.json").read_text()
    cases = [
        (["place", s, "line", "--a", "1,2,3", "4,5", "--b", "1,2", "3,4"], "got '1,2,3'"),
        (["place", s, "line", "--a", "abc", "4,5", "--b", "1,2", "3,4"], "got 'abc'"),
        (["place", s, "line", "--a", "nan,5", "4,5", "--b", "1,2", "3,4"], "(finite numbers)"),
        (["place", s, "line", "--truth", "pipe", "--noise", "nan"], "--noise within 0 .. 20"),
        (["place", s, "line", "--truth", "nothing"], "unknown feature 'nothing'; expected"),
        (["plan", s, "fly_away", "line1"], "there is no macro 'fly_away'; expected one of ready,"),
        (["plan", s, "surface_scan", "line1"], "'surface_scan' is not on the menu for a line"),
        (["plan", s, "move_around_axis", "line1", "--option", "angle_deg=nan"], "(finite)"),
        (["plan", s, "move_around_axis", "line1", "--option", "angle_deg=1e308"], "-180 .. 180"),
        (["plan", s, "grab_pipe", "line1", "--option", "standoff=0.1"], "its options: none"),
        (["plan", s, "make_box", "line1"], "make_box needs a triad, got line"),
        (["aim", s, "nan", "0", "0"], "expected finite X Y Z"),
        (["aim", s, "5", "5", "5"], "outside the unit's travel"),
        (["aim", s, "0.5", "0", "0.3", "--zoom", "nan"], "--zoom within 0 .. 1"),
        (["play", s, "path1", "--script", "0:fly"], "unknown action 'fly'"),
        (["play", s, "path1", "--script", "nan:play"], "a time >= 0 s"),
        (["play", s, "path1", "--script", "0:play@nan"], "a finite number"),
        (["play", s, "path1", "--script", "0:play@5"], "a speed within 0.1 .. 1, got 5.0"),
        (["play", s, "path1", "--script", "0:pause@0.5"], "0.0:pause: takes nothing"),
        (["play", s, "path1", "--timeout", "nan"], "--timeout within 0 .. 3600"),
        (["new", str(tmp_path / "t"), "--seed", "-1"], "expected a seed >= 0, got -1"),
    ]
    for args, message in cases:
        assert umbra_main(["sketch", *args]) == 2, args
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, (args, err)
        assert (tmp_path / "s" / "session.json").read_text() == state  # nothing was kept
    # an aim beyond the units' travel used to end in a traceback: a separate process shows none
    done = _umbra("aim", s, "5", "5", "5")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    # the whole camera model at zoom 0 (0.009 rad tilt in its mount): 62.6 deg, not 62.9
    assert "tilt 62.6 deg is outside the unit's travel" in done.stderr
    # and the session still plays its checked path
    assert run_json("play", s, "path1")["success"]


def test_cli_clicks_by_pixels_as_in_the_readme(tmp_path: Path, run_json):
    """The README's sequence: clicks typed as pixels on the pipe of scene 3 grab it."""
    s = str(tmp_path / "s")
    run_json("new", s, "--seed", "3")
    run_json("aim", s, "--at", "pipe_center", "--zoom", "0.3")
    run_json("snapshot", s)
    line = run_json("place", s, "line", "--a", "525,109", "107,175", "--b", "544,109", "101,171")
    assert line["primitive"] == "line1"
    assert "grab_pipe" in run_json("macros", s, "line1")["macros"]
    assert run_json("plan", s, "grab_pipe", "line1")["ok"]
    script = "0:play 2:pause 2.5:back 3.5:play@0.5 5:speed@1"
    played = run_json("play", s, "path1", "--script", script)
    assert played["mode"] == "done" and played["success"], played


def test_cli_place_warns_when_the_depth_rests_on_the_handles(tmp_path: Path, run_json):
    """Scene 5's pipe runs 0.5 deg from image b's epipolar lines: its line is flagged with what
    to do, and its stated sigma holds the handle error; the door's vertical hinge is not."""
    s = str(tmp_path / "s")
    run_json("new", s, "--seed", "5")
    run_json("aim", s, "--at", "pipe_center", "--zoom", "0.3")
    run_json("snapshot", s)
    pipe = run_json("place", s, "line", "--truth", "pipe", "--noise", "0")
    (warning,) = pipe["warnings"]
    assert warning.startswith("line1: depth poorly constrained: in image b it runs within 0.5 deg")
    assert "live wrist view" in warning and "another pan of the same cameras does not" in warning
    assert min(pipe["largest_sigma_mm"]) > 35.0  # 20 px of handle error at ~2.2 mm per px
    hinge = run_json("place", s, "line", "--truth", "hinge", "--noise", "0")
    assert hinge["warnings"] == [] and max(hinge["largest_sigma_mm"]) < 10.0
