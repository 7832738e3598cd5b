"""``umbra record-info``'s rates: (count - 1) over the span of a channel's own messages, and no
rate at all for a channel of a few events (two messages 10 ms apart are not "100 Hz")."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from umbra.connectors.messages import Scalar
from umbra.runtime.cli.main import main
from umbra.runtime.recording.info import MIN_RATE_MESSAGES
from umbra.runtime.recording.writer import RecordingFile


def _record(path: Path, channels: dict[str, list[float]]) -> None:
    rec = RecordingFile(path, blocking=True)
    for topic, times in channels.items():
        for i, t in enumerate(times):
            rec.offer(topic, Scalar(value=float(i), stamp=t, seq=i + 1), t)
    rec.close()


def test_rates_come_from_each_channels_messages_and_events_get_none(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "rates.mcap"
    _record(
        path,
        {
            "/clicks/value": [1.00, 1.01],  # two clicks 10 ms apart: events
            "/few/value": [0.0, 0.5, 0.6, 2.0][: MIN_RATE_MESSAGES - 1],
            "/servo/value": [0.5 + i * 0.02 for i in range(51)],  # 50 Hz over 1 s
            "/slow/value": [i * 0.4 for i in range(MIN_RATE_MESSAGES)],  # 2.5 Hz
        },
    )
    assert main(["record-info", str(path), "--json"]) == 0
    channels = {c["topic"]: c for c in json.loads(capsys.readouterr().out)["channels"]}
    assert channels["/clicks/value"]["rate_hz"] is None
    assert channels["/few/value"]["rate_hz"] is None
    assert channels["/servo/value"]["rate_hz"] == pytest.approx(50.0, rel=1e-9)
    assert channels["/slow/value"]["rate_hz"] == pytest.approx(2.5, rel=1e-9)
    assert main(["record-info", str(path)]) == 0
    table = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines() if line}
    assert table["/clicks/value"][3] == "event" and table["/servo/value"][3] == "50.00"
