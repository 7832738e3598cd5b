"""``umbra modules``: list the registered module types."""

from __future__ import annotations

import argparse
import re
import textwrap

NAME = "modules"
HELP = "list module types (from the umbra.modules entry points)"
GUIDE = "docs/reference/modules.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON")


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.registry import Registry

    registry = Registry()
    rows = []
    for name in registry.names():
        cls = registry.get(name)
        doc = first_sentence(cls.__doc__ or "") if cls else ""
        rows.append((name, doc if cls else f"(failed to load: {registry.broken.get(name)})"))
    if args.json:
        from umbra.runtime.cli.common import print_json

        print_json({name: doc for name, doc in rows})
        return 0
    width = max((len(n) for n, _ in rows), default=0)
    for name, doc in rows:  # a long sentence wraps under itself, never cut
        indent = " " * (width + 2)
        print(
            textwrap.fill(
                doc, 100, initial_indent=name.ljust(width) + "  ", subsequent_indent=indent
            )
        )
    return 0


#: The end of a sentence: ., ! or ? right after a word, then a space and a capital (or the end).
#: A period standing alone (``T_a . T_b``) or inside a word (``e.g.``, ``1.5``) is not one.
_SENTENCE_END = re.compile(r"(?<=\S)[.!?](?=\s+[A-Z`(\[]|\s*$)")


def first_sentence(doc: str) -> str:
    """The first sentence of a docstring's first paragraph, on one line (whole, never cut)."""
    paragraph = " ".join(doc.strip().split("\n\n")[0].split())
    end = _SENTENCE_END.search(paragraph)
    return paragraph[: end.end()] if end else paragraph
