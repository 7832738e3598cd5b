"""The graph's ``record:`` setting and its checks (no heavy imports: the parser uses it).

::

    record: true                        # record every output, images as JPEG
    record:
      images: raw                       # raw | jpeg | png: how image outputs are recorded
      jpeg_quality: 90                  # 1..100
      ports: {camera.image: png, view.image: off}   # per output: raw | jpeg | png | off
      file: recording.mcap              # inside the run folder

``umbra run --record`` turns recording on with these settings (or the defaults).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from umbra.connectors.errors import Location
from umbra.connectors.user_files import run_file_problem

IMAGE_CHOICES = ("raw", "jpeg", "png")
PORT_CHOICES = (*IMAGE_CHOICES, "off")
RECORD_KEYS = ("images", "jpeg_quality", "ports", "file")
DEFAULT_FILE = "recording.mcap"


@dataclass
class RecordSettings:
    """Whether and how a run records its connections (see the module docstring)."""

    enabled: bool = False
    images: str = "jpeg"
    jpeg_quality: int = 90
    ports: dict[str, str] = field(default_factory=dict)
    file: str = DEFAULT_FILE
    #: ``foxglove`` (Foxglove's schemas) or ``ros2`` (ros2msg/cdr channels: ``--record-format``)
    format: str = "foxglove"
    loc: Location | None = None
    port_locs: dict[str, Location] = field(default_factory=dict)

    def choice(self, module: str, port: str) -> str:
        """``raw``, ``jpeg``, ``png`` or ``off`` for output ``module.port``: its ``ports`` entry,
        else ``images`` (which only image outputs use)."""
        return self.ports.get(f"{module}.{port}", self.images)


def parse_record(
    value: Any, loc: Location, error: Callable[[Location, str], None]
) -> RecordSettings:
    """The ``record:`` value (a bool or a mapping); problems go to ``error(loc, message)``."""
    if isinstance(value, bool):
        return RecordSettings(enabled=value, loc=loc)
    if not isinstance(value, dict):
        error(loc, f"`record` must be true, false or a mapping, found {type(value).__name__}")
        return RecordSettings(loc=loc)
    settings = RecordSettings(enabled=True, loc=loc)
    where = getattr(value, "val_loc", {})
    keys = getattr(value, "key_loc", {})
    for key in value:
        if key not in RECORD_KEYS:
            error(
                keys.get(key, loc),
                f"unknown key `{key}` in `record` (expected one of {', '.join(RECORD_KEYS)})",
            )
    if "images" in value:
        if value["images"] not in IMAGE_CHOICES:
            error(
                where.get("images", loc),
                f"`record.images` must be one of {', '.join(IMAGE_CHOICES)}, "
                f"found {value['images']!r}",
            )
        else:
            settings.images = value["images"]
    if "jpeg_quality" in value:
        q = value["jpeg_quality"]
        if isinstance(q, bool) or not isinstance(q, int) or not 1 <= q <= 100:
            error(
                where.get("jpeg_quality", loc),
                f"`record.jpeg_quality` must be a whole number from 1 to 100, found {q!r}",
            )
        else:
            settings.jpeg_quality = q
    if "file" in value:
        f = value["file"]
        why = run_file_problem(f) if isinstance(f, str) else "is not a string"
        if why or not isinstance(f, str):
            error(where.get("file", loc), f"`record.file` {f!r} {why}")
        else:
            settings.file = f
    if "ports" in value:
        ports = value["ports"]
        ploc = where.get("ports", loc)
        if not isinstance(ports, dict):
            error(ploc, f"`record.ports` must map MODULE.PORT to one of {', '.join(PORT_CHOICES)}")
        else:
            plocs = getattr(ports, "val_loc", {})
            pkeys = getattr(ports, "key_loc", {})
            for name, choice in ports.items():
                if choice is False:  # YAML reads a bare `off` as false
                    choice = "off"
                if not isinstance(name, str) or name.count(".") != 1:
                    error(
                        pkeys.get(name, ploc),
                        f"`record.ports`: expected MODULE.PORT, found {name!r}",
                    )
                elif choice not in PORT_CHOICES:
                    error(
                        plocs.get(name, ploc),
                        f"`record.ports.{name}` must be one of {', '.join(PORT_CHOICES)}, "
                        f"found {choice!r}",
                    )
                else:
                    settings.ports[name] = choice
                    settings.port_locs[name] = pkeys.get(name, ploc)
    return settings


def check_record_ports(
    settings: RecordSettings,
    outputs: dict[str, set[str] | None],
    error: Callable[[Location, str], None],
) -> None:
    """Each ``record.ports`` entry names an output of a module of the graph (``outputs``: output
    names by module; None for a module whose declaration was already reported broken)."""
    for name in settings.ports:
        module, port = name.split(".")
        loc = settings.port_locs.get(name, settings.loc or Location("graph", 0))
        if module not in outputs:
            error(loc, f"`record.ports`: no module `{module}` in the graph")
        elif (names := outputs[module]) is not None and port not in names:
            error(
                loc,
                f"`record.ports`: module `{module}` has no output `{port}` "
                f"(outputs: {', '.join(sorted(names)) or 'none'})",
            )
