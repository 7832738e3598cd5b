"""``umbra check`` refuses what ``umbra run`` would, in the modules' own parameter declarations:
a SONY ``port`` that is no serial device (``'&a x'``) and a scripted-operator step that is no
command (issue #29: check passed both, run refused them)."""

from __future__ import annotations

import re
from pathlib import Path

import pydantic
import pytest

from umbra.modules.calib.visca.sony import Sony
from umbra.modules.sketch.operator_script import SketchOperatorSim
from umbra.runtime.cli.main import main
from umbra.runtime.graph.parse import parse_graph_file

REPO = Path(__file__).resolve().parents[2]
SKETCH = (REPO / "graphs" / "active_sketch.yaml").read_text()
SONY_GRAPH = """graph: sony_port
modules:
  sony: {{type: SONY, rate: 20, params: {{port: {port}}}}}
"""


@pytest.mark.parametrize(
    "port",
    ["sim", "/dev/ttyUSB0", "/dev/serial/by-id/usb-FTDI_FT232R-if00-port0", "/dev/pts/7", "COM3"],
)
def test_serial_devices_and_sim_are_ports(port: str) -> None:
    assert Sony.Params(port=port).port == port


@pytest.mark.parametrize(
    "port", ["&a x", "", " ", "ttyUSB0", "/dev/tty USB0", "/dev/ttyUSB0;reboot", "SIM", "*", "/"]
)
def test_anything_else_is_refused_by_check_at_its_line(
    port: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(pydantic.ValidationError, match="is not a serial device"):
        Sony.Params(port=port)
    graph = tmp_path / "sony.yaml"
    graph.write_text(SONY_GRAPH.format(port=repr(port)))
    assert main(["check", str(graph)]) == 2
    err = capsys.readouterr().err
    assert re.search(rf"^{re.escape(str(graph))}:3:\d+: error: parameter `port` of `sony`: ", err)
    assert "is not a serial device" in err and "Traceback" not in err


def _sketch_with(step: str) -> str:
    return SKETCH.replace("        - vcr pause\n", f"        - {step!r}\n", 1)


@pytest.mark.parametrize(
    ("step", "why"),
    [
        ("rm -rf /", "not a command; expected one of aim, zoom, snapshot"),
        ("", "not a command"),
        ("vcr fly", "expected vcr ACTION [NUMBER] with ACTION one of play"),
        ("wait soon", "expected `wait S` with 0 <= S <= 3600 seconds"),
        ("wait nan", "expected `wait S`"),
        ("wait_vcr flying", "expected `wait_vcr MODE` with MODE one of idle"),
        ("settle 3", "expected `settle` alone"),
        ("place blob @pipe", "expected `place KIND @feature`, KIND one of point"),
        ("zoom 2", "expected zoom Z with 0 <= Z <= 1"),
        ("aim 1 2", "expected aim X Y Z [ZOOM]"),
    ],
)
def test_a_script_step_that_is_no_command_fails_check_at_its_line(
    step: str, why: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "sketch.yaml"
    graph.write_text(_sketch_with(step))
    assert main(["check", str(graph)]) == 2
    err = capsys.readouterr().err
    line = _sketch_with(step).splitlines().index(f"        - {step!r}") + 1
    script_at = _sketch_with(step).splitlines().index("      script:") + 1
    found = re.search(rf"^{re.escape(str(graph))}:(\d+):\d+: error: .*script step 8 ", err, re.M)
    # at the step, or at the script's value (the list) where the check places parameter errors
    assert found and int(found.group(1)) in (line, script_at, script_at + 1), err
    assert why in err and "Traceback" not in err


def test_run_refuses_the_same_step_before_anything_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    graph = tmp_path / "sketch.yaml"
    graph.write_text(_sketch_with("rm -rf /"))
    code = main(["run", str(graph), "--clock", "sim", "--duration", "0.1", "--quiet",
                 "--out", str(tmp_path / "out")])  # fmt: skip
    assert code == 2
    assert "script step 8 'rm -rf /': not a command" in capsys.readouterr().err


def test_every_step_of_the_shipped_sketch_scripts_is_a_command() -> None:
    for name in ("active_sketch.yaml", "active_sketch_3d.yaml", "active_sketch_page.yaml"):
        assert main(["check", str(REPO / "graphs" / name)]) == 0, name
        spec = parse_graph_file(REPO / "graphs" / name)  # the 3-D one extends active_sketch
        assert "SketchOperatorSim" in {m.type for m in spec.modules.values()}
    assert SketchOperatorSim.Params(script=["wait 0", "wait_vcr done", "vcr play 0.5"]).script
