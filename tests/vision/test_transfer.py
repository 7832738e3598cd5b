"""The camera's transfer curve: an sRGB camera's edges are measured on the light its codes stand
for, so its patches keep their area; read as codes, the half-way point of every edge lies towards
its dark side."""

from __future__ import annotations

import numpy as np
import pytest
from skimage.color import rgb2xyz, xyz2rgb

from umbra.modules.vision import color
from umbra.modules.vision import photo_scene as ps
from umbra.modules.vision.edge_fit import EdgeFitParams, fit_edges, sample_light
from umbra.modules.vision.metrics import polygon_iou
from umbra.modules.vision.polygon import signed_area
from umbra.modules.vision.snake import SnakeParams
from umbra.modules.vision.snake_config import SnakeSettings, snake_setup
from umbra.modules.vision.tracker import SnakeTracker
from umbra.modules.vision.transfer import light_table, to_codes, to_light

from .test_edge_fit import half_plane_image

#: CIE XYZ of the sRGB white (D65): gray light L is XYZ = L * this.
_D65 = np.array([0.95047, 1.0, 1.08883])


def skimage_codes(light: np.ndarray) -> np.ndarray:
    """sRGB codes (0..255 float) of ``light`` (0..255, any shape), each value encoded as the
    gray of that light by scikit-image's sRGB (an implementation apart from ours)."""
    flat = np.asarray(light, dtype=float).reshape(-1, 1) / 255.0
    encoded = xyz2rgb((flat * _D65)[None])[0]
    return (255.0 * encoded.mean(axis=1)).reshape(np.shape(light))


def test_the_light_of_srgb_codes_is_scikit_images() -> None:
    codes = np.arange(256, dtype=float)
    gray = np.repeat((codes / 255.0)[:, None], 3, axis=1)
    skimage_light = 255.0 * rgb2xyz(gray[None])[0][:, 1]  # Y of a gray is its light
    np.testing.assert_allclose(to_light(codes, "srgb"), skimage_light, atol=2e-3)
    np.testing.assert_allclose(light_table("srgb"), skimage_light, atol=2e-3)
    # Code 128 is 21.6 % of the light, not half of it.
    assert to_light(np.array([128.0]), "srgb")[0] / 255.0 == pytest.approx(0.2158, abs=1e-4)
    np.testing.assert_allclose(to_codes(to_light(codes, "srgb"), "srgb"), codes, atol=1e-3)
    np.testing.assert_allclose(to_codes(skimage_light, "srgb"), codes, atol=0.02)
    # Linear codes are their light; the curve goes on above the sensor's top.
    np.testing.assert_array_equal(to_light(codes, "linear"), codes)
    above = to_light(np.array([255.0, 300.0]), "srgb")
    assert above[0] == pytest.approx(255.0) and above[1] > 300.0


def test_light_is_interpolated_after_each_pixel_is_decoded() -> None:
    rng = np.random.default_rng(8)
    image = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    points = rng.uniform([0, 0], [38.99, 28.99], (50, 7, 2))
    light = to_light(image.astype(float), "srgb").astype(float)
    u0, v0 = np.floor(points[..., 0]).astype(int), np.floor(points[..., 1]).astype(int)
    fu, fv = (points[..., 0] - u0)[..., None], (points[..., 1] - v0)[..., None]
    exact = (1 - fv) * ((1 - fu) * light[v0, u0] + fu * light[v0, u0 + 1]) + fv * (
        (1 - fu) * light[v0 + 1, u0] + fu * light[v0 + 1, u0 + 1]
    )
    np.testing.assert_allclose(sample_light(image, points, "srgb"), exact, atol=1e-3)
    # Points outside read the border pixel's light.
    border = sample_light(image, np.array([[[-5.0, 3.0], [60.0, 100.0]]]), "srgb")
    np.testing.assert_allclose(border[0], light[[3, 29], [0, 39]], atol=1e-3)


