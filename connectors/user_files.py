"""Reading a user's file without trusting it: a regular file, of bounded size, as text.

``/dev/zero``, a FIFO, a directory or a 10 GB file named where a DH table or a calibration file is
expected are refused before anything is read (a FIFO is opened without blocking). Text is UTF-8
(a byte-order mark is allowed, and UTF-16/32 files that start with one are decoded); anything else
is an error naming the line of the first bad byte. Every failure is a :class:`UserError` reading
``FILE: error: ...`` or ``FILE:LINE: error: ...``.

Files a graph *writes* (a recording, a plot, a video, a scene) are named relative to the run
folder and stay inside it: :func:`run_file_problem` refuses absolute paths and ``..``. A path the
user types on the command line (``umbra run G --set rec.path=/data/pick.mcap``) arrives as
:class:`OnCommandLine` and may name any place: the person running the graph chose it, not the file.
"""

from __future__ import annotations

import codecs
import os
import stat
from pathlib import Path, PurePosixPath

from umbra.connectors.errors import UserError
from umbra.connectors.limits import MAX_TEXT_FILE_BYTES as MAX_TEXT_BYTES

_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32"),
    (codecs.BOM_UTF32_BE, "utf-32"),
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)


def read_bytes(path: str | Path, what: str, max_bytes: int = MAX_TEXT_BYTES) -> bytes:
    """The bytes of regular file ``path`` (``what`` names it in errors: "DH file")."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise UserError(f"{path}: error: cannot read {what}: no such file") from None
    except OSError as exc:
        raise UserError(f"{path}: error: cannot read {what}: {exc.strerror}") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise UserError(f"{path}: error: is a directory, expected a {what}")
        if not stat.S_ISREG(info.st_mode):
            raise UserError(
                f"{path}: error: not a regular file ({_kind(info.st_mode)}), expected a {what}"
            )
        if info.st_size > max_bytes:
            raise UserError(
                f"{path}: error: {what} is {info.st_size} bytes, more than the {max_bytes} "
                "this reader accepts"
            )
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise UserError(f"{path}: error: cannot read {what}: {exc.strerror}") from None
    finally:
        os.close(fd)
    if len(data) > max_bytes:  # grew while being read
        raise UserError(f"{path}: error: {what} is more than {max_bytes} bytes")
    return data


def decode_text(data: bytes, source: str) -> str:
    """``data`` as text: UTF-8, or UTF-8/16/32 with a byte-order mark; NUL bytes are refused."""
    encoding = next((enc for bom, enc in _BOMS if data.startswith(bom)), "utf-8")
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise UserError(
            f"{source}:{line}: error: not {encoding.upper().removesuffix('-SIG')} text "
            f"(byte {exc.start} is 0x{data[exc.start]:02x}); save the file as UTF-8"
        ) from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise UserError(f"{source}:{line}: error: not a text file (contains a NUL byte)")
    return text


def read_text(path: str | Path, what: str, max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The text of regular file ``path``, bounded and decoded as :func:`decode_text` says."""
    return decode_text(read_bytes(path, what, max_bytes), str(path))


class OnCommandLine(str):
    """Text the user typed on the command line (a ``--set`` value): a file a module writes may
    lie outside the run folder when the user names it there."""


#: What a refusal of a path outside the run folder tells the user to do instead.
_OUTSIDE_HINT = (
    "files a graph writes stay in the run folder (the --out folder); give a relative path, or "
    "name an outside file on the command line: umbra run GRAPH --set MODULE.PARAM=PATH"
)


def run_file_problem(path: str) -> str:
    """Why ``path`` does not name a file a graph may write; empty when it may. A path inside the
    run folder may; one outside it (absolute, or leaving it by ``..``) only when the user typed
    it on the command line (:class:`OnCommandLine`)."""
    if not path.strip():
        return "is empty"
    if "\x00" in path:
        return "holds a NUL character"
    if isinstance(path, OnCommandLine):
        return ""
    posix = PurePosixPath(path.replace("\\", "/"))
    if posix.is_absolute() or (len(path) > 1 and path[1] == ":"):
        return f"is absolute; {_OUTSIDE_HINT}"
    if ".." in posix.parts:
        return f"leaves the run folder (`..`); {_OUTSIDE_HINT}"
    return ""


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"
