"""Zenoh links between the processes of a graph.

``config`` builds safe zenoh configurations (peer mode, scouting off, explicit endpoints),
``session`` opens them, ``transport`` is the :class:`umbra.runtime.links_api.LinkTransport` over
zenoh (publishers, subscribers, liveliness, counters), ``shm`` puts large samples in shared memory
and ``process`` runs one process of a split graph with its links.

Trust: ``identity`` (who produced a sample: the producer's live session), ``bounds`` (the largest
sample a link accepts), ``acl`` (zenoh access rules derived from the graph), ``auth`` (the
launcher's per-run credentials), ``tls`` (``umbra keys``: CA, certificates, per-process
configurations), ``exposure`` (no plain-text endpoint beyond loopback unless ``--insecure``),
``shm_sweep`` (shared memory of a dead process removed at once).
"""

from umbra.runtime.links.config import Endpoints, build_config, free_loopback_ports, loopback_mesh
from umbra.runtime.links.session import open_session
from umbra.runtime.links.transport import ZenohTransport, alive_key

__all__ = [
    "Endpoints",
    "ZenohTransport",
    "alive_key",
    "build_config",
    "free_loopback_ports",
    "loopback_mesh",
    "open_session",
]
