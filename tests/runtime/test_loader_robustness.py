"""No input makes the graph loader crash, hang or print a traceback (property-tested)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from umbra.connectors.errors import CheckFailed, UserError
from umbra.runtime.graph.check import check_text, load_graph

LIMITS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _only_user_errors(data: str | bytes) -> None:
    try:
        check_text(data, "fuzz.yaml")
    except CheckFailed as exc:
        assert exc.diagnostics, "a failed check must say what failed"
        for d in exc.diagnostics:
            assert d.location.file == "fuzz.yaml" and d.location.line >= 1
    except UserError:
        pass


@LIMITS
@given(st.binary(max_size=2000))
def test_random_bytes(data: bytes) -> None:
    _only_user_errors(data)


@LIMITS
@given(st.text(max_size=2000))
def test_random_text(text: str) -> None:
    _only_user_errors(text)


yaml_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda children: (
        st.lists(children, max_size=5) | st.dictionaries(st.text(max_size=10), children, max_size=5)
    ),
    max_leaves=40,
)
graph_like = st.fixed_dictionaries(
    {},
    optional={
        "graph": st.one_of(st.text(max_size=10), yaml_values),
        "modules": st.one_of(
            yaml_values,
            st.dictionaries(
                st.sampled_from(["a", "b", "c"]),
                st.fixed_dictionaries(
                    {"type": st.sampled_from(["Counter", "Gain", "Printer", "Nope", "Recorder"])},
                    optional={
                        "rate": yaml_values | st.floats(),
                        "params": yaml_values,
                        "trigger": yaml_values,
                        "process": yaml_values,
                    },
                ),
            ),
        ),
        "connections": st.one_of(
            yaml_values,
            st.lists(
                st.sampled_from(
                    [
                        "a.count -> b.input",
                        "b.output ~> a.input",
                        "a.x -> c.value",
                        "b.output -> c.value",
                        "c.y -> a.z",
                    ]
                ),
                max_size=5,
            ),
        ),
        "frames": yaml_values,
        "processes": yaml_values,
        "links": yaml_values,
        "seed": yaml_values,
    },
)


@LIMITS
@given(graph_like)
def test_random_graph_shaped_documents(doc: dict) -> None:
    _only_user_errors(yaml.safe_dump(doc))


def test_deep_nesting() -> None:
    with pytest.raises(CheckFailed, match="nesting"):
        check_text("graph: g\nmodules: " + "[" * 100_000 + "]" * 100_000, "f.yaml")
    with pytest.raises(CheckFailed, match="nesting"):
        check_text("a:\n" + "".join(" " * i + "b:\n" for i in range(1, 300)), "f.yaml")


def test_alias_bomb() -> None:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 10):
        prev = f"*a{i - 1}"
        lines.append(f"a{i}: &a{i} [{', '.join([prev] * 10)}]")
    with pytest.raises(CheckFailed, match="more than 100000 YAML nodes"):
        check_text("\n".join(lines), "bomb.yaml")


def test_ten_megabyte_file(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_bytes(b"graph: g\n" + b"# padding\n" * 1_000_000)
    with pytest.raises(CheckFailed, match="at most"):
        load_graph(str(big))


def test_binary_garbage_file_via_cli(tmp_path: Path) -> None:
    junk = tmp_path / "junk.yaml"
    junk.write_bytes(bytes(range(256)) * 10)
    proc = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "check", str(junk)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert f"{junk}:2:1: error: not UTF-8 text (byte 128 is 0x80)" in proc.stderr


def test_missing_and_directory_paths(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no such graph file"):
        load_graph(str(tmp_path / "absent.yaml"))
    with pytest.raises(UserError, match="is a directory"):
        load_graph(str(tmp_path))
