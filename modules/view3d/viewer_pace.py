"""The 3-D view's pace: the page rule of every page server (at most
:data:`~umbra.connectors.limits.MAX_PAGE_IN_FLIGHT` updates on their way to a page that has not
said it applied them) on viser, whose page says nothing of the kind by itself.

viser sends as fast as the socket takes it, and a browser's socket reads on in a worker while
its page is busy, so a browser that draws slower than the updates come (a loaded machine,
software WebGL) piles them up in its page and applies a backlog: the arm and the video late by
seconds, and the run's end behind them (measured on one loaded core: the end shown 6-8 s late,
with about forty updates applied in one go before it).

After each update :class:`BrowserPace` asks every browser a question that it answers only when
it applies its queued messages (a read of its local storage, handled in the same turn as the
scene's messages). An update is answered once every browser has answered its question, or
after :data:`~umbra.connectors.limits.PAGE_ACK_TIMEOUT_S` per browser that does not (a browser
that never answers slows the others, never stops them). A turn held back loses nothing: the
sender keeps the newest samples and sends them next.
"""

from __future__ import annotations

import queue
import threading

import viser

from umbra.connectors.limits import MAX_PAGE_IN_FLIGHT, PAGE_ACK_TIMEOUT_S

#: The local-storage key the question reads (nothing writes it: the answer is "none").
PACE_KEY = "umbra-pace"


class BrowserPace:
    """Holds back the updates of ``server`` while :data:`MAX_PAGE_IN_FLIGHT` are unanswered.

    ``ready()`` says whether the next update may go; ``sent()`` says that one went (the pace's
    thread then asks each browser). ``answers``, ``late``: the browsers' answers that came, and
    questions that waited ``timeout_s`` in vain."""

    def __init__(self, server: viser.ViserServer, timeout_s: float = PAGE_ACK_TIMEOUT_S) -> None:
        self._server = server
        self._timeout_s = timeout_s
        self._lock = threading.Lock()
        self._unanswered = 0  #: updates sent and not yet answered (under the lock)
        self._questions: queue.SimpleQueue[bool] = queue.SimpleQueue()  #: one per update
        self._stopping = threading.Event()
        self.answers = 0
        self.late = 0
        self._thread = threading.Thread(target=self._ask, name="view3d-pace", daemon=True)
        self._thread.start()

    def ready(self) -> bool:
        """Whether the next update may go (fewer than the limit on their way)."""
        with self._lock:
            return self._unanswered < MAX_PAGE_IN_FLIGHT

    def sent(self) -> None:
        """An update has just been queued to the browsers: it counts until they have applied
        it."""
        with self._lock:
            self._unanswered += 1
        self._server.flush()  # the update out now, before the question (a browser's own queue)
        self._questions.put(True)

    def stop(self) -> None:
        """Stop asking (the server stops next)."""
        self._stopping.set()
        self._questions.put(False)

    def _ask(self) -> None:
        while self._questions.get() and not self._stopping.is_set():
            for client in list(self._server.get_clients().values()):
                if self._stopping.is_set():
                    return
                try:
                    client.local_storage.get_item(PACE_KEY, timeout=self._timeout_s)
                    self.answers += 1
                except TimeoutError:
                    self.late += 1
                except RuntimeError:
                    pass  # gone, or its storage refused: either way nothing is queued for it
            with self._lock:
                self._unanswered -= 1
