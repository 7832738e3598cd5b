"""``umbra describe TYPE``: ports and parameters, generated from the module's declarations."""

from __future__ import annotations

import argparse
import inspect
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from umbra.connectors.module import Module

NAME = "describe"
HELP = "print a module type's ports and parameters"
GUIDE = "docs/reference/modules.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("type", metavar="TYPE", help="module type name (see `umbra modules`)")


def describe(cls: type[Module[Any]]) -> str:
    """The text ``umbra describe`` prints for module class ``cls``."""
    lines = [f"{cls.type_name()}  ({cls.__module__}.{cls.__qualname__})"]
    if cls.SAFETY_GUARD:
        lines.append("safety guard: command paths through this module count as guarded")
    doc = inspect.cleandoc(cls.__doc__ or "")
    if doc:
        lines += ["", *("  " + d for d in doc.splitlines())]
    for title, decls in (("inputs", cls.input_decls()), ("outputs", cls.output_decls())):
        lines += ["", f"{title}:"]
        if not decls:
            lines.append("  (none)")
        for name, d in decls.items():
            flags = []
            frame = d.describe_frame()
            if frame:
                flags.append(f"frame {frame}")
            if d.joints is not None:
                flags.append(f"joints {d.joints}")
            for attr in ("trigger", "feedback", "requires_guard"):
                if getattr(d, attr, False):
                    flags.append(attr.replace("_", " "))
            max_age = getattr(d, "max_age", None)
            if max_age is not None:
                flags.append(f"max age {max_age} s")
            if getattr(d, "required", True) is False:
                flags.append("optional")
            extra = f" [{', '.join(flags)}]" if flags else ""
            lines.append(f"  {name}: {d.msg_type.__name__}{extra}  {d.doc}")
    from umbra.connectors.params import describe_params  # `umbra --help` loads this file

    lines += ["", "parameters:"]
    params = describe_params(cls.Params)
    if not params:
        lines.append("  (none)")
    for p in params:
        unit = f" [{p.unit}]" if p.unit else ""
        cons = f", {p.constraints}" if p.constraints else ""
        default = "(required)" if p.required else f"= {p.default!r}"
        marks = [m for m, on in _marks(cls, p.name).items() if on]
        mark = f" ({', '.join(marks)})" if marks else ""
        lines.append(f"  {p.name}: {p.type} {default}{unit}{cons}{mark}  {p.doc}")
    return "\n".join(lines)


def _marks(cls: type[Module[Any]], name: str) -> dict[str, bool]:
    """``tunable``: may be changed while the graph runs; ``safety``: bounds what reaches the arm."""
    from umbra.connectors.params import is_safety, is_tunable

    return {"tunable": is_tunable(cls.Params, name), "safety": is_safety(cls.Params, name)}


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.registry import Registry

    cls = Registry().require(args.type)
    print(describe(cls))
    return 0
