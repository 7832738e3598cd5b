"""The snake's area and outline on photographs it was never tuned on, at 1920 x 1080.

Frames come from :mod:`umbra.modules.vision.photo_scene` (another generator than the project's
renderer): a coloured patch under perspective on the held-out scikit-image photographs, with
lens and motion blur, lighting gain 0.55-1.45, colour casts, shot and read noise and JPEG. The
truth is the patch's quadrilateral. The snake learns the colour at the seed click on the frame
and grows from there, as the tracker does when the operator seeds it.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from umbra.modules.vision import photo_scene as ps
from umbra.modules.vision.metrics import polygon_iou, polygon_mask
from umbra.modules.vision.polygon import signed_area
from umbra.modules.vision.tracker import SnakeTracker

#: The held-out frames scored here (frames of ``photo_scene`` seed 2031).
FIRST, FRAMES = 6, 6


def outline_on(frame: ps.PhotoFrame, seed_offset: np.ndarray) -> np.ndarray:
    """The tracker's outline after acquiring from a click ``seed_offset`` (fractions of the
    patch's extent, within 15 %) from the patch's centre."""
    seed = frame.corners.mean(axis=0) + seed_offset * np.ptp(frame.corners, axis=0)
    tracker = SnakeTracker()
    tracker.seed_at_point(frame.image, seed)
    return tracker.update(frame.image).vertices


def test_the_photograph_sets_do_not_overlap() -> None:
    assert not set(ps.TUNING_PHOTOS) & set(ps.HELD_OUT_PHOTOS)
    for name in ps.HELD_OUT_PHOTOS:
        assert ps.load_photo(name).shape[2] == 3


def test_the_generator_truth_is_the_drawn_area() -> None:
    """The rendered patch covers the truth polygon's area: coverage summed over the pixels
    against the shoelace area, for a noiseless frame of each kind of edge."""
    rng = np.random.default_rng(5)
    for _ in range(3):
        corners = ps._patch_corners((1920, 1080), rng)
        coverage, _ = ps.patch_coverage(corners, (1080, 1920))
        assert float(coverage.sum()) == pytest.approx(abs(signed_area(corners)), rel=2e-4)


def test_area_bias_and_iou_on_held_out_photographs_at_1920x1080() -> None:
    """Median |area bias| within 0.2 % and IoU >= 0.99 on every frame (the edge fit before this
    test: IoU 0.975 on frame 7, a small patch whose corners the snake's tension rounded)."""
    rng = np.random.default_rng(2032)
    biases, ious = [], []
    for index in range(FIRST + FRAMES):
        seed_offset = rng.uniform(-0.15, 0.15, 2)
        if index < FIRST:
            continue
        photo = ps.HELD_OUT_PHOTOS[index % len(ps.HELD_OUT_PHOTOS)]
        frame = ps.render(photo, np.random.default_rng([2031, index]))
        assert frame.image.shape == (1080, 1920, 3)
        outline = outline_on(frame, seed_offset)
        biases.append(abs(signed_area(outline)) / frame.area_px2 - 1.0)
        ious.append(polygon_iou(outline, frame.corners, frame.image.shape[:2]))
    assert float(np.median(np.abs(biases))) <= 0.002, biases
    assert min(ious) >= 0.99, ious


def test_harsh_frames_clip_a_channel_and_carry_jpeg_blocks() -> None:
    """The harsh camera draws what a camera draws: at gain 1.55-1.6 a bright paint saturates a
    channel inside the patch (clipped at 255 before the JPEG round trip), and every frame goes
    through cv2.imencode at quality 70-95 (the same frame without it differs)."""
    bright = replace(ps.HARSH, gain_range=(1.55, 1.6))
    frame = ps.render("rocket", np.random.default_rng(8), (640, 480), conditions=bright)
    assert 70 <= frame.conditions["jpeg_quality"] <= 95
    plain = ps.render(
        "rocket", np.random.default_rng(8), (640, 480), conditions=replace(bright, jpeg_share=0.0)
    )
    assert float(np.mean(np.abs(frame.image.astype(float) - plain.image))) > 0.5
    inside = polygon_mask(frame.corners, (480, 640)).astype(np.uint8)
    inside = cv2.erode(inside, np.ones((9, 9), np.uint8)).astype(bool)
    patch = plain.image[inside]
    assert np.mean(patch.max(axis=1) == 255) > 0.5  # a channel clips over most of the patch


@pytest.mark.slow
@pytest.mark.untimed
def test_area_bias_at_every_lighting_gain_on_harsh_held_out_frames_at_1920x1080() -> None:
    """JPEG at quality 70-95 on every frame, twice the sensor noise, gains 0.55-1.6 (the
    patch's brightest channel clips above about 1.2): the median area bias within 0.2 % in
    every band of gain."""
    rng = np.random.default_rng(4301)
    by_gain: dict[int, list[float]] = {}
    for index in range(60):
        seed_offset = rng.uniform(-0.15, 0.15, 2)
        photo = ps.HELD_OUT_PHOTOS[index % len(ps.HELD_OUT_PHOTOS)]
        frame = ps.render(photo, np.random.default_rng([4300, index]), conditions=ps.HARSH)
        outline = outline_on(frame, seed_offset)
        band = int(np.searchsorted([0.85, 1.15, 1.35], frame.conditions["gain"]))
        by_gain.setdefault(band, []).append(abs(signed_area(outline)) / frame.area_px2 - 1.0)
    assert len(by_gain) == 4
    for band, biases in by_gain.items():
        assert abs(float(np.median(biases))) <= 0.002, (band, biases)


@pytest.mark.slow
@pytest.mark.untimed
def test_harsh_held_out_frames_at_640x480_track_without_false_alarms() -> None:
    """At 640 x 480 (patches of 120-300 px under perspective, JPEG 70-95, twice the noise, gains
    up to 1.6 that clip a channel), 40 frames of seed 4340: every whole patch passes its sanity
    checks (the shapes are tested on the patch seen head-on; tested on the image, 22 of the bench's
    60 such frames failed), the outline's IoU is at least 0.985 on every frame (0.9895 measured;
    before acquisition learned from the interior and the sides were fitted whole, 0.98) and its
    median at least 0.99, and the median area bias stays within 0.25 % in every band of gain
    (0.11 % measured; -0.28 % above a gain of 1.35, where white backgrounds clip, before the
    steepest point measured edges against a clipped background)."""
    conditions = replace(ps.HARSH, span_px=(120.0, 300.0))
    rng = np.random.default_rng(4341)
    ious, by_gain, failed = [], {}, []
    for index in range(40):
        seed_offset = rng.uniform(-0.15, 0.15, 2)
        photo = ps.HELD_OUT_PHOTOS[index % len(ps.HELD_OUT_PHOTOS)]
        frame = ps.render(photo, np.random.default_rng([4340, index]), (640, 480), conditions)
        seed = frame.corners.mean(axis=0) + seed_offset * np.ptp(frame.corners, axis=0)
        tracker = SnakeTracker()
        tracker.seed_at_point(frame.image, seed)
        update = tracker.update(frame.image)
        if update.status != "tracking":
            failed.append((index, update.sanity.reason))
        ious.append(polygon_iou(update.vertices, frame.corners, (480, 640)))
        band = int(np.searchsorted([0.85, 1.15, 1.35], frame.conditions["gain"]))
        bias = abs(signed_area(update.vertices)) / frame.area_px2 - 1.0
        by_gain.setdefault(band, []).append(bias)
    assert not failed, failed
    assert min(ious) >= 0.985, ious
    assert float(np.median(ious)) >= 0.99, ious
    assert len(by_gain) == 4
    for band, biases in by_gain.items():
        assert abs(float(np.median(biases))) <= 0.0025, (band, biases)


@pytest.mark.slow
@pytest.mark.untimed
def test_ninety_five_in_a_hundred_harsh_frames_at_640x480_reach_iou_0_99() -> None:
    """120 harsh held-out frames at 640 x 480 (seeds 4350-4352): the 5th percentile of the
    outline's IoU is at least 0.9895 (0.9914 measured) and its median at least 0.995 (0.996).
    Before the corners were put where the sides meet, the outline of patches over 150 px was
    measured at the coarse grid's spacing, a halo's vertices left unmeasured and edges against
    a clipped background read at their half step: 5th percentile 0.987, 9 frames below 0.99
    (now 5)."""
    conditions = replace(ps.HARSH, span_px=(120.0, 300.0))
    ious = []
    for seed in (4350, 4351, 4352):
        rng = np.random.default_rng(seed + 1)
        for index in range(40):
            seed_offset = rng.uniform(-0.15, 0.15, 2)
            photo = ps.HELD_OUT_PHOTOS[index % len(ps.HELD_OUT_PHOTOS)]
            frame = ps.render(photo, np.random.default_rng([seed, index]), (640, 480), conditions)
            ious.append(polygon_iou(outline_on(frame, seed_offset), frame.corners, (480, 640)))
    assert float(np.percentile(ious, 5)) >= 0.9895, sorted(ious)[:8]
    assert float(np.median(ious)) >= 0.995, float(np.median(ious))
