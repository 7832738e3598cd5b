"""`umbra sketch ...`: one session over separate calls, snapshot files, user errors exit 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import pytest

from runtime.cli.main import main as umbra_main


def _umbra(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "runtime.cli.main", "sketch", *args],
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
    assert max(line["largest_sigma_mm"]) < 10.0
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
