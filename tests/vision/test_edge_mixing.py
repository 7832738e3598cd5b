"""A channel that the patch clips, put back from how the edge mixes the channels that do not clip:
the edge of a patch whose colour model was learned from already clipped pixels is found where it
is, not half a pixel out."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.special import ndtr

from umbra.modules.vision import color, edge_fit
from umbra.modules.vision.edge_mixing import unclip_by_mixing

TOP, FLOOR, MIN_CONTRAST = 240.0, 2.0, 20.0
#: Profile samples every 0.5 px over ±4 px, inner (patch) end first; ends of 3 samples.
OFFSETS = np.arange(-4.0, 4.001, 0.5)
ENDS = 3


def _put_back(read: np.ndarray, given: np.ndarray) -> np.ndarray:
    """:func:`unclip_by_mixing` of profiles ``read`` (N, K, 3) as the colour model put them back
    (``given``), with the ends' colours the means of ``ENDS`` samples as read."""
    inner, outer = read[:, :ENDS].mean(axis=1), read[:, -ENDS:].mean(axis=1)
    return unclip_by_mixing(read, given, inner, outer, TOP, FLOOR, MIN_CONTRAST)


def _profiles(
    patch: np.ndarray, background: np.ndarray, blur_px: float, noise: float, rng
) -> tuple[np.ndarray, np.ndarray]:
    """Profiles (N, K, 3) across an edge at offset 0 blurred by a Gaussian of ``blur_px``, each
    with its own background colour (N x 3: a textured background), as the sensor has them
    before (float) and after the clip (8 bits, ``noise`` gray levels)."""
    t = ndtr(-OFFSETS / blur_px)  # 1 on the patch's side
    truth = background[:, None, :] + t[None, :, None] * (patch - background)[:, None, :]
    read = np.clip(np.rint(truth + rng.normal(0.0, noise, truth.shape)), 0, 255)
    return truth, read.astype(np.float32)


def test_clipped_samples_are_put_back_on_the_line_the_mixing_draws() -> None:
    """A blue patch at 350 (the sensor reads 255) against 60 profiles of a background textured
    by ±10 gray levels, blurred by 0.8-1.3 px, 1.5 gray levels of noise: the put-back blue of
    the samples the sensor clipped lies within 10 % of the blue it would have read (the step is
    about 320; half of them within 2 %), where the colour model alone left it at the clip, a
    fifth of the step low or more."""
    rng = np.random.default_rng(7)
    patch = np.array([350.0, 95.0, 70.0])
    for blur_px in (0.8, 1.3):
        background = np.array([30.0, 22.0, 25.0]) + rng.uniform(-10.0, 10.0, (60, 3))
        truth, read = _profiles(patch, background, blur_px, 1.5, rng)
        put_back = _put_back(read, read)
        clipped = read[..., 0] >= TOP
        assert clipped.sum() > 300
        error = (put_back[..., 0] - truth[..., 0])[clipped] / (patch[0] - background[:, 0].mean())
        assert np.abs(np.median(error)) < 0.02, blur_px
        assert np.percentile(np.abs(error), 95) < 0.1, blur_px
        left = (read[..., 0] - truth[..., 0])[clipped] / (patch[0] - background[:, 0].mean())
        assert np.median(left) < -0.2
        # The channels that do not clip are left as they were read.
        assert np.array_equal(put_back[..., 1:], read[..., 1:])


def test_profiles_that_cannot_tell_the_hidden_step_are_left_alone() -> None:
    """No put-back where the other channels differ by less than 20 gray levels across the edge,
    where the clipped channel's background is clipped too, or where the blue reads below the
    top at the patch's end."""
    rng = np.random.default_rng(8)
    cases = {
        "flat others": (np.array([350.0, 40.0, 30.0]), np.array([30.0, 30.0, 25.0])),
        "both ends clipped": (np.array([350.0, 95.0, 70.0]), np.array([300.0, 22.0, 25.0])),
        "no clip": (np.array([230.0, 95.0, 70.0]), np.array([30.0, 22.0, 25.0])),
    }
    for name, (patch, colour) in cases.items():
        _, read = _profiles(patch, np.repeat(colour[None], 20, axis=0), 1.0, 1.5, rng)
        given = read + 1.0  # what the colour model put back, told apart from what was read
        out = _put_back(read, given)
        assert np.array_equal(out, given), name


def _blue_patch_frame(edge_px: float, blur_px: float, rng) -> np.ndarray:
    """A 200 x 200 frame: a blue patch (B 350, G 95, R 70 before the clip) left of the vertical
    line u = ``edge_px`` on a dark background, area-sampled (8x), Gaussian blur as a lens blurs,
    2 gray levels of noise, clipped to 8 bits."""
    size, fine = 200, 8
    grid = (np.arange(size * fine) + 0.5) / fine - 0.5
    uu, _ = np.meshgrid(grid, grid)
    coverage = (uu < edge_px).reshape(size, fine, size, fine).mean(axis=(1, 3))[:, :, None]
    patch, background = np.array([350.0, 95.0, 70.0]), np.array([30.0, 20.0, 25.0])
    image = coverage * patch + (1.0 - coverage) * background
    image = cv2.GaussianBlur(image, (0, 0), blur_px) + rng.normal(0.0, 2.0, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _side_offset(image: np.ndarray, edge_px: float) -> float:
    """Mean offset [px, + outwards] of the edge fit of 30 vertices 1.3 px inside the edge, with
    the colour model learned from the patch's own (clipped) pixels."""
    model = color.fit(image[40:160, 20:90].reshape(-1, 3))
    v = np.linspace(40.0, 160.0, 30)
    vertices = np.column_stack([np.full(v.size, edge_px - 1.3), v])
    normals = np.repeat([[1.0, 0.0]], v.size, axis=0)
    fit = edge_fit.fit_edges(image, vertices, normals, model, 3.0, 20.0)
    assert fit.found.all()
    return float(np.mean(fit.vertices[:, 0] - edge_px))


@pytest.mark.parametrize("blur_px", [0.8, 1.3])
def test_a_patch_learned_clipped_has_its_edge_found_where_it_is(
    blur_px: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The colour model learned from pixels whose blue is clipped puts the blue back at about
    the sensor's top, so its half step lay 0.2-0.35 px outside the edge; put back from the
    edge's mixing, the edge is found to 0.1 px."""
    rng = np.random.default_rng(11)
    edge_px = 100.3
    image = _blue_patch_frame(edge_px, blur_px, rng)
    assert abs(_side_offset(image, edge_px)) < 0.1
    monkeypatch.setattr(edge_fit, "unclip_by_mixing", lambda raw, given, *rest: given)
    assert _side_offset(image, edge_px) > 0.18
