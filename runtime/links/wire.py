"""What a sample on a link says about itself to any zenoh client: its zenoh encoding, and who may
be sent a frame-pool descriptor instead of the sample's bytes (``docs/wire-format.md``).

Encoding: every put names its format and message type, ``application/x-umbra;v=V;type=T``:
``V`` is the envelope version of the payload (3 compact, 2 framed, 1 general:
``umbra.connectors.codec``), ``T`` the message type's name. A frame-pool descriptor, which only the
graph's processes on this host can read, says ``application/x-umbra-pool;type=T``.

Pool hand-off: a descriptor goes out only while every session connected to the publishing one is
a process of the graph whose liveliness token proves it (``umbra.runtime.links.identity``) and names
a marker file in this host's ``/dev/shm`` owned by this user
(``umbra.runtime.links.pool.marker_pid``). Zenoh sends a put to every matching subscriber of every
connected session, so a single other session — an observer, a recorder, a third-party client, a
router that may forward to anyone — makes the producer send the sample's bytes instead: a subscriber
that is not one of our processes always gets bytes it can decode.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import zenoh

#: MIME type of a sample's bytes (``docs/wire-format.md``).
MEDIA_TYPE = "application/x-umbra"
#: MIME type of a frame-pool descriptor (only the graph's processes on one host read it).
POOL_MEDIA_TYPE = "application/x-umbra-pool"


def encoding_text(type_name: str, version: int) -> str:
    """``application/x-umbra;v=VERSION;type=TYPE``."""
    return f"{MEDIA_TYPE};v={version};type={type_name}"


def sample_encoding(type_name: str, version: int) -> zenoh.Encoding:
    """The zenoh encoding of a sample of type ``type_name`` in envelope ``version``."""
    encoding: zenoh.Encoding = zenoh.Encoding(encoding_text(type_name, version))
    return encoding


def pool_encoding(type_name: str) -> zenoh.Encoding:
    """The zenoh encoding of a frame-pool descriptor of a ``type_name`` sample."""
    encoding: zenoh.Encoding = zenoh.Encoding(f"{POOL_MEDIA_TYPE};type={type_name}")
    return encoding


def parse_encoding(text: str) -> tuple[str, int, str] | None:
    """``(media type, version, type name)`` of an encoding string (version 0 when it names
    none); None when it is not one of ours."""
    media, *params = (part.strip() for part in text.split(";"))
    if media not in (MEDIA_TYPE, POOL_MEDIA_TYPE):
        return None
    fields = dict(p.partition("=")[::2] for p in params)
    try:
        version = int(fields.get("v", "0"))
    except ValueError:
        return None
    return media, version, fields.get("type", "")


def only_graph_peers(
    session: zenoh.Session, proven_sessions: Callable[[], Iterable[str]]
) -> Callable[[], bool]:
    """A check (a few microseconds) that every session connected to ``session`` is one of
    ``proven_sessions()`` (zenoh ids of the graph's processes whose tokens are proven): True
    when a pool descriptor reaches no one else."""
    info = session.info

    def check() -> bool:
        proven = set(proven_sessions())
        return all(str(transport.zid) in proven for transport in info.transports())

    return check
