"""A process that ends keeps its links open until its consumers have read its ends of stream.

A process that stops marks the end of each output stream (a ``delete`` on its key), then closes
its session. Closing while a busy consumer has not yet read what was sent loses it: the kernel
of a consumer whose peer reset the connection drops what it had not read, so a starved page
process missed the judge's verdict sent 0.4 s before the judge ended. So each consumer, once
it has the ends of every stream it takes from a producer, says so with a liveliness token:

``P/_alive/<consumer>/_ended/<producer>/<producer session>/<proof>``

under its own identity (the access rules let a process declare tokens only under
``P/_alive/<itself>/``; ``proof`` signs the chunks as ``umbra.runtime.links.identity`` signs a
process's token). The producer closes once every consumer process of its outputs has said so
for its session, or is gone, or ``END_ACK_S`` has passed (a frozen consumer holds nothing
longer than that). A token that names another session of the producer (an older run of it)
counts for nothing; a forged one can at most end the wait early, which is where it was before.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import zenoh

from umbra.runtime.links.identity import ALIVE, sign

#: Longest wait for the consumers' word at close [s] when the process ended normally (on its own,
#: or told to ``finish``: with the finish's own wait, within the launcher's grace for it).
END_ACK_S = 5.0
#: Longest wait when the run failed or was interrupted: well below the launcher's grace for a
#: process told to ``abort`` (``umbra.runtime.launcher.STOP_GRACE``), so it never earns a SIGTERM.
END_ACK_ABORTED_S = 2.0
#: Chunk that marks an end-of-stream token under a process's own ``_alive`` space.
ENDED = "_ended"


def ended_key(prefix: str, consumer: str, producer: str, session: str, proof: str) -> str:
    """Key of ``consumer``'s token saying it read the ends of ``producer``'s ``session``."""
    return f"{prefix}/{ALIVE}/{consumer}/{ENDED}/{producer}/{session}/{proof}"


def ended_proof(token_key: str | None, consumer: str, producer: str, session: str) -> str:
    """The proof of such a token (``identity.sign``, with ``ENDED/producer`` as the marker)."""
    return sign(token_key, consumer, f"{ENDED}/{producer}", session)


class EndAcks:
    """Both sides of the end-of-stream word of process ``process`` over ``session``."""

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        process: str,
        own_session: str,
        token_key: str | None,
        log: logging.Logger,
    ) -> None:
        self._session, self._prefix, self._process = session, prefix, process
        self._own_session, self._token_key, self._log = own_session, token_key, log
        self._said: set[tuple[str, str]] = set()  #: (producer, its session) acknowledged
        self._tokens: list[zenoh.LivelinessToken] = []
        self._heard: set[str] = set()  #: consumers that acknowledged this process's ends
        #: the consumers a close waits for now (empty when it waits for none)
        self.waiting: frozenset[str] = frozenset()
        self._changed = threading.Condition()
        self._closed = False
        self._sub = session.liveliness().declare_subscriber(
            f"{prefix}/{ALIVE}/*/{ENDED}/{process}/{own_session}/*", self._on_token, history=True
        )

    # -- consumer side --------------------------------------------------------------------------
    def acknowledge(self, producer: str, session: str) -> None:
        """Say that every stream of ``producer``'s ``session`` this process takes has ended
        (once per session; the token is declared on a thread of its own, never on zenoh's)."""
        with self._changed:
            if (producer, session) in self._said or self._closed:
                return
            self._said.add((producer, session))
        proof = ended_proof(self._token_key, self._process, producer, session)
        key = ended_key(self._prefix, self._process, producer, session, proof)
        threading.Thread(
            target=self._declare, args=(key,), name="umbra-end-ack", daemon=True
        ).start()

    def _declare(self, key: str) -> None:
        try:
            token = self._session.liveliness().declare_token(key)
        except Exception as exc:  # the session is closing: the producer stops waiting anyway
            self._log.debug("end-of-stream token %s: %s", key, exc)
            return
        with self._changed:
            self._tokens.append(token)

    # -- producer side --------------------------------------------------------------------------
    def _on_token(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return  # heard once is enough: the consumer may close at once
        parts = str(sample.key_expr).split("/")
        if len(parts) < 6 or parts[-6] != ALIVE or parts[-4] != ENDED:
            return
        consumer, proof = parts[-5], parts[-1]
        if proof != ended_proof(self._token_key, consumer, self._process, self._own_session):
            return
        with self._changed:
            self._heard.add(consumer)
            self._changed.notify_all()

    def heard(self) -> set[str]:
        """The consumers that said they read this process's ends of stream."""
        with self._changed:
            return set(self._heard)

    def wait(
        self, consumers: set[str], alive: Callable[[], set[str]], timeout_s: float = END_ACK_S
    ) -> set[str]:
        """Wait until every process of ``consumers`` has acknowledged or is not in ``alive()``,
        at most ``timeout_s``; the consumers still silent then (empty: none)."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            try:
                while True:
                    silent = consumers - self._heard - (consumers - alive())
                    self.waiting = frozenset(silent)
                    left = deadline - time.monotonic()
                    if not silent or left <= 0:
                        return silent
                    self._changed.wait(min(left, 0.02))  # a consumer may go without a token
            finally:
                self.waiting = frozenset()

    def close(self) -> None:
        """Withdraw this process's tokens and stop listening (before the session closes)."""
        with self._changed:
            self._closed = True
            tokens, self._tokens = self._tokens, []
        for token in tokens:
            try:
                token.undeclare()
            except Exception as exc:
                self._log.debug("end-of-stream token undeclare: %s", exc)
        try:
            self._sub.undeclare()
        except Exception as exc:
            self._log.debug("end-of-stream subscriber undeclare: %s", exc)
