"""Entry point of the ``umbra`` command.

Exit status: 0 success, 1 the run failed, 2 bad input (graph, parameters, files, command line),
130 interrupted.
"""

from __future__ import annotations

import argparse
import ast
import atexit
import faulthandler
import importlib
import importlib.util
import logging
import os
import re
import signal
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points
from types import ModuleType
from typing import Any, NoReturn

from umbra.connectors.errors import UserError

#: The runtime's own sub-commands, in the order ``umbra --help`` lists them. Domain commands
#: (``snake``, ``arm``, ``calib``, ``trials``...) come from the ``umbra.commands`` entry-point
#: group, so the runtime never imports a domain package by name.
COMMANDS = (
    "cmd_run",
    "cmd_check",
    "cmd_modules",
    "cmd_describe",
    "cmd_graph",
    "cmd_bench",
    "cmd_record_info",
    "cmd_replay",
    "cmd_keys",
    "cmd_topics",
    "cmd_echo",
    "cmd_hz",
)
COMMAND_GROUP = "umbra.commands"
#: The guide's front page, which ``umbra --help`` names; each command names its own page in its
#: module's ``GUIDE`` (a path in the repository, like this one).
GUIDE = "docs/index.md"


#: A command-line word that is a value, not an option: a negative number or a comma-separated
#: list that starts with one (``--q -0.5,0.2,...``, ``--seed -3,4``, ``--at -1e-3``), ``-inf``
#: and ``-nan`` included, so that the command's own check names what is wrong with them.
NEGATIVE_VALUE_RE = re.compile(r"^-(\d|\.\d|inf|nan)[\w.+\-,]*$", re.IGNORECASE)


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse takes `-0.5,1` for an option unless it matches this pattern (argparse's own
        # attribute for it, unchanged since Python 2.7; no option of ours looks like a number)
        self._negative_number_matcher = NEGATIVE_VALUE_RE

    def error(self, message: str) -> NoReturn:  # usage message and exit 2 on a bad command line
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _load_commands(only: str | None = None) -> list[ModuleType]:
    """The command modules: just the one named ``only`` when it names one that loads (a command
    imports its own stacks, never the others'), else every command."""
    one = _load_command(only) if only else None
    if one is not None:
        return [one]
    found = [importlib.import_module(f"umbra.runtime.cli.{name}") for name in COMMANDS]
    for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            found.append(ep.load())
        except Exception as exc:  # a broken plug-in must not take the CLI down
            print(f"umbra: warning: command `{ep.name}` failed to load: {exc}", file=sys.stderr)
    return found


def _load_command(name: str) -> ModuleType | None:
    """The module of the command ``name`` (runtime ``cmd_<name>``, or the entry point of that
    name), or None when none loads with that ``NAME``."""
    module = f"cmd_{name.replace('-', '_')}"
    try:
        if module in COMMANDS:
            cmd = importlib.import_module(f"umbra.runtime.cli.{module}")
        else:
            (ep,) = [ep for ep in entry_points(group=COMMAND_GROUP) if ep.name == name]
            cmd = ep.load()
    except Exception:  # none, two, or a broken plug-in: loading them all says which
        return None
    return cmd if getattr(cmd, "NAME", None) == name else None


def _command_modules() -> list[str]:
    """The import names of every command's module: the runtime's, then the plug-ins' by name."""
    plugins = sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name)
    return [f"umbra.runtime.cli.{name}" for name in COMMANDS] + [ep.module for ep in plugins]


def _declared_face(module: str) -> tuple[str, str] | None:
    """``(NAME, HELP)`` as the command module ``module`` declares them, read from its source
    without running it (``umbra --help`` lists every command and needs nothing else of them);
    None when the source is not at hand or does not declare both as plain strings."""
    try:
        spec = importlib.util.find_spec(module)
        loader = spec.loader if spec else None
        source = loader.get_source(module) if loader and hasattr(loader, "get_source") else None
        tree = ast.parse(source) if source else None
    except (ImportError, SyntaxError, ValueError):
        return None
    found: dict[str, str] = {}
    for node in tree.body if tree else ():
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
            if isinstance(target, ast.Name) and target.id in ("NAME", "HELP"):
                value = node.value
                if isinstance(value, ast.Constant) and isinstance(value.value, str):
                    found[target.id] = value.value
    return (found["NAME"], found["HELP"]) if len(found) == 2 else None


