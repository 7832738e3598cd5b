"""``umbra modules``: list the registered module types."""

from __future__ import annotations

import argparse

from runtime.registry import Registry

NAME = "modules"
HELP = "list module types (from the umbra.modules entry points)"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON")


def main(args: argparse.Namespace) -> int:
    registry = Registry()
    rows = []
    for name in registry.names():
        cls = registry.get(name)
        doc = (cls.__doc__ or "").strip().splitlines()[0] if cls and cls.__doc__ else ""
        rows.append((name, doc if cls else f"(failed to load: {registry.broken.get(name)})"))
    if args.json:
        from runtime.cli.common import print_json

        print_json({name: doc for name, doc in rows})
        return 0
    width = max((len(n) for n, _ in rows), default=0)
    for name, doc in rows:
        print(f"{name.ljust(width)}  {doc}")
    return 0
