# ruff: noqa: E501 -- a table of cases: one case a line reads best
"""Hand-edited ``session.json`` of ``umbra sketch``: every damage is ``FILE[:LINE]: error: ...``
with exit status 2 and the session left as it was, never a traceback (the eight tracebacks of
issue #29: Latin-1, deep nesting, seed type, events shape, unknown command, missing keys...)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from umbra.connectors.errors import UserError
from umbra.modules.sketch.session_file import MAX_SESSION_EVENTS, parse_session_state
from umbra.runtime.cli.main import main

REPO = Path(__file__).resolve().parents[2]
AIM = {"cmd": "aim", "xyz": [0.5, 0.0, 0.3], "at": None, "zoom": 0.2}
PLACE = {"cmd": "place", "kind": "line", "a": ["1,2", "3,4"], "b": ["5,6", "7,8"], "truth": None,
         "noise": 0.5, "seed": 1}  # fmt: skip
PLAY = {"cmd": "play", "path": "path1", "script": [[0.0, "play", None], [2.0, "speed", 0.5]],
        "timeout": 60.0}  # fmt: skip
VALID = {"seed": 3, "events": [AIM, {"cmd": "snapshot"}, PLACE, PLAY]}


def _doc(**change: object) -> bytes:
    return json.dumps({**VALID, **change}).encode()


def _event(base: dict, **change: object) -> bytes:
    return _doc(events=[{**base, **change}])


def _missing(base: dict, key: str) -> bytes:
    return _doc(events=[{k: v for k, v in base.items() if k != key}])


CASES = [
    ("latin1", b'{"seed": 3,\n "events": [{"cmd": "aim", "at": "caf\xe9"}]}',
     r":2: error: not UTF-8 text \(byte \d+ is 0xe9\)"),
    ("deep_nesting", b'{"seed": 3, "events": ' + b"[" * 100_000 + b"]" * 100_000 + b"}",
     r": error: Expected `object`, got `array` - at `\$.events\[0\]`"),
    ("deep_nesting_options", _event({"cmd": "plan", "macro": "grab_pipe", "primitive": None,
     "options": {}}, options={"x": json.loads("[" * 500 + "]" * 500)}),
     r": error: Expected `float`, got `array` - at `\$.events\[0\].options\[...\]`"),
    ("seed_string", _doc(seed="3"), r": error: Expected `int`, got `str` - at `\$.seed`"),
    ("seed_float", _doc(seed=3.5), r": error: Expected `int`, got `float` - at `\$.seed`"),
    ("seed_negative", _doc(seed=-1), r": error: Expected `int` >= 0 - at `\$.seed`"),
    ("seed_huge", b'{"seed": 1' + b"0" * 5000 + b', "events": []}', r": error: .*\$.seed"),
    ("events_object", _doc(events={}), r": error: Expected `array`, got `object` - at `\$.events`"),
    ("events_of_strings", _doc(events=["aim"]), r"Expected `object`, got `str` - at `\$.events\[0\]`"),
    ("unknown_command", _event({"cmd": "launch"}), r": error: unknown value 'launch' \(expected one of aim, snapshot, place, macros, plan, play\) - at `\$.events\[0\].cmd`"),
    ("missing_cmd", _event({"xyz": [1, 2, 3]}), r"missing required field `cmd` - at `\$.events\[0\]`"),
    ("missing_seed", json.dumps({"events": []}).encode(), r"missing required field `seed`"),
    ("missing_events", json.dumps({"seed": 1}).encode(), r"missing required field `events`"),
    ("missing_zoom", _missing(AIM, "zoom"), r"missing required field `zoom` - at `\$.events\[0\]`"),
    ("missing_script", _missing(PLAY, "script"), r"missing required field `script`"),
    ("unknown_key", _event(AIM, speed=9), r"unknown field `speed` - at `\$.events\[0\]`"),
    ("zoom_2", _event(AIM, zoom=2), r"Expected `float` <= 1.0 - at `\$.events\[0\].zoom`"),
    ("xyz_nan", b'{"seed": 1, "events": [{"cmd": "aim", "xyz": [NaN, 0, 0], "at": null, "zoom": null}]}',
     r"^/\S+session.json:1: error: JSON is malformed"),
    ("xyz_1e999", b'{"seed": 1, "events": [{"cmd": "aim", "xyz": [1e999, 0, 0], "at": null, "zoom": null}]}',
     r"error: .*at `\$.events\[0\].xyz\[0\]`"),
    ("aim_both", _event(AIM, at="pipe_center"), r"expected `xyz` of 3 numbers or `at` \(one of them\)"),
    ("aim_neither", _event(AIM, xyz=[]), r"expected `xyz` of 3 numbers or `at` \(one of them\)"),
    ("place_kind", _event(PLACE, kind="cube"), r"unknown value 'cube' \(expected one of point, line, plane, triad\) - at `\$.events\[0\].kind`"),
    ("place_noise", _event(PLACE, noise=1e6), r"<= 20.0 - at `\$.events\[0\].noise`"),
    ("play_action", _event(PLAY, script=[[0, "explode", None]]), r"unknown value 'explode' \(expected one of play, back, .*\) - at `\$.events\[0\].script\[0\]\[1\]`"),
    ("play_step_shape", _event(PLAY, script=[[0, "play"]]), r"Expected `array` of length 3.*script\[0\]"),
    ("play_negative_time", _event(PLAY, script=[[-1, "play", None]]), r">= 0.0 - at `\$.events\[0\].script\[0\]\[0\]`"),
    ("play_timeout", _event(PLAY, timeout=0), r"> 0.0 - at `\$.events\[0\].timeout`"),
    ("too_many_events", _doc(events=[{"cmd": "snapshot"}] * (MAX_SESSION_EVENTS + 1)),
     rf"length <= {MAX_SESSION_EVENTS} - at `\$.events`"),
    ("not_json", b"seed: 3\nevents: []\n", r":1: error: JSON is malformed"),
    ("empty", b"", r": error: Input data was truncated"),
    ("array", b"[]", r": error: Expected `object`, got `array`"),
    ("nul", b'{"seed": 3, "events": []}\x00', r":1: error: not a text file \(contains a NUL byte\)"),
    ("pixel_nan", _event(PLACE, a=["nan,1", "3,4"]), r"expected a pixel written U,V \(finite numbers, like 320.5,240\) - at `\$.events\[0\].a\[0\]`"),
    ("pixel_huge", _event(PLACE, b=["1,2", "1e999,4"]), r"expected a pixel written U,V .* - at `\$.events\[0\].b\[1\]`"),
    ("pixel_three", _event(PLACE, a=["1,2,3"]), r"expected a pixel written U,V"),
]  # fmt: skip


def test_a_valid_session_reads_back_as_written() -> None:
    state = parse_session_state(json.dumps(VALID).encode(), "session.json")
    assert state == VALID


@pytest.mark.parametrize(("name", "data", "error"), CASES, ids=[c[0] for c in CASES])
def test_a_damaged_session_file_is_a_located_error(name: str, data: bytes, error: str) -> None:
    with pytest.raises(UserError) as err:
        parse_session_state(data, "/s/session.json")
    message = str(err.value)
    assert message.startswith("/s/session.json"), message
    assert re.search(error, message), message
    assert "\n" not in message


@pytest.mark.parametrize("name", ["latin1", "deep_nesting", "seed_string", "events_object",
                                  "unknown_command", "missing_cmd", "missing_zoom", "play_step_shape"])  # fmt: skip
def test_the_sketch_cli_refuses_it_and_keeps_the_file(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _name, data, error = next(c for c in CASES if c[0] == name)
    folder = tmp_path / "s"
    folder.mkdir()
    (folder / "session.json").write_bytes(data)
    assert main(["sketch", "macros", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    (line,) = err.strip().splitlines()
    assert line.startswith(f"{folder / 'session.json'}") and re.search(error, line), line
    assert (folder / "session.json").read_bytes() == data


def test_no_traceback_reaches_the_terminal(tmp_path: Path) -> None:
    folder = tmp_path / "s"
    folder.mkdir()
    (folder / "session.json").write_bytes(next(c[1] for c in CASES if c[0] == "latin1"))
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "sketch", "snapshot", str(folder)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.startswith(f"{folder / 'session.json'}:2: error: not UTF-8 text")


def test_an_event_the_session_cannot_replay_names_the_file_and_the_event(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Well-typed but impossible: an aim at a feature the scene does not have (the 2nd event)."""
    folder = tmp_path / "s"
    folder.mkdir()
    events = [{"cmd": "snapshot"}, {"cmd": "aim", "xyz": [], "at": "moon_center", "zoom": None}]
    data = json.dumps({"seed": 3, "events": events}).encode()
    (folder / "session.json").write_bytes(data)
    assert main(["sketch", "macros", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{folder / 'session.json'}: error: event 2 (aim) cannot be replayed: ")
    assert "unknown feature 'moon_center'" in err and "Traceback" not in err
    assert (folder / "session.json").read_bytes() == data
