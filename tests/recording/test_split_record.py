"""``--record`` on a split run: one file per run, what both processes produced, in time order."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.recording.conftest import GRAPH
from tests.recording.frame_tree import assert_one_tree
from umbra.runtime.recording.samples import iter_samples

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_a_split_run_records_both_processes_into_one_file(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = subprocess.run(
        [
            *(sys.executable, "-m", "umbra.runtime.cli.main", "run", str(GRAPH), "--duration", "4"),
            *("--record", "--out", str(out), "--quiet"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert "recording: " in proc.stderr and "from 2 processes" in proc.stderr, proc.stderr
    assert sorted(p.name for p in out.glob("*.mcap")) == ["recording.mcap"]  # parts merged
    with open(out / "recording.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        times = [m.log_time for _s, _c, m in reader.iter_messages(log_time_order=False)]
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert times == sorted(times)
    by_process: dict[str, set[str]] = {}
    for channel in summary.channels.values():
        process = (channel.metadata or {}).get("umbra.process")
        if process:
            by_process.setdefault(process, set()).add(channel.topic)
    assert "/camera/image" in by_process["umbra"] and "/servo/twist" in by_process["umbra"]
    assert "/kinematics/joint_rates" in by_process["smart"]
    assert meta["umbra.run"]["clock"] == "real" and meta["umbra.recording"]["dropped"] == "0"
    rates = [s for s in iter_samples(out / "recording.mcap", ["/kinematics/joint_rates"])]
    smart = json.loads((out / "summary-smart.json").read_text())
    calls = next(m for m in smart["modules"] if m["module"] == "kinematics")["calls"]
    # every command the kinematics sent (one a step, and the safe stop's zero), however many
    # steps a loaded machine let it run in 4 s
    assert calls <= len(rates) <= calls + 1 and calls > 100
    assert len(by_process["smart"]) == smart["recording"]["topics"]  # each output it recorded
    # the umbra part's static frames also leave out what the smart part's poses move
    frames = assert_one_tree(out / "recording.mcap", root="base")
    assert {"camera", "tool", "flange", "link3", "table"} <= frames
