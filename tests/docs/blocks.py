"""The code blocks of README.md and docs/*.md, and the commands in their shell blocks.

Convention for the documentation (checked by ``test_docs_blocks.py``):

* Every fenced block names its language: ``bash``, ``python``, ``yaml``, ``toml``, ``json``,
  ``json5`` are run or checked; ``text`` is shown and never run (output, file layouts).
* A block shown but not run (it needs files or hosts a reader must bring, or it is a fragment of
  a larger file) says so after its language: ```` ```python norun ````. Use it sparingly: every
  block a user would run as it stands must run.
* A block that is a whole file a reader copies names it (any language):
  ```` ```python file=affine-demo/affine.py ````. The tests write a page's files into a fresh
  folder before its commands run there; a ``test_*.py`` file is run with pytest; a graph file
  is checked (``yaml file=X fails``: a graph shown for the errors ``umbra check`` reports).
* In a ``bash`` block, a line with a host prompt (``robot$ umbra run ...``) is shown for another
  machine and not run; ``# ...`` starts a comment; every other line is a command that is run. A
  command ending in ``&`` runs in the background while the block's later commands run (and is
  stopped at the block's end); a comment ``# exits N`` says the exit status it ends with.
* A ``text output`` block right after a ``bash`` block is what its last command prints: every
  line of it must be in that command's output.
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
_EXITS = re.compile(r"#\s*exits\s+(\d+)\b")


@dataclass(frozen=True)
class Block:
    """One fenced block: where it is, its language, whether it is run, its text."""

    file: Path
    line: int
    language: str
    norun: bool
    text: str
    options: tuple[str, ...] = ()

    @property
    def where(self) -> str:
        return f"{self.file.relative_to(ROOT)}:{self.line}"

    @property
    def runs(self) -> bool:
        return self.language in RUN_LANGUAGES and not self.norun

    @property
    def file_name(self) -> str | None:
        """The file this block is (``file=NAME``), relative to the reader's folder."""
        names = [o.removeprefix("file=") for o in self.options if o.startswith("file=")]
        return names[0] if names else None

    @property
    def fails(self) -> bool:
        """A graph shown for the errors ``umbra check`` reports on it."""
        return "fails" in self.options

    @property
    def is_output(self) -> bool:
        """What the ``bash`` block before it prints."""
        return self.language == "text" and "output" in self.options


def doc_files() -> list[Path]:
    """README.md and every page of the guide (``docs/**/*.md``)."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def blocks(path: Path) -> list[Block]:
    text = path.read_text(encoding="utf-8")
    found = []
    for match in _FENCE.finditer(text):
        info = match.group(1).split()
        language = info[0].lower() if info else ""
        line = text[: match.start()].count("\n") + 1
        options = tuple(info[1:])
        found.append(Block(path, line, language, "norun" in options, match.group(2), options))
    return found


def all_blocks() -> list[Block]:
    return [b for path in doc_files() for b in blocks(path)]


@dataclass(frozen=True)
class Command:
    """One command line of a bash block (``&&`` chains split), as argv."""

    block: Block
    line: int
    argv: list[str]
    background: bool = False
    expect: int | None = None  # the exit status a `# exits N` comment says

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
        said = _EXITS.search(raw)
        expect = int(said.group(1)) if said else None
        part: list[str] = []
        for word in [*words, "&&"]:
            if word in ("&&", ";", "||", "&"):
                if part:
                    line = block.line + 1 + offset
                    out.append(Command(block, line, part, word == "&", expect))
                part = []
            else:
                part.append(word)
    return out


def files(path: Path) -> dict[str, Block]:
    """The whole files a page shows (``file=NAME`` blocks), by name."""
    return {b.file_name: b for b in blocks(path) if b.file_name}


def write_files(path: Path, folder: Path) -> list[Path]:
    """Write the page's files into ``folder``, as a reader copies them; returns their paths."""
    written = []
    for name, block in files(path).items():
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(block.text, encoding="utf-8")
        written.append(target)
    return written


def output_after(block: Block) -> Block | None:
    """The ``text output`` block that follows ``block`` in its page, if the next block is one."""
    page = blocks(block.file)
    at = [b.line for b in page].index(block.line)
    nxt = page[at + 1] if at + 1 < len(page) else None
    return nxt if nxt is not None and nxt.is_output else None
