"""A live frame's capture time: the driver's buffer stamp where the backend gives one on the
host's monotonic clock, else the moment grab() dequeued it (before decoding)."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

from tests.poll import wait_for
from umbra.modules.vision import capture as capture_module
from umbra.modules.vision.capture import CaptureReader, CaptureSource
from umbra.modules.vision.capture_time import MAX_DRIVER_LAG_S, capture_time


def test_a_driver_stamp_on_our_clock_is_the_capture_time() -> None:
    grabbed = 1000.0
    assert capture_time((grabbed - 0.040) * 1000, grabbed) == (
        pytest.approx(grabbed - 0.040),
        "driver",
    )


@pytest.mark.parametrize(
    "driver_ms",
    [
        None,  # not asked (a stream)
        0.0,  # OpenCV before the first frame
        33.3,  # a media position, not a clock
        (1000.0 - MAX_DRIVER_LAG_S - 0.5) * 1000,  # older than any frame in a queue
        (1000.0 + 0.5) * 1000,  # after the frame was dequeued: another clock
        float("nan"),
    ],
)
def test_a_stamp_that_cannot_be_a_capture_time_gives_way_to_the_grab(driver_ms) -> None:
    assert capture_time(driver_ms, 1000.0) == (1000.0, "grab")


class _V4L2Like:
    """A device as OpenCV's V4L2 backend shows one: each buffer dequeued ``transfer_s`` after
    its exposure, and CAP_PROP_POS_MSEC the exposure on CLOCK_MONOTONIC in milliseconds."""

    transfer_s = 0.045

    def __init__(self, *args, **kwargs) -> None:
        self.exposed: list[float] = []

    def isOpened(self) -> bool:
        return True

    def set(self, prop, value) -> bool:
        return True

    def grab(self) -> bool:
        time.sleep(0.01)
        self.exposed.append(time.monotonic() - self.transfer_s)
        return True

    def get(self, prop) -> float:
        assert prop == cv2.CAP_PROP_POS_MSEC
        return self.driver_ms()

    def driver_ms(self) -> float:
        return self.exposed[-1] * 1000.0

    def retrieve(self):
        frame = np.full((48, 64, 3), len(self.exposed) % 256, np.uint8)
        return True, frame

    def release(self) -> None:
        pass


class _MediaPositionLike(_V4L2Like):
    """A backend whose CAP_PROP_POS_MSEC is a position in the media, not a clock."""

    def driver_ms(self) -> float:
        return 33.3 * len(self.exposed)


def _newest(reader: CaptureReader):
    reader.start()
    try:
        frame = wait_for(
            reader.latest, 5.0, "frame 3 from the fake device", ok=lambda f: f.number >= 3
        )
        return frame, reader._capture.exposed[frame.number - 1]
    finally:
        reader.close()


def test_a_device_frame_carries_the_drivers_exposure_time(monkeypatch) -> None:
    monkeypatch.setattr(capture_module.cv2, "VideoCapture", _V4L2Like)
    monkeypatch.setattr(capture_module, "source_problem", lambda source: "")
    frame, exposed = _newest(CaptureReader(CaptureSource.parse(0)))
    assert frame.stamped_by == "driver"
    assert frame.captured_at == pytest.approx(exposed, abs=1e-6)


def test_a_backend_without_a_clock_stamp_dates_the_frame_at_its_dequeue(monkeypatch) -> None:
    monkeypatch.setattr(capture_module.cv2, "VideoCapture", _MediaPositionLike)
    monkeypatch.setattr(capture_module, "source_problem", lambda source: "")
    frame, exposed = _newest(CaptureReader(CaptureSource.parse(0)))
    assert frame.stamped_by == "grab"
    # dated when it was dequeued, transfer_s after its exposure: older than the driver says
    # would be wrong, and so would the media position (0.1 s since the epoch of the clock)
    assert frame.captured_at - exposed >= _V4L2Like.transfer_s - 1e-6
    assert frame.captured_at > 1.0
