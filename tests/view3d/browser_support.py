"""Driving the 3-D view in Debian's Chromium with Playwright, for the browser tests."""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from tests.browser import launch, needs_chromium  # noqa: F401 - re-exported for the tests
from umbra.modules.view3d.geometry import matrix_from_wxyz


def block_outside_loopback(page) -> None:
    """Refuse every request that leaves 127.0.0.1 at once (the machine has no internet; a web
    font the page asks for elsewhere would otherwise hold the first screenshot for seconds)."""

    def route(r) -> None:
        host = r.request.url.split("://", 1)[-1].split("/", 1)[0].split(":", 1)[0]
        if host in ("127.0.0.1", "localhost") or r.request.url.startswith(("data:", "blob:")):
            r.continue_()
        else:
            r.abort()

    page.route("**/*", route)


@dataclass
class Canvas:
    """The viewer's canvas on the page: offset and size in CSS pixels."""

    left: float
    top: float
    width: float
    height: float


def canvas_box(page) -> Canvas | None:
    """The page's largest canvas, or None while it has none (a page reloading)."""
    box = page.evaluate(
        """() => { let best = null; for (const c of document.querySelectorAll('canvas')) {
             const r = c.getBoundingClientRect();
             if (!best || r.width * r.height > best.width * best.height) best = r; }
           return best && {left: best.left, top: best.top, width: best.width,
                           height: best.height}; }"""
    )
    return None if box is None else Canvas(box["left"], box["top"], box["width"], box["height"])


def screenshot(page) -> np.ndarray:
    """The page as an RGB array (one array pixel per CSS pixel)."""
    from PIL import Image as PILImage

    return np.asarray(PILImage.open(io.BytesIO(page.screenshot())).convert("RGB"))


def project_to_page(client, canvas: Canvas, points: np.ndarray) -> np.ndarray:
    """Page pixels ``(n, 2)`` of world points seen by a browser's viewer camera (viser's
    camera: OpenCV axes, vertical field of view, square pixels, centred)."""
    camera = client.camera
    R = matrix_from_wxyz(camera.wxyz)
    c = (np.asarray(points, dtype=float) - np.asarray(camera.position)) @ R
    f = (canvas.height / 2.0) / np.tan(camera.fov / 2.0)
    u = canvas.width / 2.0 + f * c[:, 0] / c[:, 2]
    v = canvas.height / 2.0 + f * c[:, 1] / c[:, 2]
    return np.stack([u + canvas.left, v + canvas.top], axis=1)


def inside_quad(quad: np.ndarray, shape: tuple[int, int], shrink: float) -> np.ndarray:
    """Mask of the pixels inside a convex quadrilateral shrunk (``shrink`` > 0) or grown (< 0)
    towards / away from its centre by that many pixels."""
    import cv2

    centre = quad.mean(axis=0)
    direction = quad - centre
    scale = 1.0 - shrink / np.linalg.norm(direction, axis=1, keepdims=True)
    moved = centre + direction * scale
    mask = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(mask, np.round(moved).astype(np.int32), 1)
    return mask.astype(bool)
