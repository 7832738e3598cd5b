"""What ``umbra topics`` makes of the samples it sees: rate over the window, drops from the
sequence gaps, the end of a stream."""

from __future__ import annotations

import pytest

from umbra.connectors.messages import Scalar
from umbra.runtime.cli.cmd_topics import Seen, _row
from umbra.runtime.links.observe import Observed

# whole runs of umbra in subprocesses, seconds each: in CI with -m slow (a short default run)
pytestmark = pytest.mark.slow


def _sample(seq: int, at: float) -> Observed:
    msg = Scalar(value=float(seq), seq=seq)
    return Observed("p/m/o", "sample", msg, "Scalar", 40, "zid", at)


def test_rate_drops_and_end_of_stream() -> None:
    seen = Seen()
    for seq, at in ((1, 10.0), (2, 10.01), (5, 10.02), (6, 10.03), (4, 10.035)):
        seen.add(_sample(seq, at))
    assert seen.count == 5 and seen.drops == 2  # 3 and 4 missing when 5 came; 4 late
    assert abs(seen.rate() - 4 / 0.035) < 1e-9  # type: ignore[operator]
    row = _row("p/m/o", "Scalar", "umbra", seen, 10.1, True)
    assert (row["drops"], row["samples"], row["age_s"], row["note"]) == (2, 5, 0.065, "")
    seen.add(Observed("p/m/o", "end", None, "Scalar", 0, "zid", 10.2))
    assert _row("p/m/o", "Scalar", "umbra", seen, 10.3, True)["note"] == "ended"
    assert _row("p/m/o", "Scalar", "umbra", None, 10.3, True)["note"] == "nothing in the window"
    quiet = _row("p/m/o", "Scalar", "smart", None, 10.3, False)
    assert (quiet["rate_hz"], quiet["note"]) == (None, "not published (run with --publish-all)")
