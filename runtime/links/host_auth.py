"""Credentials for processes started by hand on one host: derived from a per-user secret.

``umbra run GRAPH --process NAME`` started by hand (not by the launcher) on this host, without
``--insecure`` and without a zenoh configuration that authenticates on its own (TLS, a password):
every process of the graph reads one secret of this user, kept in a private folder, and derives
from it what the launcher hands its children (``umbra.runtime.links.auth``):

* a password per process, and the dictionary of all of them: zenoh's ``usrpwd`` authentication
  refuses a session that cannot show one, so a stranger on this host cannot even connect;
* a zenoh id per process, by which a process that connects knows the one it connected to (that
  side of a link shows no password: ``usrpwd`` goes one way);
* the access-control rules derived from the graph (``umbra.runtime.links.acl``): each process
  publishes only its outputs, subscribes only to its inputs, declares only its own liveliness token;
* an observer password (user ``observer@umbra``): ``umbra topics``, ``echo`` and ``hz`` of this
  user join the graph with it, allowed to read every output key and the liveliness tokens and
  nothing else (``umbra.runtime.links.acl.Observer``).

The folder is ``$XDG_RUNTIME_DIR/umbra/`` (emptied when the user logs out) or else
``~/.cache/umbra/``, mode 0700; the secret is one file per graph name and key prefix, mode 0600,
made by whichever process starts first (written under another name, then published with
``link``, which fails when the file exists: it is made once, atomically, and never seen half
written) and read by the others. A folder or file that another user owns or that others may
read is refused (exit 2): its secret would be no secret. Removing the file changes every
credential of the graph at its next start.

Processes of another user (or ``sudo``) or of another host do not share the secret: they cannot
link. Across hosts use ``umbra keys`` (mutual TLS); ``--insecure`` turns all of this off.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import os
import secrets
import stat
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from umbra.connectors.errors import UserError
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import OBSERVER_USER, local_observer, zenoh_acl
from umbra.runtime.links.auth import credentials, dictionary_text, write_private

#: Bytes of the secret (written as hex digits).
SECRET_BYTES = 32
#: Hex digits of a derived password.
PASSWORD_HEX = 48
FIX = "remove it (a new secret is made at the next start) or run with --insecure"


def secret_folder(env: Mapping[str, str] = os.environ) -> Path:
    """``$XDG_RUNTIME_DIR/umbra`` when that variable names an absolute folder, else
    ``~/.cache/umbra``."""
    runtime = env.get("XDG_RUNTIME_DIR", "")
    if runtime and Path(runtime).is_absolute() and Path(runtime).is_dir():
        return Path(runtime) / "umbra"
    return Path.home() / ".cache" / "umbra"


def secret_name(graph: str, prefix: str) -> str:
    """File name of the secret of graph ``graph`` with key prefix ``prefix``."""
    digest = hashlib.sha256(f"{graph}\0{prefix}".encode()).hexdigest()[:16]
    safe = "".join(c if c.isalnum() or c in "_-." else "_" for c in graph)[:64]
    return f"links-{safe}-{digest}"


def _private(path: Path, st: os.stat_result, kind: str, want: int) -> None:
    """UserError unless ``path`` (``st``: its lstat) is a ``kind`` of this user that nobody
    else may read, write or enter."""
    is_kind = stat.S_ISDIR if kind == "folder" else stat.S_ISREG
    if not is_kind(st.st_mode):
        raise UserError(
            f"{path}: error: expected the link secret {kind} (not a symbolic link or anything "
            f"else), found something else; {FIX}"
        )
    uid = os.geteuid()
    if st.st_uid != uid:
        raise UserError(
            f"{path}: error: the link secret {kind} must belong to you (uid {uid}), found "
            f"uid {st.st_uid}: whoever owns it knows the secret; {FIX}"
        )
    mode = stat.S_IMODE(st.st_mode)
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise UserError(
            f"{path}: error: the link secret {kind} must be private (mode {want:04o}), found "
            f"mode {mode:04o}: others may read it; {FIX}"
        )


def private_folder(folder: Path) -> Path:
    """``folder``, made mode 0700 when missing; UserError when it is not private to this user."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    with contextlib.suppress(FileExistsError):
        folder.mkdir(mode=0o700)
    _private(folder, folder.lstat(), "folder", 0o700)
    return folder


