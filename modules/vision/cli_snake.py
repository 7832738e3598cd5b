"""``umbra snake IMAGE --seed U,V``: grow the statistical pressure snake on one image.

Loads the image, learns the target color around the seed point, grows the snake until it
converges and runs the sanity checks. Prints the result for a person, or with ``--json`` one
object: status, reason, centroid [u, v] (px), area (px²), orientation_deg (principal axis from
the u axis towards v), axes [major, minor] (px), polygon [[u, v], ...] (px), iterations,
converged, and time_ms (the snake alone, not loading or writing). ``--set NAME=VALUE`` changes
a snake setting (the vsSnake parameter names, e.g. ``k_sigma=3.5``, ``max_rotation_deg=10``).
``--overlay OUT.png`` writes the image with the snake and its checks drawn on it.

Exit status: 0 when the contour passes the sanity checks, 1 when it fails them, 2 bad input.
"""

from __future__ import annotations

import argparse

import numpy as np
import pydantic

from umbra.connectors.cli_support import parse_set, print_json
from umbra.connectors.errors import UserError
from umbra.connectors.params import validation_problems
from umbra.modules.vision.image_file import read_image
from umbra.modules.vision.overlay import draw_overlay
from umbra.modules.vision.snake_config import SnakeSettings, snake_setup
from umbra.modules.vision.tracker import SnakeTracker

NAME = "snake"
HELP = "run the snake on one image until it converges"
GUIDE = "docs/guide/pickup.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("image", metavar="IMAGE", help="image file (PNG, JPEG, ...)")
    parser.add_argument(
        "--seed", required=True, metavar="U,V", help="seed point inside the target [px]"
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="snake setting, as the vsSnake parameters (repeatable)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--overlay", metavar="OUT.png", help="write the drawn result here")


def _seed(text: str, shape: tuple[int, ...]) -> tuple[float, float]:
    parts = text.split(",")
    try:
        u, v = (float(p) for p in parts)
    except ValueError:
        raise UserError(f"--seed expects U,V in pixels (e.g. 320,240), found `{text}`") from None
    height, width = shape[:2]
    if not (0 <= u < width and 0 <= v < height):
        raise UserError(f"--seed {u:g},{v:g} is outside the {width}x{height} image")
    return u, v


def _load(path: str) -> np.ndarray:
    """The image (bounded in bytes and pixels, decoded as BGR):
    ``umbra.modules.vision.image_file``."""
    return read_image(path)


def main(args: argparse.Namespace) -> int:
    import cv2

    image = _load(args.image)
    seed = _seed(args.seed, image.shape)
    try:
        settings = SnakeSettings(**parse_set(args.set))
    except pydantic.ValidationError as exc:
        problems = "; ".join(validation_problems(SnakeSettings, exc))
        raise UserError(f"--set: snake settings: {problems}") from None
    params, limits = snake_setup(settings)
    tracker = SnakeTracker(params, limits)
    try:
        tracker.seed_at_point(image, seed)
    except ValueError as exc:
        raise UserError(f"--seed {seed[0]:g},{seed[1]:g}: {exc}") from None
    update = tracker.update(image)
    sanity = update.sanity
    features = sanity.features
    result = {
        "image": args.image,
        "seed": list(seed),
        "status": sanity.status,
        "reason": sanity.reason,
        "centroid": list(features.centroid_uv) if features else None,
        "area": features.area_px2 if features else 0.0,
        "orientation_deg": float(np.rad2deg(features.orientation_rad)) if features else None,
        "axes": [features.major_axis_px, features.minor_axis_px] if features else None,
        "polygon": np.round(update.vertices, 3).tolist(),
        "iterations": update.iterations,
        "converged": update.converged,
        "time_ms": 1e3 * update.snake_time_s,
    }
    if args.overlay:
        lines = [f"snake: {sanity.status}" + (f" - {sanity.reason}" if sanity.reason else "")]
        drawn = draw_overlay(image, update.vertices, sanity, lines)
        try:
            written = cv2.imwrite(args.overlay, drawn)
        except cv2.error:
            written = False
        if not written:
            raise UserError(f"--overlay {args.overlay}: cannot write the image there")
    if args.json:
        print_json(result)
    else:
        _print(result, len(update.vertices))
    return 0 if sanity.ok else 1


def _print(result: dict, vertices: int) -> None:
    print(
        f"{result['image']}: {result['status']}"
        + (f" ({result['reason']})" if result["reason"] else "")
    )
    if result["centroid"] is not None:
        u, v = result["centroid"]
        major, minor = result["axes"]
        print(f"  centroid     {u:.2f}, {v:.2f} px")
        print(f"  area         {result['area']:.1f} px²")
        print(f"  orientation  {result['orientation_deg']:.2f} deg")
        print(f"  axes         {major:.1f} x {minor:.1f} px")
    state = "converged" if result["converged"] else "not converged"
    print(
        f"  snake        {vertices} vertices, {result['iterations']} iterations ({state}), "
        f"{result['time_ms']:.2f} ms"
    )
