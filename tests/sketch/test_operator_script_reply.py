"""The scripted operator reads Sketch's reply by its code (``SketchReply``), as it arrives
decoded from another process: a done command moves the script on, a refused one ends the run
(exit 1) with Sketch's reason, and a refused snapshot right after ``settle`` is taken again."""

from __future__ import annotations

from umbra.connectors.codec import Codec
from umbra.connectors.messages import Status, Text
from umbra.connectors.ptu_messages import PtuState
from umbra.connectors.sketch_messages import SketchReply
from umbra.modules.sketch.operator_script import SNAPSHOT_RETRIES, SketchOperatorSim
from umbra.runtime.harness import ModuleHarness


def _decoded(stage: SketchReply, message: str) -> Status:
    """Sketch's reply as a peer process's sample reaches this one (its stage a plain word)."""
    codec = Codec()
    reply = codec.decode(codec.encode(Status(stage=stage, message=message)), Status)
    assert type(reply.stage) is str  # what arrives is the word, not the member
    return reply


def _commands(h: ModuleHarness) -> list[str]:
    return [sample.text for sample in h.outputs("command") if isinstance(sample, Text)]


def test_a_done_command_moves_on_and_a_refused_one_ends_the_run_with_the_reason() -> None:
    params = {"script": ["vcr play", "vcr pause", "vcr stop"]}
    with ModuleHarness(SketchOperatorSim, params) as h:
        h.step(dt=0.05)
        assert _commands(h) == ["vcr play"]
        h.step(dt=0.05)
        assert _commands(h) == ["vcr play"]  # no reply yet: it waits for Sketch's
        h.push("sketch_status", _decoded(SketchReply.OK, "path1 playing"))
        h.step(dt=0.05)
        h.step(dt=0.05)
        assert _commands(h) == ["vcr play", "vcr pause"]
        assert h.stop_request is None
        h.push("sketch_status", _decoded(SketchReply.REFUSED, "vcr: plan a macro first"))
        h.step(dt=0.05)
        assert h.stop_request == ("operator script: refused: vcr: plan a macro first", 1)
        h.step(dt=0.05)
        assert _commands(h) == ["vcr play", "vcr pause"]  # nothing more after the refusal


def test_a_refused_snapshot_after_settle_is_taken_again_then_ends_the_run() -> None:
    params = {"script": ["settle", "snapshot"], "settle_s": 0.0}
    with ModuleHarness(SketchOperatorSim, params) as h:
        for attempt in range(SNAPSHOT_RETRIES + 1):
            for _ in range(4):
                for ptu in ("ptu_a", "ptu_b"):  # both cameras still: settled
                    h.push(ptu, PtuState(pan=0.0, tilt=0.0, moving=False))
                h.step(dt=0.05)
                if _commands(h).count("snapshot") == attempt + 1:
                    break
            assert _commands(h).count("snapshot") == attempt + 1
            h.push("sketch_status", _decoded(SketchReply.REFUSED, "PTU a is still slewing"))
            h.step(dt=0.05)
            stopped = attempt == SNAPSHOT_RETRIES
            assert (h.stop_request is not None) == stopped, (attempt, h.stop_request)
        assert h.stop_request == ("operator script: refused: PTU a is still slewing", 1)
