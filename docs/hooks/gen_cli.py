"""The command-line reference, generated from the ``umbra`` parser (run by the site's build hook,
``generated.py``): ``umbra --help`` and each command's ``--help``, as they print."""

from __future__ import annotations

import argparse
import os

from umbra.runtime.cli.main import build_parser

PAGE = "reference/cli.md"


def render() -> str:
    os.environ["COLUMNS"] = "100"  # argparse wraps at the terminal's width: the page's, fixed
    parser = build_parser()
    out = [
        "# Command-line reference",
        "",
        "`umbra --help` and each command's `--help`, generated from the parser when the site "
        "is built. Exit status: 0 success, 1 the run failed, 2 bad input (graph, parameters, "
        "files, command line), 130 interrupted (Ctrl-C / SIGTERM; summaries and recordings are "
        "still written). Domain commands (`snake`, `arm`, `calib`, `trials`, `pose-tool`, "
        "`sketch`) come from the `umbra.commands` entry points.",
        "",
        "## umbra",
        "",
        "```text",
        parser.format_help().rstrip(),
        "```",
    ]
    for name, sub in commands(parser).items():
        out += ["", f"## umbra {name}", "", "```text", sub.format_help().rstrip(), "```"]
    return "\n".join(out) + "\n"


def commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """Each command's sub-parser by name, in the order ``umbra --help`` lists them."""
    for action in parser._actions:  # argparse keeps sub-parsers only here
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}
