"""Graphs compose: ``extends:`` (merge, add, ``!replace``, ``remove_connections``), ``values:``
referenced as ``$NAME``, every problem at the file and line where it is written, and the
composed graph as one text that reads as the same graph."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from umbra.connectors.errors import CheckFailed
from umbra.runtime.cli.main import main
from umbra.runtime.graph.check import check_spec, check_text, load_graph
from umbra.runtime.graph.parse import parse_graph_file, parse_graph_text

REPO = Path(__file__).resolve().parents[2]

BASE = """\
graph: base
values:
  rate_hz: 50
  start: 3
processes:
  umbra: {realtime_priority: 20}
  smart: {}
modules:
  src: {type: Counter, process: umbra, rate: $rate_hz, params: {start: $start, step_by: 2}}
  gain: {type: Gain, process: umbra, params: {gain: 2.0}}
  show: {type: Printer, process: smart, trigger: value}
connections:
  - src.count -> gain.input
  - gain.output -> show.value
"""


def _write(folder: Path, name: str, text: str) -> str:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return str(path)


def _problems(path: str) -> list[str]:
    with pytest.raises(CheckFailed) as info:
        load_graph(path)
    return [str(d) for d in info.value.diagnostics]


def test_an_extending_graph_merges_adds_replaces_and_removes(tmp_path: Path) -> None:
    _write(tmp_path, "graphs/base.yaml", BASE)
    child = _write(
        tmp_path,
        "graphs/child.yaml",
        "extends: base.yaml\n"
        "graph: child\n"
        "values: {rate_hz: 20}\n"
        "processes: {umbra: !replace {}}\n"
        "modules:\n"
        "  src: {params: {step_by: 5}}\n"
        "  tee: {type: Printer, process: smart, trigger: value}\n"
        "connections:\n"
        "  - src.count -> show.value\n"
        "  - src.count -> tee.value\n"
        "remove_connections:\n"
        "  - gain.output -> show.value\n",
    )
    plan = load_graph(child)
    spec = plan.spec
    assert spec.name == "child" and list(spec.processes) == ["umbra", "smart"]
    assert spec.realtime_priority == {}  # `!replace {}`: the base's 20 is gone
    src = spec.modules["src"]
    assert (src.type, src.rate, src.params) == ("Counter", 20.0, {"start": 3, "step_by": 5})
    assert plan.modules["src"].params.step_by == 5 and plan.modules["src"].params.start == 3
    assert [str(c) for c in spec.connections] == [
        "src.count -> gain.input",
        "src.count -> show.value",
        "src.count -> tee.value",
    ]
    assert list(spec.modules) == ["src", "gain", "show", "tee"]
    # each part keeps where it is written: the step in the child, the start in the base's values
    assert src.param_val_loc["step_by"].file.endswith("child.yaml")
    assert src.param_val_loc["start"].file.endswith("base.yaml")
    assert src.param_val_loc["start"].line == 4
    assert spec.sources == [child, str(Path(child).parent / "base.yaml")]


def test_the_composed_text_reads_as_the_same_graph(tmp_path: Path) -> None:
    _write(tmp_path, "base.yaml", BASE)
    child = _write(
        tmp_path, "child.yaml", "extends: base.yaml\ngraph: child\nmodules: {src: {rate: 10}}\n"
    )
    spec = parse_graph_file(child)
    assert spec.text.startswith(f"# {child} as run: composed from")
    assert "extends" not in spec.text and "$" not in spec.text
    again = parse_graph_text(spec.text, "again.yaml")
    assert {n: (m.type, m.rate, m.params) for n, m in again.modules.items()} == {
        n: (m.type, m.rate, m.params) for n, m in spec.modules.items()
    }
    assert [str(c) for c in again.connections] == [str(c) for c in spec.connections]
    assert again.realtime_priority == spec.realtime_priority == {"umbra": 20}
    alone = parse_graph_file(_write(tmp_path, "alone.yaml", BASE))
    assert alone.text == BASE  # a graph that extends nothing is recorded as written


def test_a_bad_parameter_of_the_base_is_reported_at_the_base_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = _write(tmp_path, "base.yaml", BASE.replace("gain: 2.0", "gain: .inf"))
    child = _write(
        tmp_path, "child.yaml", "extends: base.yaml\ngraph: child\nmodules: {src: {rate: -1}}\n"
    )
    found = _problems(child)
    assert any(p.startswith(f"{base}:10:") and "gain" in p for p in found), found
    assert any(p.startswith(f"{child}:3:") and "rate" in p for p in found), found
    assert main(["check", child]) == 2
    err = capsys.readouterr().err
    assert f"{base}:10:" in err and "Traceback" not in err


def test_a_value_a_module_refuses_is_reported_where_values_writes_it(tmp_path: Path) -> None:
    graph = _write(tmp_path, "g.yaml", BASE.replace("rate_hz: 50", "rate_hz: -5"))
    found = _problems(graph)
    assert any(p.startswith(f"{graph}:3:") and "rate" in p for p in found), found


@pytest.mark.parametrize(
    ("text", "line", "fragment"),
    [
        (
            "  - src.count -> show.nope\n",
            13,
            "`remove_connections`: the graph this one extends has",
        ),
        ("  - src.count\n", 13, "a connection to remove is written as in `connections`"),
    ],
)
def test_removing_what_the_base_lacks_is_an_error_at_its_line(
    tmp_path: Path, text: str, line: int, fragment: str
) -> None:
    _write(tmp_path, "base.yaml", BASE)
    child = _write(
        tmp_path,
        "child.yaml",
        "extends: base.yaml\ngraph: child\n" + "\n" * 9 + "remove_connections:\n" + text,
    )
    found = _problems(child)
    assert any(p.startswith(f"{child}:{line}:") and fragment in p for p in found), found


def test_cycles_missing_and_unreadable_bases_are_errors_at_the_extends_line(
    tmp_path: Path,
) -> None:
    a = _write(tmp_path, "a.yaml", "graph: a\nextends: b.yaml\n")
    _write(tmp_path, "b.yaml", "graph: b\n\nextends: a.yaml\n")
    found = _problems(a)
    assert found == [f"{tmp_path}/b.yaml:3:10: error: `extends: a.yaml` makes a cycle: "
                     "a.yaml -> b.yaml -> a.yaml"]  # fmt: skip
    itself = _write(tmp_path, "self.yaml", "extends: self.yaml\ngraph: s\n")
    assert "makes a cycle: self.yaml -> self.yaml" in _problems(itself)[0]
    missing = _write(tmp_path, "m.yaml", "graph: m\nextends: sub/none.yaml\n")
    assert _problems(missing) == [
        f"{missing}:2:10: error: `extends`: no such graph file `{tmp_path}/sub/none.yaml` "
        f"(the path is relative to {missing})"
    ]
    folder = _write(tmp_path, "d.yaml", "graph: d\nextends: .\n")
    assert "is a directory" in _problems(folder)[0]
    os.mkfifo(tmp_path / "pipe.yaml")
    piped = _write(tmp_path, "p.yaml", "graph: p\nextends: pipe.yaml\n")
    assert "not a regular file (a FIFO)" in _problems(piped)[0]
    broken = _write(tmp_path, "broken_base.yaml", "graph: x\nmodules: [a, b\n")
    child = _write(tmp_path, "c.yaml", "extends: broken_base.yaml\ngraph: c\n")
    assert _problems(child)[0].startswith(f"{broken}:3:1: error: YAML syntax")


def test_a_chain_is_bounded(tmp_path: Path) -> None:
    _write(tmp_path, "g0.yaml", BASE)
    for i in range(1, 10):
        _write(tmp_path, f"g{i}.yaml", f"extends: g{i - 1}.yaml\ngraph: g{i}\n")
    assert parse_graph_file(tmp_path / "g7.yaml").name == "g7"  # 8 files
    assert "a chain of more than 8 graph files" in _problems(str(tmp_path / "g9.yaml"))[0]


def test_unknown_values_and_removing_without_a_base_say_what_to_do() -> None:
    text = BASE.replace("rate: $rate_hz", "rate: $rate_hzz") + "remove_connections: []\n"
    with pytest.raises(CheckFailed) as info:
        check_text(text, "g.yaml")
    said = [str(d) for d in info.value.diagnostics]
    assert any(
        s.startswith("g.yaml:9:") and "`$rate_hzz` names no value" in s and "rate_hz" in s
        for s in said
    ), said
    assert any(s.startswith("g.yaml:15:") and "has no `extends:`" in s for s in said), said
    literal = BASE.replace("graph: base\n", "graph: base\ndescription: $$rate_hz\n")
    assert check_text(literal, "g.yaml").spec.description == "$rate_hz"
    nested = BASE.replace("  start: 3\n", "  start: 3\n  twice: [$start]\n")
    with pytest.raises(CheckFailed) as info:
        check_text(nested, "g.yaml")
    assert str(info.value).startswith(
        "g.yaml:5:11: error: a value of `values:` cannot name another value"
    )


def _shape(spec: object) -> dict:
    return {
        "modules": {
            n: (m.type, m.process, m.rate, m.trigger, m.params)
            for n, m in spec.modules.items()  # type: ignore[attr-defined]
        },
        "connections": [str(c) for c in spec.connections],  # type: ignore[attr-defined]
        "frames": [(f.parent, f.child, f.T_parent_child.tolist()) for f in spec.frames],  # type: ignore[attr-defined]
        "processes": list(spec.processes),  # type: ignore[attr-defined]
        "rt": spec.realtime_priority,  # type: ignore[attr-defined]
        "nice": spec.nice,  # type: ignore[attr-defined]
    }


@pytest.mark.parametrize(
    ("variant", "base", "view_inputs"),
    [
        ("tool_pickup_3d.yaml", "tool_pickup.yaml", 5),
        ("active_sketch_3d.yaml", "active_sketch.yaml", 12),
    ],
)
def test_the_shipped_3d_graphs_are_their_base_and_the_view(
    variant: str, base: str, view_inputs: int
) -> None:
    """The 3-D variants are the base graph plus the view and its inputs, nothing else (the
    pick-up's vision process keeps the base's SCHED_FIFO priority: without it, REG_VEL held the
    arm for old data with a page open)."""
    three_d = _shape(parse_graph_file(REPO / "graphs" / variant))
    plain = _shape(parse_graph_file(REPO / "graphs" / base))
    view = three_d["modules"].pop("view3d")
    assert view[0] == "View3D"
    added = [c for c in three_d["connections"] if ".view3d." in f".{c.split(' ')[-1]}"]
    assert len(added) == view_inputs
    assert [c for c in three_d["connections"] if c not in added] == plain["connections"]
    three_d["connections"] = plain["connections"]
    if base == "tool_pickup.yaml":
        assert three_d["rt"] == plain["rt"] == {"umbra": 20, "smart": 50}
    assert three_d == plain


def test_the_wrist_camera_is_written_once_in_the_pickup() -> None:
    text = (REPO / "graphs" / "tool_pickup.yaml").read_text()
    assert text.count("800") == 2 and text.count("0.14]") == 1  # fx, fy; the tool offset
    spec = parse_graph_file(REPO / "graphs" / "tool_pickup_3d.yaml")
    camera, servo = spec.modules["camera"].params, spec.modules["servo"].params
    intrinsics = [camera[k] for k in ("fx", "fy", "u0", "v0", "width", "height")]
    assert spec.modules["view3d"].params["wrist_intrinsics"] == intrinsics == [
        800, 800, 640, 360, 1280, 720
    ]  # fmt: skip
    assert [servo[k] for k in ("fx", "fy", "u0", "v0")] == intrinsics[:4]
    assert camera["patch_size_m"] == [servo["patch_width"], servo["patch_height"]] == [0.06, 0.04]
    assert spec.modules["kinematics"].params["tool_xyz"] == [0, 0, 0.14]
    tool = next(f for f in spec.frames if (f.parent, f.child) == ("flange", "tool"))
    assert tool.T_parent_child[:3, 3].tolist() == [0, 0, 0.14]


def test_a_recording_attaches_the_composed_graph(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    _write(tmp_path, "base.yaml", BASE)
    child = _write(
        tmp_path,
        "child.yaml",
        "extends: base.yaml\ngraph: child\nmodules: {src: {params: {step_by: 7}}}\n",
    )
    out = tmp_path / "run"
    code = main(["run", child, "--single-process", "--clock", "sim", "--duration", "0.2",
                 "--record", "--quiet", "--out", str(out)])  # fmt: skip
    assert code == 0
    with open(out / "recording.mcap", "rb") as f:
        attached = {a.name: a.data for a in make_reader(f).iter_attachments()}[
            "graph.yaml"
        ].decode()
    assert attached == parse_graph_file(child).text
    again = check_spec(parse_graph_text(attached, "attached.yaml"))
    assert again.modules["src"].params.step_by == 7 and again.spec.name == "child"


def test_references_cannot_expand_past_the_node_bound() -> None:
    """``values:`` is no way around the alias bound: 60 references to a list of 2000 numbers
    would be 120 000 nodes."""
    numbers = ", ".join(["1"] * 2000)
    refs = ", ".join(["$big"] * 60)
    text = (
        f"graph: g\nvalues:\n  big: [{numbers}]\n"
        f"modules:\n  a: {{type: Gain, params: {{x: [{refs}]}}}}\n"
    )
    with pytest.raises(CheckFailed) as info:
        check_text(text, "g.yaml")
    first = str(info.value).splitlines()[0]
    assert first.startswith("g.yaml:5:") and "expand to more than 100000 nodes" in first
