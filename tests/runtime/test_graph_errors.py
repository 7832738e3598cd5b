"""A corpus of malformed graphs: each must fail with the exact line and column of the fault."""

from __future__ import annotations

import pytest

from tests.runtime.fixtures import make_registry
from umbra.connectors.errors import CheckFailed, UserError
from umbra.runtime.graph.check import check_text

OK_HEAD = "graph: g\nmodules:\n"

# (name, text, [(line, col, substring of the message)])
CASES = [
    ("yaml syntax", "graph: g\nmodules: [a, b\n", [(3, 1, "YAML syntax")]),
    ("tab indentation", "graph: g\nmodules:\n\ta: 1\n", [(3, 1, "YAML syntax")]),
    ("top level list", "- a\n- b\n", [(1, 1, "must be a mapping")]),
    ("top level scalar", "hello\n", [(1, 1, "must be a mapping")]),
    ("empty file", "", [(1, 1, "empty graph file")]),
    ("only comments", "# nothing\n", [(1, 1, "empty graph file")]),
    (
        "unknown top key",
        "graph: g\nmodule:\n  a: {type: Counter, rate: 1}\n",
        [(2, 1, "unknown key `module`"), (1, 1, "missing `modules:`")],
    ),
    ("missing graph name", "modules:\n  a: {type: Counter, rate: 1}\n", [(1, 1, "missing `graph")]),
    (
        "bad graph name",
        "graph: my graph\nmodules:\n  a: {type: Counter, rate: 1}\n",
        [(1, 8, "identifier")],
    ),
    ("modules not mapping", "graph: g\nmodules: [a]\n", [(2, 10, "must be a mapping")]),
    ("empty modules", "graph: g\nmodules: {}\n", [(2, 10, "is empty")]),
    (
        "unknown module type",
        OK_HEAD + "  a: {type: Countr, rate: 1}\n",
        [(3, 13, "unknown module type `Countr`; did you mean `Counter`?")],
    ),
    ("module without type", OK_HEAD + "  a: {rate: 1}\n", [(3, 3, "needs `type")]),
    (
        "unknown module key",
        OK_HEAD + "  a: {type: Counter, rat: 1}\n",
        [(3, 22, "unknown key `rat`"), (3, 3, "needs `rate: HZ`")],
    ),
    ("negative rate", OK_HEAD + "  a: {type: Counter, rate: -5}\n", [(3, 28, "positive number")]),
    ("rate not a number", OK_HEAD + "  a: {type: Counter, rate: fast}\n", [(3, 28, "positive")]),
    (
        "unknown parameter",
        OK_HEAD + "  a: {type: Counter, rate: 1, params: {strat: 1}}\n",
        [(3, 40, "unknown parameter `strat` for Counter `a`; did you mean `start`?")],
    ),
    (
        "parameter wrong type",
        OK_HEAD + "  a: {type: Counter, rate: 1, params: {start: abc}}\n",
        [(3, 47, "parameter `start` of `a`")],
    ),
    (
        "parameter out of range",
        OK_HEAD + "  a: {type: Printer, params: {max_rate_hz: -1}}\n",
        [(3, 44, "greater than 0")],
    ),
    (
        "parameter bad choice",
        OK_HEAD + "  a: {type: Signal, rate: 1, params: {waveform: saw}}\n",
        [(3, 49, "parameter `waveform`")],
    ),
    (
        "duplicate module",
        OK_HEAD + "  a: {type: Counter, rate: 1}\n  a: {type: Counter, rate: 2}\n",
        [(4, 3, "duplicate key `a` (first at line 3)")],
    ),
    (
        "unknown process",
        "graph: g\nprocesses: {umbra: {}}\nmodules:\n"
        "  a: {type: Counter, rate: 1, process: umbar}\n",
        [(4, 40, "unknown process `umbar`"), (4, 40, "did you mean `umbra`?")],
    ),
    (
        "process latency negative",
        "graph: g\nprocesses:\n  smart: {cpu_latency_us: -3}\nmodules:\n"
        "  a: {type: Counter, rate: 1, process: smart}\n",
        [(3, 27, "cpu_latency_us of process `smart` must be a whole number of microseconds")],
    ),
    (
        "process latency not a number",
        "graph: g\nprocesses:\n  smart: {cpu_latency_us: low}\nmodules:\n"
        "  a: {type: Counter, rate: 1, process: smart}\n",
        [(3, 27, "found 'low'")],
    ),
    (
        "unknown process setting",
        "graph: g\nprocesses:\n  smart: {cpu_latency: 0}\nmodules:\n"
        "  a: {type: Counter, rate: 1, process: smart}\n",
        [(3, 11, "unknown key `cpu_latency` in process `smart`; did you mean `cpu_latency_us`?")],
    ),
    (
        "process missing",
        "graph: g\nprocesses: {umbra: {}}\nmodules:\n  a: {type: Counter, rate: 1}\n",
        [(4, 3, "needs `process:`")],
    ),
    (
        "unknown module in connection",
        OK_HEAD + "  a: {type: Counter, rate: 1}\n"
        "  p: {type: Printer}\nconnections:\n  - b.count -> p.value\n",
        [(6, 5, "unknown module `b`")],
    ),
    (
        "unknown output port",
        OK_HEAD + "  a: {type: Counter, rate: 1}\n"
        "  p: {type: Printer}\nconnections:\n  - a.cont -> p.value\n",
        [(6, 7, "has no output `cont`; did you mean `count`?")],
    ),
    (
        "unknown input port",
        OK_HEAD + "  a: {type: Counter, rate: 1}\n"
        "  p: {type: Printer}\nconnections:\n  - a.count -> p.valeu\n",
        [(6, 18, "has no input `valeu`; did you mean `value`?")],
    ),
    (
        "input used as output",
        OK_HEAD + "  g: {type: Gain}\n  p: {type: Printer}\nconnections:\n  - g.input -> p.value\n",
        [(6, 7, "`g.input` is an input")],
    ),
    (
        "bad connection syntax",
        OK_HEAD + "  a: {type: Counter, rate: 1}\nconnections:\n  - a.count => p\n",
        [(5, 5, "module.output -> module.input")],
    ),
    (
        "connections not list",
        OK_HEAD + "  a: {type: Counter, rate: 1}\nconnections: a.count\n",
        [(4, 14, "must be a list")],
    ),
    (
        "type mismatch",
        OK_HEAD + "  s: {type: TwistSource, rate: 1}\n  g: {type: Gain}\n"
        "connections:\n  - s.twist -> g.input\n",
        [(6, 7, "type mismatch: `s.twist` sends Twist, `g.input` expects Scalar")],
    ),
    (
        "frame mismatch",
        OK_HEAD + "  s: {type: TwistSource, rate: 1, params: {frame: camera}}\n"
        "  t: {type: TwistSink}\nconnections:\n  - s.twist -> t.twist\n",
        [(6, 7, "frame mismatch: `s.twist` is a Twist in `camera`, `t.twist` wants `tool`")],
    ),
    (
        "two producers",
        OK_HEAD + "  a: {type: Counter, rate: 1}\n  b: {type: Counter, rate: 1}\n"
        "  p: {type: Printer}\nconnections:\n  - a.count -> p.value\n  - b.count -> p.value\n",
        [(8, 16, "input `p.value` has two producers: `a.count` (line 7) and `b.count`")],
    ),
    (
        "required input unconnected",
        OK_HEAD + "  g: {type: Gain}\n",
        [(3, 3, "required input `g.input` (Scalar) is not connected")],
    ),
    (
        "loop without delay",
        OK_HEAD + "  a: {type: Gain, rate: 1}\n  b: {type: Gain}\n"
        "connections:\n  - a.output -> b.input\n  - b.output -> a.input\n",
        [(7, 5, "loop a -> b -> a has no delayed connection")],
    ),
    (
        "unknown frame",
        OK_HEAD + "  s: {type: TwistSource, rate: 1, params: {frame: camra}}\n",
        [(3, 51, "unknown frame `camra` in parameter `frame` of `s`; did you mean `camera`?")],
    ),
    (
        "bad static frame",
        "graph: g\nframes:\n  tool-camera: {xyz: [0, 0, 0]}\nmodules:\n"
        "  a: {type: Counter, rate: 1}\n",
        [(3, 3, "written `parent->child`")],
    ),
    (
        "static frame bad xyz",
        "graph: g\nframes:\n  tool->camera: {xyz: [0, 0]}\nmodules:\n"
        "  a: {type: Counter, rate: 1}\n",
        [(3, 23, "must be 3 numbers")],
    ),
    (
        "joint mismatch",
        OK_HEAD + "  v: {type: ToolTwistSource, rate: 1}\n  r: {type: Guard}\n"
        "  k: {type: Kin, params: {joints: [a, b, c]}}\n  d: {type: Driver}\nconnections:\n"
        "  - v.twist -> r.twist_in\n  - r.twist_out -> k.twist\n  - k.rates -> d.rates\n",
        [
            (
                10,
                7,
                "joint mismatch: `k.rates` carries joints ['a', 'b', 'c'], `d.rates` expects "
                "['j1', 'j2', 'j3']",
            )
        ],
    ),
    (
        "no guard on command path",
        OK_HEAD + "  v: {type: ToolTwistSource, rate: 1}\n"
        "  k: {type: Kin}\n  d: {type: Driver}\nconnections:\n  - v.twist -> k.twist\n"
        "  - k.rates -> d.rates\n  - d.state ~> k.joint_state\n",
        [(8, 5, "command path v -> k -> d.rates has none")],
    ),
    (
        "max age too strict",
        OK_HEAD + "  a: {type: Counter, rate: 10}\n  f: {type: Fresh}\n"
        "connections:\n  - a.count -> f.value\n",
        [(6, 5, "accepts samples up to 0.05 s old, but `a` runs at 10 Hz")],
    ),
    (
        "trigger names no input",
        OK_HEAD + "  a: {type: Counter, rate: 1}\n"
        "  p: {type: Printer, trigger: valu}\nconnections:\n  - a.count -> p.value\n",
        [(4, 31, "`trigger` names `valu`")],
    ),
    (
        "bad clock",
        "graph: g\nclock: wall\nmodules:\n  a: {type: Counter, rate: 1}\n",
        [(2, 8, "clock must be `sim` or `real`")],
    ),
    (
        "bad seed",
        "graph: g\nseed: -1\nmodules:\n  a: {type: Counter, rate: 1}\n",
        [(2, 7, "seed must be a non-negative integer")],
    ),
    (
        "bad link dispatch",
        "graph: g\nlinks: {dispatch: thread}\nmodules:\n  a: {type: Counter, rate: 1}\n",
        [(2, 19, "`links.dispatch` must be one of inline, loop, found str 'thread'")],
    ),
    (
        "python tag",
        "graph: !!python/object/apply:os.system [ls]\nmodules: {}\n",
        [(1, 8, "unsupported YAML tag")],
    ),
]


