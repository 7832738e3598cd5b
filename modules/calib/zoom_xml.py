"""Read and write the zoom calibration XML of the Sandia report's Appendix D, exactly as printed.

The format puts values in the text *before* child elements and lists in braces::

    <SR_world>
    <SR_filename> C:/ieddApps/camera/zoom_cam.xml </SR_filename>
    <SR_comment> free text </SR_comment>
    <SR_cam> zcam                              <- camera name
      <SR_zoom> 0.0                            <- normalized zoom, 0 wide .. 1 tele
        <SR_cam_int> {fx fy fxy u0 v0 k1 k2 p1 p2} </SR_cam_int>
        <SR_cam_ext> {dx dy dz thetax thetay thetaz} </SR_cam_ext>
      </SR_zoom>
      ...
    </SR_cam>
    </SR_world>

Units: see :mod:`umbra.modules.calib.zoom_table` (pixels; metres and radians for the extrinsics).
Zooms must lie in 0..1 and increase down the file. Every problem is reported as a
:class:`umbra.connectors.errors.UserError` reading ``FILE:LINE: error: message``; the parser is
expat (standard library), which gives the line of every element and text run. DOCTYPE
declarations (and so entity definitions) are refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np

from umbra.connectors.errors import UserError
from umbra.connectors.user_files import read_bytes
from umbra.modules.calib.zoom_table import ZoomFile, ZoomTable

INTRINSIC_LABEL = "{fx fy fxy u0 v0 k1 k2 p1 p2}"
EXTRINSIC_LABEL = "{dx dy dz thetax thetay thetaz}"


@dataclass
class _Element:
    tag: str
    line: int
    attributes: dict[str, str]
    text: str = ""
    text_line: int = 0
    children: list[_Element] = field(default_factory=list)


class _SpotError(Exception):
    def __init__(self, line: int, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.message = message


def _parse_tree(data: bytes) -> _Element:
    parser = expat.ParserCreate()
    stack: list[_Element] = []
    root: list[_Element] = []

    def start(tag: str, attributes: dict[str, str]) -> None:
        element = _Element(tag, parser.CurrentLineNumber, dict(attributes))
        if stack:
            stack[-1].children.append(element)
        else:
            root.append(element)
        stack.append(element)

    def end(tag: str) -> None:
        stack.pop()

    def characters(text: str) -> None:
        current = stack[-1]
        if current.children:
            if text.strip():
                raise _SpotError(
                    parser.CurrentLineNumber,
                    f"unexpected text {text.strip()!r} after <{current.children[-1].tag}> in "
                    f"<{current.tag}> (values go before the child elements)",
                )
            return
        if text.strip() and not current.text.strip():
            current.text_line = parser.CurrentLineNumber
        current.text += text

    def doctype(*_: object) -> None:
        raise _SpotError(parser.CurrentLineNumber, "DOCTYPE declarations are not allowed")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = characters
    parser.StartDoctypeDeclHandler = doctype
    parser.Parse(data, True)
    return root[0]


def _only(element: _Element, allowed: tuple[str, ...]) -> None:
    if element.attributes:
        name = next(iter(element.attributes))
        raise _SpotError(element.line, f"unexpected attribute {name!r} on <{element.tag}>")
    for child in element.children:
        if child.tag not in allowed:
            expected = ", ".join(f"<{t}>" for t in allowed) or "no child elements"
            raise _SpotError(
                child.line,
                f"unexpected element <{child.tag}> in <{element.tag}>; expected {expected}",
            )


def _no_text(element: _Element) -> None:
    if element.text.strip():
        raise _SpotError(
            element.text_line,
            f"unexpected text {element.text.strip()[:40]!r} in <{element.tag}>",
        )


def _number(token: str, line: int, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise _SpotError(line, f"bad number {token!r} in {what}") from None
    if not math.isfinite(value):
        raise _SpotError(line, f"bad number {token!r} in {what} (must be finite)")
    return value


def _value_list(element: _Element, count: int, label: str) -> list[float]:
    _only(element, ())
    line = element.text_line or element.line
    text = element.text.strip()
    if not text:
        raise _SpotError(element.line, f"<{element.tag}> is empty; expected {count} values {label}")
    if not (text.startswith("{") and text.endswith("}")):
        raise _SpotError(
            line, f"<{element.tag}> values must be enclosed in braces {label}, found {text[:40]!r}"
        )
    tokens = text[1:-1].split()
    values = [_number(t, line, f"<{element.tag}>") for t in tokens]
    if len(values) != count:
        raise _SpotError(line, f"<{element.tag}> needs {count} values {label}, found {len(values)}")
    return values


def _zoom_entry(element: _Element) -> tuple[float, list[float], list[float]]:
    _only(element, ("SR_cam_int", "SR_cam_ext"))
    text = element.text.strip()
    if not text:
        raise _SpotError(element.line, "<SR_zoom> needs a normalized zoom 0..1 before its children")
    zoom = _number(text, element.text_line, "<SR_zoom>")
    if not 0.0 <= zoom <= 1.0:
        raise _SpotError(element.text_line, f"zoom {zoom:g} is outside the normalized range 0..1")
    found: dict[str, _Element] = {}
    for child in element.children:
        if child.tag in found:
            raise _SpotError(
                child.line,
                f"second <{child.tag}> in <SR_zoom> (first on line {found[child.tag].line})",
            )
        found[child.tag] = child
    for tag in ("SR_cam_int", "SR_cam_ext"):
        if tag not in found:
            raise _SpotError(element.line, f"<SR_zoom> {zoom:g} has no <{tag}>")
    intrinsics = _value_list(found["SR_cam_int"], 9, INTRINSIC_LABEL)
    if intrinsics[0] <= 0 or intrinsics[1] <= 0:
        raise _SpotError(
            found["SR_cam_int"].text_line,
            f"focal lengths must be positive, found fx={intrinsics[0]:g} fy={intrinsics[1]:g}",
        )
    extrinsics = _value_list(found["SR_cam_ext"], 6, EXTRINSIC_LABEL)
    return zoom, intrinsics, extrinsics


def _camera(element: _Element) -> ZoomTable:
    _only(element, ("SR_zoom",))
    name = element.text.strip()
    if not element.children:
        raise _SpotError(element.line, f"camera {name!r} has no <SR_zoom> entries")
    zooms: list[float] = []
    intrinsics: list[list[float]] = []
    extrinsics: list[list[float]] = []
    lines: list[int] = []
    for child in element.children:
        zoom, intr, extr = _zoom_entry(child)
        if zooms and zoom <= zooms[-1]:
            raise _SpotError(
                child.text_line,
                f"zoom {zoom:g} does not increase from the previous zoom {zooms[-1]:g} "
                f"(line {lines[-1]}); list zooms in increasing order",
            )
        zooms.append(zoom)
        intrinsics.append(intr)
        extrinsics.append(extr)
        lines.append(child.text_line)
    try:
        return ZoomTable(name, np.array(zooms), np.array(intrinsics), np.array(extrinsics))
    except ValueError as error:
        raise _SpotError(element.line, str(error)) from None


def _world(root: _Element) -> ZoomFile:
    if root.tag != "SR_world":
        raise _SpotError(root.line, f"expected <SR_world> as the root element, found <{root.tag}>")
    _only(root, ("SR_filename", "SR_comment", "SR_cam"))
    _no_text(root)
    comment, recorded_path = "", ""
    cameras: list[ZoomTable] = []
    seen: dict[str, int] = {}
    for child in root.children:
        if child.tag == "SR_cam":
            table = _camera(child)
            if table.name in seen:
                raise _SpotError(
                    child.line,
                    f"second camera named {table.name!r} (first on line {seen[table.name]})",
                )
            seen[table.name] = child.line
            cameras.append(table)
        else:
            _only(child, ())
            if child.tag == "SR_comment":
                comment = child.text.strip()
            else:
                recorded_path = child.text.strip()
    if not cameras:
        raise _SpotError(root.line, "the file defines no camera (<SR_cam>)")
    return ZoomFile(tuple(cameras), comment, recorded_path)


def parse_zoom_xml(data: bytes | str, source: str = "<string>") -> ZoomFile:
    """Parse Appendix D XML text; errors are ``UserError("SOURCE:LINE: error: ...")``."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        return _world(_parse_tree(raw))
    except expat.ExpatError as error:
        message = expat.ErrorString(error.code)
        raise UserError(
            f"{source}:{error.lineno}: error: not well-formed XML: {message} "
            f"(column {error.offset + 1})"
        ) from None
    except _SpotError as failure:
        raise UserError(f"{source}:{failure.line}: error: {failure.message}") from None


