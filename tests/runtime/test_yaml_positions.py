"""Positions are right whatever the whitespace: a problem is reported at the line (counted by LF)
and column (characters) where an editor shows it, with CRLF line ends, blank lines, trailing
spaces, Unicode spaces in comments and a byte-order mark; a tab or an invisible space in an
indentation, and a line end an editor may not count, are reported where they are. Merge keys
work as YAML 1.1 defines them. Property-tested against both YAML readers of the project."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from umbra.connectors import safe_yaml
from umbra.connectors.errors import CheckFailed
from umbra.runtime.graph.check import check_text
from umbra.runtime.graph.parse import parse_graph_text

LIMITS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])

#: A sound graph, one line a list item; `BAD` marks the value the checks refuse.
LINES = [
    "graph: g",
    "modules:",
    "  src:",
    "    type: Counter",
    "    rate: BAD",
    "  show: {type: Printer, trigger: value}",
    "connections:",
    "  - src.count -> show.value",
]
ODD_SPACES = ["\t", "\u00a0", "\u2003", "\u2009", "\u202f", "\u3000", "\u200b", "\ufeff", "\u2060"]
#: Whitespace that is fine where it is put: in a blank line, after a value, in a comment.
BLANK = st.sampled_from(["", " ", "   ", "  # a note", "# \u00a0no-break\u3000in a comment"])
TRAILING = st.sampled_from(["", " ", "  ", "  # ok", " #\u2003em space in a comment"])


def _error_lines(text: str) -> list[str]:
    with pytest.raises(CheckFailed) as info:
        check_text(text, "g.yaml")
    return [str(d) for d in info.value.diagnostics]


@LIMITS
@given(
    blanks=st.lists(st.tuples(st.integers(0, len(LINES)), BLANK), max_size=6),
    trailing=st.lists(TRAILING, min_size=len(LINES), max_size=len(LINES)),
    crlf=st.booleans(),
    bom=st.booleans(),
)
def test_a_bad_value_is_reported_where_an_editor_shows_it(
    blanks: list[tuple[int, str]], trailing: list[str], crlf: bool, bom: bool
) -> None:
    lines = [line.replace("BAD", "-5") + tail for line, tail in zip(LINES, trailing, strict=True)]
    for at, blank in sorted(blanks, reverse=True):
        lines.insert(at, blank)
    row = next(i for i, line in enumerate(lines) if line.startswith("    rate: -5"))
    text = ("\ufeff" if bom else "") + ("\r\n" if crlf else "\n").join(lines) + "\n"
    said = _error_lines(text)
    assert any(s.startswith(f"g.yaml:{row + 1}:11: error: rate") for s in said), (text, said)


@LIMITS
@given(
    row=st.integers(2, len(LINES) - 1),
    odd=st.sampled_from(ODD_SPACES),
    crlf=st.booleans(),
    blanks=st.integers(0, 3),
)
def test_an_odd_space_in_an_indentation_is_reported_at_its_own_place(
    row: int, odd: str, crlf: bool, blanks: int
) -> None:
    lines = [line.replace("BAD", "10") for line in LINES]
    lines[1:1] = [""] * blanks
    row += blanks
    indent = len(lines[row]) - len(lines[row].lstrip(" "))
    lines[row] = lines[row][:indent] + odd + lines[row][indent:]
    text = ("\r\n" if crlf else "\n").join(lines) + "\n"
    said = _error_lines(text)
    expected = f"g.yaml:{row + 1}:{indent + 1}: error: "
    assert said[0].startswith(expected), (repr(text), said)
    assert f"(U+{ord(odd):04X}) where YAML expects indentation" in said[0]
    with pytest.raises(safe_yaml.YamlError) as info:  # the other YAML reader: the same place
        safe_yaml.load(text, "f.yaml")
    assert str(info.value).startswith(f"f.yaml:{row + 1}: error: ")
    assert "where YAML expects indentation" in str(info.value)


def test_the_no_break_space_of_the_hostile_corpus_is_reported_on_its_line() -> None:
    text = "graph: g\nmodules:\n  a: {type: Counter, rate: 10}\n  b:\n\u00a0   type: Printer\n"
    assert _error_lines(text) == [
        "g.yaml:5:1: error: a no-break space (U+00A0) where YAML expects "
        "indentation: YAML indents with spaces only"
    ]


@pytest.mark.parametrize("end", ["\r", "\x85", "\u2028", "\u2029"])
def test_a_line_end_an_editor_may_not_count_is_refused_where_it_is(end: str) -> None:
    text = f"graph: g\nmodules:\n  a: {{type: Counter,{end} rate: 10}}\n"
    said = _error_lines(text)
    assert len(said) == 1 and said[0].startswith("g.yaml:3:21: error: ")
    assert "ends a line here" in said[0] and "save the file with LF or CRLF" in said[0]
    with pytest.raises(safe_yaml.YamlError, match=r"^f\.yaml:3: error: .* ends a line here"):
        safe_yaml.load(text, "f.yaml")


MERGE = """\
graph: g
values: {slow: &slow {rate: 5}}
modules:
  src: &counter {type: Counter, rate: 10, params: {start: 1}}
  two:
    <<: *counter
    rate: 20
  three:
    <<: [*slow, *counter]
    params: {step_by: 3}
  show: {type: Printer, trigger: value}
connections:
  - src.count -> show.value
"""


def test_merge_keys_work_as_yaml_11_defines_them() -> None:
    spec = parse_graph_text(MERGE, "g.yaml")
    two, three = spec.modules["two"], spec.modules["three"]
    assert (two.type, two.rate, two.params) == ("Counter", 20.0, {"start": 1})  # own key wins
    assert two.rate_loc is not None and two.rate_loc.line == 7
    assert two.param_val_loc["start"].line == 4  # merged: where the anchor's mapping writes it
    # of a list, the earlier mapping wins (rate 5); a mapping given is the value (no deep merge)
    assert (three.type, three.rate, three.params) == ("Counter", 5.0, {"step_by": 3})
    assert three.rate_loc is not None and three.rate_loc.line == 2
    ordered = "x: &a {rate: 1}\ny: &b {rate: 2, type: T}\nz: {<<: [*a, *b], own: 3}\n"
    assert safe_yaml.load(ordered, "o.yaml")[1]["z"] == {"rate": 1, "type": "T", "own": 3}
    assert safe_yaml.load(ordered.replace("own: 3", "rate: 9"), "o.yaml")[1]["z"]["rate"] == 9


def test_a_key_twice_and_a_bad_merge_are_refused_at_their_place() -> None:
    said = _error_lines(
        MERGE.replace("  show:", "  four: {<<: *counter, rate: 3, rate: 4}\n  show:")
    )
    assert any("duplicate key `rate`" in s and s.startswith("g.yaml:11:") for s in said), said
    said = _error_lines(MERGE.replace("<<: *counter\n    rate: 20", "<<: 5\n    rate: 20"))
    assert said[0].startswith("g.yaml:6:9: error: bad merge: `<<` takes a mapping")
    twice = MERGE.replace("    rate: 20", "    <<: *counter")
    assert _error_lines(twice)[0].startswith("g.yaml:7:5: error: duplicate merge key `<<`")