@pytest.mark.parametrize(("name", "text", "expected"), CASES, ids=[c[0] for c in CASES])
def test_malformed_graph_reports_exact_location(name: str, text: str, expected: list) -> None:
    with pytest.raises(CheckFailed) as info:
        check_text(text, "g.yaml", make_registry())
    lines = str(info.value).splitlines()
    for line, col, fragment in expected:
        prefix = f"g.yaml:{line}:{col}: error: "
        assert any(text_line.startswith(prefix) and fragment in text_line for text_line in lines), (
            f"expected `{prefix}...{fragment}` in:\n" + "\n".join(lines)
        )


def test_corpus_is_large_enough() -> None:
    assert len(CASES) >= 30


def test_all_problems_are_reported_at_once() -> None:
    text = OK_HEAD + (
        "  a: {type: Countr, rate: 1}\n  g: {type: Gain}\n"
        "  p: {type: Printer, params: {max_rate: 3}}\n"
    )
    with pytest.raises(CheckFailed) as info:
        check_text(text, "g.yaml", make_registry())
    assert len(info.value.diagnostics) == 3


def test_guarded_path_passes_and_feedback_is_not_a_command_path() -> None:
    text = OK_HEAD + (
        "  v: {type: ToolTwistSource, rate: 1}\n  r: {type: Guard}\n"
        "  k: {type: Kin}\n  d: {type: Driver}\nconnections:\n"
        "  - v.twist -> r.twist_in\n  - r.twist_out -> k.twist\n"
        "  - k.rates -> d.rates\n  - d.state ~> k.joint_state\n"
    )
    plan = check_text(text, "g.yaml", make_registry())
    assert plan.order == ["v", "r", "k", "d"]


def test_broken_module_type_is_reported_the_same_by_check_and_require() -> None:
    registry = make_registry()
    registry.broken["Acme"] = "ImportError: no module named acme"
    expected = "module type `Acme` failed to load: ImportError: no module named acme"
    with pytest.raises(CheckFailed) as info:
        check_text(OK_HEAD + "  a: {type: Acme, rate: 1}\n", "g.yaml", registry)
    assert str(info.value) == f"g.yaml:3:13: error: {expected}"
    with pytest.raises(UserError) as error:
        registry.require("Acme")
    assert str(error.value) == expected