def read_zoom_xml(path: str | Path) -> ZoomFile:
    """Read an Appendix D zoom calibration file."""
    path = Path(path)
    return parse_zoom_xml(read_bytes(path, "zoom calibration file"), str(path))


def _format_values(values: np.ndarray) -> str:
    return "{" + " ".join(repr(float(v)) for v in values) + "}"


def format_zoom_xml(zoom_file: ZoomFile) -> str:
    """Appendix D XML text with the report's layout; numbers round-trip exactly."""
    from xml.sax.saxutils import escape

    lines = ['<?xml version="1.0"?>', "<SR_world>"]
    if zoom_file.recorded_path:
        lines.append(f"<SR_filename> {escape(zoom_file.recorded_path)} </SR_filename>")
    if zoom_file.comment:
        lines += ["<SR_comment>", escape(zoom_file.comment), "</SR_comment>"]
    for table in zoom_file.cameras:
        lines += ["", f"<SR_cam> {escape(table.name)}"]
        for zoom, intr, extr in zip(table.zooms, table.intrinsics, table.extrinsics, strict=True):
            lines += [
                f"  <SR_zoom> {float(zoom)!r}",
                f"    <SR_cam_int> {_format_values(intr)} </SR_cam_int>",
                f"    <SR_cam_ext> {_format_values(extr)} </SR_cam_ext>",
                "  </SR_zoom>",
            ]
        lines.append("</SR_cam>")
    lines.append("</SR_world>")
    return "\n".join(lines) + "\n"


def write_zoom_xml(path: str | Path, zoom_file: ZoomFile) -> None:
    """Write ``zoom_file`` as Appendix D XML."""
    Path(path).write_text(format_zoom_xml(zoom_file), encoding="utf-8")
