"""CSV files of 3-D/2-D correspondences for the calibration command line.

A header names the columns: ``x,y,z,u,v`` (points in metres, pixels), plus ``camera`` for
correspondences seen by several cameras. Blank lines and lines starting with ``#`` are skipped.
Errors are ``UserError("FILE:LINE: error: ...")``.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.errors import UserError
from umbra.modules.calib import yaml_nodes as yn

NUMERIC = ("x", "y", "z", "u", "v")
#: Most correspondences a file may hold (a calibration uses tens to thousands).
MAX_ROWS = 100_000


@dataclass(frozen=True, eq=False)
class Correspondences:
    """Points ``(n, 3)`` (metres), pixels ``(n, 2)``, optional camera names and source lines."""

    points: NDArray[np.float64]
    pixels: NDArray[np.float64]
    cameras: tuple[str, ...]
    lines: tuple[int, ...]


def parse_correspondences(
    content: str, source: str = "<string>", with_camera: bool = False
) -> Correspondences:
    """Parse correspondence CSV text; ``with_camera`` requires a ``camera`` column."""
    expected = (("camera",) if with_camera else ()) + NUMERIC
    rows = [
        (number, line)
        for number, line in enumerate(content.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise UserError(f"{source}:1: error: no header; expected columns {','.join(expected)}")
    header_line, header_text = rows[0]
    if len(rows) - 1 > MAX_ROWS:
        raise UserError(
            f"{source}:{rows[MAX_ROWS + 1][0]}: error: more than {MAX_ROWS} correspondences"
        )
    header = [h.strip().lower() for h in _cells(header_text, source, header_line)]
    if sorted(header) != sorted(expected):
        raise UserError(
            f"{source}:{header_line}: error: header must name the columns "
            f"{','.join(expected)}; found {','.join(header)}"
        )
    points, pixels, cameras, lines = [], [], [], []
    for line_number, line in rows[1:]:
        cells = [c.strip() for c in _cells(line, source, line_number)]
        if len(cells) != len(header):
            raise UserError(
                f"{source}:{line_number}: error: expected {len(header)} values, found {len(cells)}"
            )
        row = dict(zip(header, cells, strict=True))
        values = {}
        for key in NUMERIC:
            try:
                values[key] = float(row[key])
            except ValueError:
                raise UserError(
                    f"{source}:{line_number}: error: bad number {row[key]!r} in column {key}"
                ) from None
            if not math.isfinite(values[key]):
                raise UserError(f"{source}:{line_number}: error: {key} must be finite")
        points.append([values["x"], values["y"], values["z"]])
        pixels.append([values["u"], values["v"]])
        cameras.append(row.get("camera", ""))
        lines.append(line_number)
    if not points:
        raise UserError(f"{source}:{header_line}: error: no correspondences after the header")
    return Correspondences(
        np.array(points, dtype=float), np.array(pixels, dtype=float), tuple(cameras), tuple(lines)
    )


def _cells(line: str, source: str, line_number: int) -> list[str]:
    """The comma-separated cells of one line; UserError when the csv module refuses it."""
    try:
        return next(csv.reader(io.StringIO(line)), [])
    except csv.Error as error:
        raise UserError(f"{source}:{line_number}: error: not a CSV line: {error}") from None


def load_correspondences(path: str | Path, with_camera: bool = False) -> Correspondences:
    """Read a correspondence CSV file."""
    return parse_correspondences(yn.read_text(path, "correspondence file"), str(path), with_camera)