@pytest.mark.parametrize("blur_sigma_px", [0.7, 1.2])
@pytest.mark.parametrize(
    ("patch_bgr", "background_bgr"),
    [((20.0, 30.0, 140.0), (190.0, 200.0, 210.0)), ((40.0, 180.0, 230.0), (25.0, 20.0, 8.0))],
    ids=["dark-patch", "bright-patch"],
)
def test_an_srgb_edge_is_where_half_its_light_is(
    blur_sigma_px: float, patch_bgr: tuple, background_bgr: tuple
) -> None:
    """A blurred edge between a dark and a bright side, encoded by scikit-image's sRGB: read as
    light the edge is found within 0.03 px; read as codes it lies 0.15 px or more towards the
    dark side (into a dark patch, out of a bright one)."""
    rng = np.random.default_rng(11)
    image, normal, edge = half_plane_image(
        0.2,
        0.37,
        blur_sigma_px,
        0.0,
        rng,
        np.array(patch_bgr),
        np.array(background_bgr),
        encode=skimage_codes,
    )
    inner = np.rint(skimage_codes(np.array(patch_bgr)))
    model = color.from_rgb(tuple(inner[::-1]), 8.0)
    along = np.array([-normal[1], normal[0]])
    t = np.linspace(-60.0, 60.0, 40)
    vertices = np.array([100.0, 100.0]) + 0.2 * normal + t[:, None] * along
    vertices = vertices + rng.uniform(-1.0, 1.0, t.size)[:, None] * normal
    normals = np.repeat(normal[None, :], t.size, axis=0)
    offset = {}
    for encoding in ("linear", "srgb"):
        fit = fit_edges(image, vertices, normals, model, 3.0, 5.0, EdgeFitParams(encoding=encoding))
        assert fit.found.all()
        offset[encoding] = float(np.mean(fit.vertices @ normal - edge))
    assert abs(offset["srgb"]) < 0.03, offset
    towards_dark = -1.0 if sum(patch_bgr) < sum(background_bgr) else 1.0
    assert towards_dark * offset["linear"] > 0.15, offset


def test_srgb_frames_keep_their_area_when_the_snake_reads_light() -> None:
    """12 frames of the photo generator's sRGB camera at 640 x 480 (held-out photographs, no
    JPEG): with ``image_encoding: srgb`` the median |area bias| is within 0.1 % (0.04 %
    measured) and every IoU at least 0.99 (0.9946); read as codes, the median is 0.2 % or more
    (0.30 %)."""
    conditions = ps.CameraConditions(span_px=(120.0, 300.0), encoding="srgb", jpeg_share=0.0)
    bias: dict[str, list[float]] = {"linear": [], "srgb": []}
    ious = []
    for encoding, biases in bias.items():
        rng = np.random.default_rng(4361)
        for index in range(12):
            seed_offset = rng.uniform(-0.15, 0.15, 2)
            photo = ps.HELD_OUT_PHOTOS[index % len(ps.HELD_OUT_PHOTOS)]
            frame = ps.render(photo, np.random.default_rng([4360, index]), (640, 480), conditions)
            tracker = SnakeTracker(SnakeParams(image_encoding=encoding))
            seed = frame.corners.mean(axis=0) + seed_offset * np.ptp(frame.corners, axis=0)
            tracker.seed_at_point(frame.image, seed)
            outline = tracker.update(frame.image).vertices
            biases.append(abs(signed_area(outline)) / frame.area_px2 - 1.0)
            if encoding == "srgb":
                ious.append(polygon_iou(outline, frame.corners, (480, 640)))
    assert float(np.median(np.abs(bias["srgb"]))) <= 0.001, bias["srgb"]
    assert float(np.median(np.abs(bias["linear"]))) >= 0.002, bias["linear"]
    assert min(ious) >= 0.99, ious


def test_the_encoding_is_a_setting_with_two_choices() -> None:
    params, _ = snake_setup(SnakeSettings(image_encoding="srgb"))
    assert params.image_encoding == "srgb"
    assert snake_setup(SnakeSettings())[0].image_encoding == "linear"
    with pytest.raises(ValueError, match="'linear' or 'srgb'"):
        SnakeSettings(image_encoding="gamma")
