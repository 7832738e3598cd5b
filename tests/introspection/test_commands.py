"""``umbra topics``, ``echo`` and ``hz`` against a real running graph (counter_split: a 100 Hz
counter in process `umbra`, doubled in process `smart`). Rates are checked within wide bounds
(50..150 Hz for 100 Hz): the machine may be loaded, the figure must still be the right one."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.introspection.helpers import COUNTER, json_lines, running, umbra_cli, user_folder
from tests.links.conftest import Running
from tests.poll import wait_for
from umbra.runtime.links.observe import Observation

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow

PREFIX = "umbra/counter_split"


def test_topics_echo_and_hz_on_a_run_publishing_every_output(
    umbra: Callable[..., Running], plugin_env: dict[str, str]
) -> None:
    run = umbra(
        "run", COUNTER, "--publish-all", "--duration", "300", "--quiet",
        "--set", "counter.stop_after=100000",
    )  # fmt: skip
    running(run, plugin_env)
    topics = umbra_cli(plugin_env, "topics", "--json", "--window", "2")
    assert topics.returncode == 0, topics.stderr
    rows = {r["key"]: r for r in json_lines(topics.stdout)}
    assert set(rows) == {f"{PREFIX}/counter/count", f"{PREFIX}/double/output"}
    count, double = rows[f"{PREFIX}/counter/count"], rows[f"{PREFIX}/double/output"]
    assert (count["type"], count["producer"]) == ("Scalar", "umbra")
    assert (double["type"], double["producer"]) == ("Scalar", "smart")  # not a link: published
    for row in (count, double):
        assert 50 < row["rate_hz"] < 150 and row["samples"] > 50, row
        # state streams drop under congestion rather than queue: a loaded machine loses a few
        assert 0 <= row["age_s"] < 0.5 and row["drops"] < row["samples"] / 5, row
        assert row["note"] == "", row

    # the API: a wildcard becomes one subscription per readable key (the rules refuse wider)
    observer = Observation.open(folder=user_folder(plugin_env))
    seen: set[str] = set()
    try:
        observer.subscribe(lambda o: seen.add(o.key), f"{PREFIX}/*/*")
        wait_for(lambda: len(seen) >= 2, 10, "two keys observed", 0.05)
    finally:
        observer.close()
    assert seen == set(rows)

    echo = umbra_cli(plugin_env, "echo", "double/output", "--once", "--json")
    assert echo.returncode == 0, echo.stderr
    (sample,) = json_lines(echo.stdout)
    assert sample["key"] == f"{PREFIX}/double/output" and sample["type"] == "Scalar"
    assert sample["seq"] > 0 and sample["value"] % 2 == 0 and sample["stamp"] > 0
    assert set(sample) == {"key", "type", "stamp", "seq", "origin", "value"}
    text = umbra_cli(plugin_env, "echo", f"{PREFIX}/counter/count", "--once")
    assert text.returncode == 0 and text.stdout.startswith(f"--- {PREFIX}/counter/count (Scalar")
    value = float(re.search(r"^value: (\S+)$", text.stdout, re.M).group(1))  # type: ignore[union-attr]
    seq = int(re.search(r"^seq: (\d+)$", text.stdout, re.M).group(1))  # type: ignore[union-attr]
    assert value == seq - 1  # the counter counts from 0

    hz = umbra_cli(plugin_env, "hz", "counter/count", "--duration", "2")
    assert hz.returncode == 0, hz.stderr
    rates = [float(r) for r in re.findall(r"average rate: ([\d.]+) Hz", hz.stdout)]
    assert len(rates) == 2 and all(50 < r < 150 for r in rates), hz.stdout

    wrong = umbra_cli(plugin_env, "echo", "counter/nope", "--once")
    assert wrong.returncode == 2 and "Traceback" not in wrong.stderr
    assert (
        "expected a key graph `counter_split` may read, found `umbra/counter_split/counter/nope`"
        in wrong.stderr
    )
    run.popen.terminate()
    run.finish()
    gone = umbra_cli(plugin_env, "topics")
    assert gone.returncode == 2 and "no graph runs on this host" in gone.stderr
    assert "Traceback" not in gone.stderr


def test_outputs_that_cross_no_process_are_listed_as_not_published_and_a_refused_observer_is_told(
    umbra: Callable[..., Running], plugin_env: dict[str, str], tmp_path: Path
) -> None:
    run = umbra(
        "run", COUNTER, "--duration", "300", "--quiet", "--set", "counter.stop_after=100000"
    )  # fmt: skip
    running(run, plugin_env)
    topics = umbra_cli(plugin_env, "topics", "--json", "--window", "1")
    rows = {r["key"]: r for r in json_lines(topics.stdout)}
    assert rows[f"{PREFIX}/counter/count"]["samples"] > 0  # a link: always published
    double = rows[f"{PREFIX}/double/output"]
    assert double["samples"] == 0 and double["note"] == "not published (run with --publish-all)"
    echo = umbra_cli(plugin_env, "echo", "double/output", "--once")
    assert echo.returncode == 2 and "Traceback" not in echo.stderr
    assert "feeds no other process, so it is not published" in echo.stderr
    table = umbra_cli(plugin_env, "topics", "--window", "1")
    assert table.returncode == 0
    assert re.search(rf"^{PREFIX}/counter/count +Scalar +umbra +\d+\.\d +\d", table.stdout, re.M)

    # the same run files with a wrong observer password: the processes refuse the session
    wrong = tmp_path / "wrong"
    (wrong / "umbra" / "runs").mkdir(parents=True)
    wrong.chmod(0o700)
    for path in (user_folder(plugin_env) / "runs").glob("*.json"):
        entry = json.loads(path.read_text())
        entry["observer"]["password"] = "0" * 48
        (wrong / "umbra" / "runs" / path.name).write_text(json.dumps(entry))
    refused = umbra_cli(dict(plugin_env, XDG_RUNTIME_DIR=str(wrong)), "topics")
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    assert "cannot join graph `counter_split`: none of its 2 processes accepted" in refused.stderr