def _listing_parser(parser: argparse.ArgumentParser) -> argparse.ArgumentParser | None:
    """``parser`` with one entry per command, named and described from the commands' declared
    faces (:func:`_declared_face`) and configured no further: what ``umbra --help`` prints.
    None when a command's face cannot be read so (a plug-in that builds its ``HELP``); the
    caller then loads every command."""
    faces = [_declared_face(module) for module in _command_modules()]
    if any(face is None for face in faces):
        return None
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, help_text in (face for face in faces if face is not None):
        sub.add_parser(name, help=help_text)
    return parser


def _command_word(argv: Sequence[str]) -> str | None:
    """The command ``argv`` starts with; None when it starts with an option (``--help``)."""
    return argv[0] if argv and not argv[0].startswith("-") else None


def build_parser(command: str | None = None, listing: bool = False) -> argparse.ArgumentParser:
    """The ``umbra`` parser: with ``command``, only that command's sub-parser when it is one;
    with ``listing`` (``umbra --help``), every command named and described, none configured."""
    parser = _Parser(
        prog="umbra",
        description="Dataflow connector framework for vision-guided robots (Umbra/SMART).",
        epilog=f"guide: {GUIDE} (each command's --help names its page)",
    )
    if listing and command is None and _listing_parser(parser) is not None:
        return parser
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for cmd in _load_commands(command):
        guide = getattr(cmd, "GUIDE", None)  # a plug-in's command may have no page of ours
        epilog = f"guide: {guide}" if guide else None
        p = sub.add_parser(cmd.NAME, help=cmd.HELP, description=cmd.HELP, epilog=epilog)
        cmd.configure(p)
        p.set_defaults(_main=cmd.main)
    return parser


def _asks_listing(argv: Sequence[str]) -> bool:
    """Whether ``argv`` asks only for the list of commands (``umbra``, ``umbra --help``)."""
    return all(word in ("-h", "--help") for word in argv)


def main(argv: list[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else argv
    parser = build_parser(_command_word(words), listing=_asks_listing(words))
    args = parser.parse_args(argv)
    if not getattr(args, "_main", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args._main(args))
    except UserError as exc:
        print(
            f"umbra {args.command}: error: {exc}" if "error:" not in str(exc) else str(exc),
            file=sys.stderr,
        )
        return 2
    except KeyboardInterrupt:
        print(f"umbra {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


def entry() -> NoReturn:
    """The ``umbra`` command: :func:`main`, then leave the process without finalizing the
    interpreter.

    Native threads (zenoh's runtime, the live server's) may still call into Python while an
    interpreter finalizes; the interpreter then ends such a thread by unwinding it through their
    frames, and glibc aborts the process ("FATAL: exception not rethrown", SIGABRT) after a run
    that went well. Everything :func:`main` writes (summaries, recordings) is written and closed
    before it returns; the exit handlers and logging are flushed here, then the process ends with
    :func:`main`'s status. SIGUSR1 prints every thread's Python stack to stderr and the run goes
    on: what a process that does not stop is waiting for. Once :func:`main` has returned, Ctrl-C
    is ignored."""
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    try:
        code = main()
    except KeyboardInterrupt:  # a Ctrl-C after main's own handler, as it returned
        code = 130
    # the status is decided and everything written: a Ctrl-C now has nothing left to stop, and
    # Python's own handler would raise it inside an exit handler (printed with its traceback)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        atexit._run_exitfuncs()  # what finalizing would run first (temporary files, ...)
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(code)


if __name__ == "__main__":
    entry()
