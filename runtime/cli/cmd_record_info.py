"""``umbra record-info RECORDING``: channels, rates, gaps, drops and duration of a recording."""

from __future__ import annotations

import argparse

NAME = "record-info"
HELP = "summarise an MCAP recording (channels, rates, gaps, drops, duration)"
GUIDE = "docs/guide/recording.md"  # the guide page this command's --help points to


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", metavar="RECORDING", help="recording (.mcap)")
    parser.add_argument("--json", action="store_true", help="one JSON object instead of a table")


def main(args: argparse.Namespace) -> int:
    from umbra.runtime.recording.info import format_info, info_json, recording_info

    info = recording_info(args.recording)
    print(info_json(info) if args.json else format_info(info))
    return 0
