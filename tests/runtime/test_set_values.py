"""``--set NAME=VALUE``: a value is read as YAML, and text that is not YAML at all is the text."""

from __future__ import annotations

import pytest

from umbra.connectors.cli_support import parse_set, parse_value
from umbra.connectors.errors import UserError
from umbra.connectors.safe_yaml import MAX_DEPTH, YamlError, load


def test_yaml_values_are_read_and_text_that_is_not_yaml_stays_text() -> None:
    assert parse_set(["a=1", "b=[0.1, 2]", "c=x"]) == {"a": 1, "b": [0.1, 2], "c": "x"}
    # not YAML at all (an unclosed flow sequence, a tab as indentation): the text as typed
    assert parse_value("[1, 2", "--set m.p") == "[1, 2"
    assert parse_value("a:\n\t- 1", "--set m.p") == "a:\n\t- 1"


def test_yaml_that_breaks_a_bound_is_refused_not_taken_as_text() -> None:
    deep = "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1)
    with pytest.raises(YamlError) as raised:
        load(deep, "v")
    assert not raised.value.syntax  # well-formed YAML, too deep
    with pytest.raises(UserError, match=r"--set m\.p: error: .*nest"):
        parse_value(deep, "--set m.p")
    with pytest.raises(YamlError) as raised:
        load("[1, 2", "v")
    assert raised.value.syntax and raised.value.line == 1