def _create(path: Path) -> None:
    """Write a new secret at ``path`` unless one is there: under a temporary name (O_EXCL),
    then published by ``link``, which fails when another process published one first."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".new-")  # O_EXCL, mode 0600
    try:
        with os.fdopen(fd, "w") as f:
            f.write(secrets.token_hex(SECRET_BYTES) + "\n")
            f.flush()
            os.fsync(f.fileno())
        with contextlib.suppress(FileExistsError):
            os.link(tmp, path)
    finally:
        os.unlink(tmp)


def _read(path: Path) -> bytes:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError as exc:
        raise UserError(f"{path}: error: cannot read the link secret: {exc}; {FIX}") from None
    with os.fdopen(fd, "rb") as f:
        _private(path, os.fstat(f.fileno()), "file", 0o600)
        text = f.read(4 * SECRET_BYTES).strip()
    try:
        secret = bytes.fromhex(text.decode("ascii"))
    except (UnicodeDecodeError, ValueError):
        secret = b""
    if len(secret) != SECRET_BYTES:
        raise UserError(
            f"{path}: error: expected a link secret of {2 * SECRET_BYTES} hex digits, found "
            f"{len(text)} bytes of something else; {FIX}"
        )
    return secret


def load_secret(graph: str, prefix: str, folder: Path | None = None) -> tuple[bytes, Path]:
    """The secret of graph ``graph`` with key prefix ``prefix`` and its file (made when there is
    none yet); UserError when the folder or the file is not private to this user."""
    where = folder or secret_folder()
    try:
        path = private_folder(where) / secret_name(graph, prefix)
        try:
            path.lstat()
        except FileNotFoundError:
            _create(path)
    except OSError as exc:  # a folder this user cannot write, a full disk...
        raise UserError(
            f"{where}: error: cannot make the link secret there: {exc}; set XDG_RUNTIME_DIR "
            f"to a folder of yours, or run with --insecure"
        ) from None
    return _read(path), path


def _derive(secret: bytes, *parts: str) -> bytes:
    return hmac.new(secret, "\0".join(parts).encode(), hashlib.sha256).digest()


@dataclass(frozen=True)
class HostSecret:
    """What every process of one graph derives from the user's secret."""

    secret: bytes

    def password(self, process: str) -> str:
        return _derive(self.secret, "password", process).hex()[:PASSWORD_HEX]

    def zid(self, process: str) -> str:
        """Zenoh id of ``process`` (127 bits, lowercase hex without a leading zero)."""
        bits = int.from_bytes(_derive(self.secret, "zid", process)[:16], "big")
        return format(bits >> 1 | 1 << 126, "x")

    def token_key(self) -> str:
        """Key proving liveliness tokens (``umbra.runtime.links.identity``), as hex."""
        return _derive(self.secret, "token").hex()

    def subject(self, process: str) -> list[dict[str, list[str]]]:
        """Zenoh subjects of ``process``: by user name when it connected to us (it showed its
        password), by zenoh id when we connected to it."""
        return [{"usernames": [process]}, {"zids": [self.zid(process)]}]


def host_credentials(plan: GraphPlan, process: str, folder: Path | None = None) -> dict[str, Any]:
    """Credentials of ``process`` of ``plan`` in the form ``umbra.runtime.links.auth.load_auth``
    gives (plus ``secret_file``, and ``observer``: the observer's user name and password);
    UserError when the secret's folder or file is not private."""
    secret, file = load_secret(plan.spec.name, plan.key_prefix, folder)
    host = HostSecret(secret)
    passwords = {p: host.password(p) for p in [*plan.populated_processes, OBSERVER_USER]}
    dictionary = file.with_name(file.name + ".dict")
    try:
        write_private(dictionary, dictionary_text(passwords))
    except OSError as exc:
        raise UserError(f"{dictionary}: error: cannot write the link passwords: {exc}") from None
    acl = zenoh_acl(plan, host.subject, [local_observer(plan)])
    auth = credentials(process, passwords, dictionary, host.zid(process), host.token_key(), acl)
    return {**auth, "secret_file": str(file)}
