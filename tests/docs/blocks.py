"""The code blocks of README.md and docs/*.md, and the commands in their shell blocks.

Convention for the documentation (checked by ``test_docs_blocks.py``):

* Every fenced block names its language: ``bash``, ``python``, ``yaml``, ``toml``, ``json``,
  ``json5`` are run or checked; ``text`` is shown and never run (output, file layouts).
* A block shown but not run (it needs files or hosts a reader must bring, or it is a fragment of
  a larger file) says so after its language: ```` ```python norun ````. Use it sparingly: every
  block a user would run as it stands must run.
* In a ``bash`` block, a line with a host prompt (``robot$ umbra run ...``) is shown for another
  machine and not run; ``# ...`` starts a comment; every other line is a command that is run.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUN_LANGUAGES = frozenset({"bash", "python", "yaml", "toml", "json", "json5"})
NEVER_RUN = frozenset({"text"})
_FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.S | re.M)
_PROMPT = re.compile(r"^[A-Za-z][\w.-]*\$\s")


@dataclass(frozen=True)
class Block:
    """One fenced block: where it is, its language, whether it is run, its text."""

    file: Path
    line: int
    language: str
    norun: bool
    text: str

    @property
    def where(self) -> str:
        return f"{self.file.relative_to(ROOT)}:{self.line}"

    @property
    def runs(self) -> bool:
        return self.language in RUN_LANGUAGES and not self.norun


def doc_files() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def blocks(path: Path) -> list[Block]:
    text = path.read_text(encoding="utf-8")
    found = []
    for match in _FENCE.finditer(text):
        info = match.group(1).split()
        language = info[0].lower() if info else ""
        line = text[: match.start()].count("\n") + 1
        found.append(Block(path, line, language, "norun" in info[1:], match.group(2)))
    return found


def all_blocks() -> list[Block]:
    return [b for path in doc_files() for b in blocks(path)]


@dataclass(frozen=True)
class Command:
    """One command line of a bash block (``&&`` chains split), as argv."""

    block: Block
    line: int
    argv: list[str]

    @property
    def where(self) -> str:
        return f"{self.block.file.relative_to(ROOT)}:{self.line}"


def commands(block: Block) -> list[Command]:
    """The commands a bash block runs (prompted lines and comments left out)."""
    out = []
    joined = block.text.replace("\\\n", " ")
    for offset, raw in enumerate(joined.splitlines()):
        if not raw.strip() or raw.lstrip().startswith("#") or _PROMPT.match(raw):
            continue
        words = shlex.split(raw, comments=True)
        part: list[str] = []
        for word in [*words, "&&"]:
            if word in ("&&", ";", "||"):
                if part:
                    out.append(Command(block, block.line + 1 + offset, part))
                part = []
            else:
                part.append(word)
    return out
