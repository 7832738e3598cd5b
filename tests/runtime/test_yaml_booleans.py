"""YAML 1.1 reads unquoted off/on/yes/no/true/false as booleans: a name written so is an error
that says what YAML did and how to quote it (graphs and every other YAML file of the project)."""

from __future__ import annotations

import pytest

from tests.runtime.fixtures import make_registry
from umbra.connectors.errors import CheckFailed
from umbra.connectors.safe_yaml import YamlError, load
from umbra.runtime.graph.check import check_text


@pytest.mark.parametrize(("word", "value"), [("off", "false"), ("yes", "true"), ("On", "true")])
def test_a_module_named_by_a_yaml_boolean_is_one_error_that_says_quote_it(
    word: str, value: str
) -> None:
    text = (
        "graph: g\nclock: sim\nmodules:\n"
        f"  {word}: {{type: Counter, rate: 10}}\n"
        "  show: {type: Printer}\n"
        f"connections:\n  - {word}.count -> show.value\n"
    )
    with pytest.raises(CheckFailed) as caught:
        check_text(text, "g.yaml", make_registry())
    diagnostics = caught.value.diagnostics
    assert len(diagnostics) == 1  # not also "unknown module" for each connection
    (d,) = diagnostics
    assert (d.location.line, d.location.column) == (4, 3)
    assert f"YAML 1.1 reads `{word}` as the boolean {value}" in d.message
    assert f"quote it, as in '{word}'" in d.message
    quoted = text.replace(f"  {word}:", f"  '{word}':").replace(f"- {word}.", f"- '{word}.")
    quoted = quoted.replace("-> show.value", "-> show.value'")
    check_text(quoted, "g.yaml", make_registry())  # quoted, it is a fine name


def test_a_process_named_no_says_yaml_read_a_boolean() -> None:
    text = (
        "graph: g\nclock: sim\nprocesses: {main: {}}\nmodules:\n"
        "  a: {type: Counter, rate: 10, process: no}\n"
    )
    with pytest.raises(CheckFailed) as caught:
        check_text(text, "g.yaml", make_registry())
    messages = [d.message for d in caught.value.diagnostics]
    assert any("found False" in m and "as the boolean false: quote it" in m for m in messages)


def test_other_yaml_files_refuse_boolean_keys_too() -> None:
    with pytest.raises(YamlError) as caught:
        load("joints:\n  no: 1\n", "arm.yaml")
    assert str(caught.value).startswith("arm.yaml:2: error: key `no` is not a name")
    assert "YAML 1.1 reads `no` as the boolean false" in str(caught.value)
    _, values = load("joints:\n  'no': 1\n  flag: off\n", "arm.yaml")
    assert values == {"joints": {"no": 1, "flag": False}}  # quoted keys and boolean values pass
