"""Chromaticity statistics: gain invariance, fitting, the whitened gate, online adaptation."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.vision import color


def test_chromaticity_is_invariant_to_a_lighting_gain() -> None:
    rng = np.random.default_rng(1)
    bgr = rng.integers(10, 160, size=(500, 3)).astype(np.float64)
    r1, g1, gray1 = color.chromaticity(bgr)
    r2, g2, gray2 = color.chromaticity(1.6 * bgr)
    np.testing.assert_allclose(r1, r2, rtol=1e-6)
    np.testing.assert_allclose(g1, g2, rtol=1e-6)
    np.testing.assert_allclose(gray2, 1.6 * gray1, rtol=1e-6)
    # BGR order: a pure red pixel has r = 1.
    r, g, _ = color.chromaticity(np.array([[0, 0, 200]]))
    assert (r[0], g[0]) == (1.0, 0.0)


def test_fit_matches_numpy_statistics_and_skips_dark_pixels() -> None:
    rng = np.random.default_rng(2)
    bright = np.clip(rng.normal([60, 170, 30], 6, size=(400, 3)), 0, 255)
    dark = np.full((50, 3), 5.0)
    model = color.fit(np.vstack([bright, dark]), min_gray=20.0, noise_floor=0.0)
    total = bright.sum(axis=1)
    rg = np.column_stack([bright[:, 2] / total, bright[:, 1] / total])
    np.testing.assert_allclose(model.mean, rg.mean(axis=0), rtol=1e-5)
    offsets = (rg - rg.mean(axis=0)) * total[:, None]
    np.testing.assert_allclose(model.offset_covariance, np.cov(offsets, rowvar=False), rtol=1e-4)
    # Offsets from the color ray are sensor noise: a few gray levels, whatever the brightness.
    assert 3.0 < np.sqrt(model.offset_covariance[0, 0]) < 9.0


def test_a_model_learned_in_bright_light_holds_in_dim_light() -> None:
    """Noise is additive in gray levels: at half the light the chromaticity scatters twice as
    much, and the model expects exactly that."""
    rng = np.random.default_rng(12)
    patch = np.array([60.0, 170.0, 30.0])
    bright = np.clip(patch + rng.normal(0, 8, size=(2000, 3)), 0, 255)
    dim = np.clip(0.5 * patch + rng.normal(0, 8, size=(2000, 3)), 0, 255)
    model = color.fit(bright)
    for pixels in (bright, dim):
        r, g, total = color.chromaticity(pixels)
        inside = color.mahalanobis_squared(model, r, g, total) <= 9.0
        assert inside.mean() > 0.97  # chi-square, 2 dof: 98.9 % within 3 sigma
    assert color.is_target(model, dim).mean() > 0.97


def test_fit_needs_enough_bright_pixels() -> None:
    with pytest.raises(ValueError, match="at least 3 seed pixels"):
        color.fit(np.full((20, 3), 4))


def test_covariance_must_be_positive_definite() -> None:
    with pytest.raises(ValueError, match="positive definite"):
        color.ColorModel(np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(ValueError, match="floor"):
        color.ColorModel(np.zeros(2), np.eye(2), chroma_floor=-1.0)


def test_gate_test_agrees_with_mahalanobis_distance() -> None:
    rng = np.random.default_rng(3)
    model = color.ColorModel(np.array([0.2, 0.6]), np.array([[40.0, 15.0], [15.0, 90.0]]), 0.01)
    pixels = rng.integers(0, 256, size=(50_000, 3)).astype(np.float32)
    r, g, total = color.chromaticity(pixels)
    for k in (2.0, 3.0, 5.0):
        fast = color.gate_test(model, pixels @ color.offset_matrix(model), k, min_gray=0.0)
        slow = color.mahalanobis_squared(model, r, g, total) <= k * k
        # Float32 rounding may flip a pixel that sits on the gate itself, nothing more.
        assert np.count_nonzero(fast != slow) <= 2
        assert 100 < np.count_nonzero(slow) < len(pixels) - 100


def test_is_target_separates_patch_from_tray() -> None:
    model = color.from_rgb((30, 170, 60), noise_gray=8.0)
    patch_bgr = np.array([[60, 170, 30], [30, 85, 15]])  # same color at half the light
    tray_bgr = np.array([[200, 205, 205], [10, 40, 8]])  # gray tray; a too-dark green
    assert color.is_target(model, patch_bgr).all()
    assert not color.is_target(model, tray_bgr).any()


def test_adapt_follows_a_color_cast_and_ignores_outliers() -> None:
    rng = np.random.default_rng(4)
    patch = np.clip(rng.normal([60, 170, 30], 5, size=(300, 3)), 0, 255)
    model = color.fit(patch)
    cast = patch * np.array([0.8, 1.0, 1.3])  # BGR gains: warmer light
    tray = np.full((100, 3), 200.0)
    samples = np.vstack([cast, tray])
    target_mean = color.fit(cast).mean
    adapted = model
    for _ in range(40):
        adapted = color.adapt(adapted, samples, rate=0.2)
    np.testing.assert_allclose(adapted.mean, target_mean, atol=2e-3)
    assert np.linalg.norm(model.mean - target_mean) > 0.02
    unchanged = color.adapt(model, tray, rate=0.5)
    np.testing.assert_array_equal(unchanged.mean, model.mean)
    with pytest.raises(ValueError, match="rate"):
        color.adapt(model, samples, rate=1.5)


def test_a_patch_whose_brightest_channel_clips_is_still_the_target() -> None:
    """A red patch (RGB 200, 40, 40) under rising light: its red channel saturates at 255 while
    green and blue go on growing. Without the clipped channel put back its chromaticity drifts
    off the model's (the gate refuses it from a gain of 1.5); with it, it is the target up to
    ``UNCLIP_MAX`` (a gain of 2.04 here), and other clipped colours are not."""
    model = color.from_rgb((200, 40, 40), noise_gray=4.0)
    truth = np.array([40.0, 40.0, 200.0])  # BGR
    for gain in (1.0, 1.4, 1.5, 1.6, 2.0):
        seen = np.minimum(np.round(gain * truth), 255.0)
        assert color.is_target(model, seen[None, :]).all(), gain
        r, g, total = color.chromaticity(seen[None, :])
        far = color.mahalanobis_squared(model, r, g, total)[0] > 9.0
        assert far == (gain >= 1.5), gain  # the raw pixel: the drift the put-back removes
    beyond = np.minimum(np.round(2.1 * truth), 255.0)[None, :]  # red would be 420
    assert not color.is_target(model, beyond).any()
    put_back = color.unclip(model, np.array([[80.0, 80.0, 255.0]], dtype=np.float32))
    np.testing.assert_allclose(put_back, [[80.0, 80.0, 400.0]], rtol=1e-6)
    others = np.array(
        [
            [255.0, 255.0, 255.0],  # white: every channel clipped, nothing to go by
            [220.0, 240.0, 255.0],  # a white stone with red clipped: red would be ~1150
            [40.0, 255.0, 255.0],  # yellow: green clipped too, and the model says it is low
            [110.0, 110.0, 255.0],  # reddish, but red would be 550: brighter than any patch
        ]
    )
    assert not color.is_target(model, others).any()


def test_adapt_learns_a_clipped_patch_as_the_gate_sees_it() -> None:
    """Adaptation takes the pixels the gate takes: a red patch at a gain of 1.6 (red clipped at
    255, green and blue at 64) is on the model's colour once red is put back, so every sample
    teaches and the mean stays on the patch's chromaticity; judged raw, the samples lie off it
    and the model would drift to the clipped colour."""
    model = color.from_rgb((200, 40, 40), noise_gray=4.0)
    rng = np.random.default_rng(11)
    seen = np.clip(np.round(rng.normal([64.0, 64.0, 320.0], 2.0, size=(200, 3))), 0, 255)
    r, g, total = color.chromaticity(seen)
    assert np.median(color.mahalanobis_squared(model, r, g, total)) > 9.0  # raw: off the colour
    adapted = color.adapt(model, seen, rate=1.0)
    assert adapted is not model
    np.testing.assert_allclose(adapted.mean, model.mean, atol=0.01)
    raw_mean = np.array([r.mean(), g.mean()])
    assert np.linalg.norm(raw_mean - model.mean) > 0.05
