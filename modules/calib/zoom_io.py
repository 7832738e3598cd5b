"""Load and save zoom calibration files by extension: ``.xml`` (Appendix D) or ``.yaml``."""

from __future__ import annotations

from pathlib import Path

from umbra.connectors.errors import UserError
from umbra.modules.calib.zoom_table import ZoomFile, ZoomTable
from umbra.modules.calib.zoom_xml import read_zoom_xml, write_zoom_xml
from umbra.modules.calib.zoom_yaml import read_zoom_yaml, write_zoom_yaml

XML_SUFFIXES = (".xml",)
YAML_SUFFIXES = (".yaml", ".yml")


def _kind(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix in XML_SUFFIXES:
        return "xml"
    if suffix in YAML_SUFFIXES:
        return "yaml"
    raise UserError(
        f"{path}: error: unknown calibration file type {suffix or '(none)'!r}; expected .xml, "
        ".yaml or .yml"
    )


def load_zoom_file(path: str | Path) -> ZoomFile:
    """Read a zoom calibration file (XML or YAML by extension)."""
    path = Path(path)
    return read_zoom_xml(path) if _kind(path) == "xml" else read_zoom_yaml(path)


def load_zoom_table(path: str | Path, camera: str | None = None) -> ZoomTable:
    """The table of camera ``camera`` (or the file's only camera) from a calibration file."""
    zoom_file = load_zoom_file(path)
    try:
        return zoom_file.camera(camera or None)
    except KeyError as error:
        raise UserError(f"{path}: error: {error.args[0]}") from None


def check_writable(path: Path, what: str) -> None:
    """UserError unless a file can be written at ``path`` (its folder exists, it is no folder)."""
    folder = path.parent
    if not folder.is_dir():
        raise UserError(
            f"{what} {path}: error: folder {folder} does not exist (create it first)"
            if not folder.exists()
            else f"{what} {path}: error: {folder} is not a folder"
        )
    if path.is_dir():
        raise UserError(f"{what} {path}: error: is a folder, expected a file name")


def save_zoom_file(path: str | Path, zoom_file: ZoomFile) -> None:
    """Write a zoom calibration file (XML or YAML by extension); UserError when it cannot."""
    path = Path(path)
    check_writable(path, "zoom file")
    try:
        if _kind(path) == "xml":
            write_zoom_xml(path, zoom_file)
        else:
            write_zoom_yaml(path, zoom_file)
    except OSError as error:
        raise UserError(f"{path}: error: cannot write the zoom file: {error.strerror}") from None
