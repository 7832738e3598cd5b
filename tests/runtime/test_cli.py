"""The command line: every command, --help, bad command lines, exit statuses, plug-ins."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from umbra.runtime.cli.main import main

GRAPH = """graph: demo
modules:
  src: {type: Counter, rate: 100, params: {stop_after: 20}}
  g: {type: Gain, params: {gain: 2}}
  rec: {type: Recorder, params: {channels: [y]}}
connections:
  - src.count -> g.input
  - g.output -> rec.y
"""


@pytest.fixture
def graph(tmp_path: Path) -> Path:
    path = tmp_path / "demo.yaml"
    path.write_text(GRAPH)
    return path


def umbra(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_run_check_graph_describe_modules(graph: Path, tmp_path: Path, capsys) -> None:
    assert main(["run", str(graph), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert (tmp_path / "o" / "summary.json").exists()
    assert main(["check", str(graph)]) == 0
    assert "graph `demo`, 3 modules" in capsys.readouterr().out
    assert main(["graph", str(graph), "--format", "mermaid"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("flowchart LR") and "src -->|count → input| g" in out
    assert main(["graph", str(graph)]) == 0
    assert '"src" -> "g" [label="count → input"]' in capsys.readouterr().out
    assert main(["describe", "Gain"]) == 0
    text = capsys.readouterr().out
    assert "input: Scalar [trigger]  value to scale" in text
    assert "gain: float = 1.0 (tunable)  factor" in text
    assert main(["modules"]) == 0
    assert "Counter" in capsys.readouterr().out


def test_set_overrides_a_parameter(graph: Path, tmp_path: Path) -> None:
    from umbra.modules.generic.recording import read_recording

    out = tmp_path / "o"
    assert main(["run", str(graph), "--out", str(out), "--quiet", "--set", "g.gain=5"]) == 0
    values = [m.value for _, m in read_recording(out / "recording.mcap")]
    assert values[:3] == [0.0, 5.0, 10.0]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["run"], "the following arguments are required: GRAPH"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
        (["graph", "x.yaml", "--format", "png"], "invalid choice: 'png'"),
        (["run", "GRAPH", "--clock", "fast"], "invalid choice: 'fast'"),
        (["run", "GRAPH", "--duration", "abc"], "invalid float value: 'abc'"),
        (["run", "GRAPH", "--duration", "-1"], "--duration must be a positive, finite number"),
        (["run", "GRAPH", "--duration", "inf"], "--duration must be a positive, finite number"),
        (["run", "GRAPH", "--attended"], "--attended: a person acts in real time: expected the"),
        (["run", "GRAPH", "--run-id", "abc"], "--run-id: a run in one process has no links"),
        (
            ["run", "GRAPH", "--connect", "tcp/127.0.0.1:7447"],
            "--connect: a run in one process has no links",
        ),
        (
            ["run", "GRAPH", "--foxglove", "--foxglove-port", "70000"],
            "--foxglove-port: expected a port from 0 to 65535 (0: any free one), found 70000",
        ),
        (
            ["run", "GRAPH", "--foxglove", "--foxglove-origin", "127.0.0.1:8080"],
            "--foxglove-origin: expected a page origin http(s)://host[:port]",
        ),
        (["replay", "x.mcap", "GRAPH", "--duration", "inf"], "--duration must be a positive, fin"),
        (["trials", "GRAPH", "--seed", "-1"], "--seed: expected a non-negative integer, found -1"),
        (["run", "GRAPH", "--set", "gain=2"], "--set expects MODULE.PARAM=VALUE"),
        (["run", "GRAPH", "--set", "nope.gain=2"], "--set: unknown module `nope`"),
        (["run", "GRAPH", "--set", "g.gain=abc"], "--set g.gain: error: parameter `gain`"),
        (["describe", "Counterr"], "unknown module type `Counterr`; did you mean `Counter`?"),
        (["check", "missing.yaml"], "missing.yaml: error: no such graph file"),
    ],
)
def test_bad_command_lines_exit_2_without_traceback(
    graph: Path, args: list[str], fragment: str
) -> None:
    args = [str(graph) if a == "GRAPH" else a for a in args]
    proc = umbra(*args)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert fragment in proc.stderr


def test_help_on_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    """Every command's --help, through the parser the console script builds (in this process),
    and the whole list from `python -m umbra.runtime.cli.main --help` in a process of its own."""
    from umbra.runtime.cli.main import _load_commands

    for cmd in _load_commands():
        with pytest.raises(SystemExit) as stop:
            main([cmd.NAME, "--help"])
        assert stop.value.code == 0, cmd.NAME
        assert "usage: umbra " + cmd.NAME in capsys.readouterr().out
    proc = umbra("--help")  # the module entry point, in a process of its own
    assert proc.returncode == 0 and all(cmd.NAME in proc.stdout for cmd in _load_commands())


def test_the_listing_is_what_the_loaded_commands_declare(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``umbra --help`` (commands' NAME and HELP read from their source) prints exactly what the
    parser built from every loaded command prints; a module whose HELP is built when it runs is
    not read (the listing then loads every command)."""
    from umbra.runtime.cli.main import _declared_face, _load_commands, build_parser

    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    assert stop.value.code == 0
    assert capsys.readouterr().out == build_parser(None).format_help()  # all loaded, configured
    for cmd in _load_commands():
        assert _declared_face(cmd.__name__) == (cmd.NAME, cmd.HELP), cmd.__name__
    (tmp_path / "built_help_cmd.py").write_text("NAME = 'x'\nHELP = 'a ' + 'sum'\n")
    (tmp_path / "plain_help_cmd.py").write_text("NAME = 'x'\nHELP = 'a' ' sum'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _declared_face("built_help_cmd") is None
    assert _declared_face("plain_help_cmd") == ("x", "a sum")
    assert _declared_face("umbra.runtime.cli.no_such_command") is None


def test_failed_run_exits_1(tmp_path: Path) -> None:
    graph = tmp_path / "bad.yaml"
    graph.write_text(
        "graph: g\nmodules:\n  p: {type: Printer}\n  s: {type: TwistSource, rate: 1}\n"
        "connections: [s.twist -> p.value]\n"
    )
    # TwistSource with a twist of the wrong length is rejected before start
    proc = umbra("run", str(graph), "--out", str(tmp_path / "o"), "--set", "s.twist=[1, 2]")
    assert proc.returncode == 2 and "twist" in proc.stderr
    assert "--set s.twist: error: parameter `twist` of `s`" in proc.stderr
    assert "at least 6 items" in proc.stderr
    assert not (tmp_path / "o" / "summary.json").exists()  # nothing ran


def test_third_party_package_adds_a_module_type(tmp_path: Path) -> None:
    site = tmp_path / "site"
    (site / "acme_filters-0.1.dist-info").mkdir(parents=True)
    (site / "acme_filters-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: acme-filters\nVersion: 0.1\n"
    )
    (site / "acme_filters-0.1.dist-info" / "entry_points.txt").write_text(
        "[umbra.modules]\nAcmeDouble = acme_filters:AcmeDouble\n"
    )
    (site / "acme_filters.py").write_text(
        textwrap.dedent('''
        from umbra.connectors import Input, Module, Output
        from umbra.connectors.messages import Scalar

        class AcmeDouble(Module):
            """Doubles a scalar (a third-party module)."""
            x = Input(Scalar, trigger=True)
            y = Output(Scalar)

            def step(self, now):
                s = self.x.get(now)
                if s is not None:
                    self.y.send(Scalar(value=2 * s.value))
        ''')
    )
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "graph: g\nmodules:\n  c: {type: Counter, rate: 10, params: {stop_after: 3}}\n"
        "  d: {type: AcmeDouble}\n  p: {type: Printer, params: {max_rate_hz: 100}}\n"
        "connections: [c.count -> d.x, d.y -> p.value]\n"
    )
    env = {"PYTHONPATH": f"{site}:{Path.cwd()}", "PATH": "/usr/bin:/bin"}
    proc = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "modules", "--json"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert json.loads(proc.stdout)["AcmeDouble"] == "Doubles a scalar (a third-party module)."
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "run",
            str(graph),
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "value=4" in proc.stdout
