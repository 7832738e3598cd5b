"""Load and save zoom calibration files by extension: ``.xml`` (Appendix D) or ``.yaml``."""

from __future__ import annotations

from pathlib import Path

from connectors.errors import UserError
from modules.calib.zoom_table import ZoomFile, ZoomTable
from modules.calib.zoom_xml import read_zoom_xml, write_zoom_xml
from modules.calib.zoom_yaml import read_zoom_yaml, write_zoom_yaml

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


def save_zoom_file(path: str | Path, zoom_file: ZoomFile) -> None:
    """Write a zoom calibration file (XML or YAML by extension)."""
    path = Path(path)
    if _kind(path) == "xml":
        write_zoom_xml(path, zoom_file)
    else:
        write_zoom_yaml(path, zoom_file)
