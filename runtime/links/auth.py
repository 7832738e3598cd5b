"""Per-run credentials for the processes the launcher starts: only they can open a link.

For each run the launcher makes a private folder (mode 0700) holding a user name and a random
password per process and the dictionary of all of them, each file mode 0600, and hands every child
the path of its own file (``--link-auth FILE``) — never a secret on a command line, where any local
user could read it. Each child's zenoh configuration then carries:

* zenoh's ``usrpwd`` transport authentication: a session that cannot show one of the run's
  passwords is refused when it opens a link, so a stranger on this host cannot even connect;
* the access-control rules derived from the graph (``umbra.runtime.links.acl``) with the user names
  as subjects: a process may publish only its own outputs and declare only its own liveliness token;
* a key shared by the run's processes that proves their liveliness tokens
  (``umbra.runtime.links.identity``);
* the run's observer password (user ``observer@umbra``, also in the dictionary), which each
  process writes into its run file (``umbra.runtime.links.runs``) for ``umbra topics`` of this user;
  the rules let the observer read every output key and the tokens, nothing else.

Processes started by hand derive the same from a secret of the user
(``umbra.runtime.links.host_auth``).

Cost: the password exchange happens once per link, when it opens; the rules are checked by zenoh
on each message (measured by ``benchmarks/bench_links.py``). The folder is removed when the run
ends.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import stat
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import zenoh

from umbra.connectors.errors import UserError
from umbra.connectors.user_files import read_text
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import (
    OBSERVER_USER,
    TUNER_USER,
    by_username,
    local_observer,
    zenoh_acl,
)

_ZID_RE = re.compile(r"^[0-9a-f]{1,32}$")
_KEY_RE = re.compile(r"^[0-9a-f]{64}$")
#: Largest link credentials file [bytes] (the rules of a graph of many processes fit easily).
MAX_AUTH_BYTES = 4_000_000


class RunCredentials:
    """The private folder of one run's credentials (``close`` removes it).

    usrpwd authentication goes one way — the process that opens a link shows its password to the
    one that listens — so a listening process knows its peers by user name, and a connecting
    process knows the process it connected to (on the port the launcher gave it) by the zenoh id
    the launcher assigned it. Process i of the mesh listens for the processes after it and
    connects to those before it (``umbra.runtime.links.config.loopback_mesh``).
    """

    def __init__(self, plan: GraphPlan, tuner_password: str | None = None) -> None:
        """``tuner_password``: the live server's, when the run is served live (its process
        may then send parameter changes: ``umbra.runtime.links.acl``)."""
        self.folder = Path(tempfile.mkdtemp(prefix="umbra-auth-"))  # mode 0700
        processes = plan.populated_processes
        passwords = {p: secrets.token_hex(24) for p in [*processes, OBSERVER_USER]}
        if tuner_password:
            passwords[TUNER_USER] = tuner_password
        tuner = by_username(TUNER_USER) if tuner_password else None
        observer = local_observer(plan)
        token_key = secrets.token_hex(32)  # proves the run's liveliness tokens
        #: zenoh id of each process (lowercase hex without a leading zero, as zenoh wants it)
        self.zids = {p: format(secrets.randbits(127) | 1 << 126, "x") for p in processes}
        dictionary = self.folder / "dictionary.txt"
        write_private(dictionary, dictionary_text(passwords))
        self.files: dict[str, Path] = {}
        for i, process in enumerate(processes):
            before = set(processes[:i])  # this process connects to them: known by zenoh id

            def subject(other: str, before: set[str] = before) -> dict[str, list[str]]:
                return {"zids": [self.zids[other]]} if other in before else by_username(other)

            path = self.folder / f"{process}.json"
            acl = zenoh_acl(plan, subject, [observer], tuner)
            auth = credentials(process, passwords, dictionary, self.zids[process], token_key, acl)
            auth["tuner"] = bool(tuner_password)  # take parameter changes from the live server
            write_private(path, json.dumps(auth))
            self.files[process] = path

    def close(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def dictionary_text(passwords: Mapping[str, str]) -> str:
    """zenoh's ``usrpwd`` dictionary: one ``user:password`` line per user."""
    return "".join(f"{user}:{password}\n" for user, password in passwords.items())


def credentials(
    process: str,
    passwords: Mapping[str, str],
    dictionary: Path,
    zid: str,
    token_key: str,
    access_control: dict[str, Any],
) -> dict[str, Any]:
    """The credentials of ``process`` in the form :func:`load_auth` reads: its user name and
    password, the dictionary file, its zenoh id, the token key, the graph's access rules and
    the observer's user name and password (``passwords`` holds every user's)."""
    return {
        "user": process,
        "password": passwords[process],
        "dictionary_file": str(dictionary),
        "zid": zid,
        "token_key": token_key,
        "access_control": access_control,
        "observer": {"user": OBSERVER_USER, "password": passwords[OBSERVER_USER]},
    }


def write_private(path: Path, text: str) -> None:
    """Write ``text`` at ``path`` (mode 0600) by replacing it whole: processes starting at once
    may write the same text, and no reader ever sees half of it."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".new-")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def load_auth(path: str) -> dict[str, Any]:
    """The credentials file ``path`` of this process; UserError when it is missing, readable by
    others, or not one."""
    file = Path(path)
    try:
        mode = file.stat().st_mode
    except OSError as exc:
        raise UserError(f"{path}: error: cannot read the link credentials: {exc}") from None
    text = read_text(file, "link credentials file", MAX_AUTH_BYTES)
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise UserError(
            f"{path}: error: link credentials must be private (mode 0600), "
            f"found mode {stat.S_IMODE(mode):04o}"
        )
    try:
        auth: dict[str, Any] = json.loads(text)
        for field in ("user", "password", "dictionary_file"):
            if not isinstance(auth[field], str) or not auth[field]:
                raise ValueError(f"`{field}` must be a non-empty string")
        zid = auth.get("zid")
        if zid is not None and not (isinstance(zid, str) and _ZID_RE.match(zid)):
            raise ValueError("`zid` must be a zenoh id (1 to 32 hex digits)")
        key = auth.get("token_key")
        if key is not None and not (isinstance(key, str) and _KEY_RE.match(key)):
            raise ValueError("`token_key` must be 64 hex digits")
        if not isinstance(auth.get("access_control", {}), dict):
            raise ValueError("`access_control` must be a mapping")
    except (ValueError, KeyError, TypeError) as exc:
        raise UserError(
            f"{path}: error: expected link credentials (user, password, dictionary_file), "
            f"found: {exc}"
        ) from None
    return auth


def apply_auth(cfg: zenoh.Config, auth: dict[str, Any]) -> None:
    """Put ``auth`` (``load_auth``) into ``cfg``: password authentication and the graph's rules."""
    usrpwd = {k: auth[k] for k in ("user", "password", "dictionary_file")}
    try:
        cfg.insert_json5("transport/auth/usrpwd", json.dumps(usrpwd))
        if auth.get("zid"):
            cfg.insert_json5("id", json.dumps(auth["zid"]))
        if auth.get("access_control"):
            cfg.insert_json5("access_control", json.dumps(auth["access_control"]))
    except Exception as exc:  # zenoh refuses a value: the file is not what the launcher wrote
        raise UserError(f"error: link credentials zenoh does not accept: {exc}") from None
