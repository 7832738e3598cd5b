"""Where canopen's annotations are looser than its objects, narrowed once.

`PdoBase.map` is declared `PdoMaps | None`, but `RPDO` and `TPDO` (a node's `rpdo`, `tpdo`)
always set it in their constructor; a node's `id` is declared `int | None` (a node built without
an id takes the object dictionary's, which may have none), but every node here is built with an
id 1..127.
"""

from __future__ import annotations

import canopen
from canopen.pdo import PdoMaps
from canopen.pdo.base import PdoBase


def maps_of(pdo: PdoBase) -> PdoMaps:
    """The PDO maps of a node's `rpdo` or `tpdo` (numbered from 1)."""
    maps = pdo.map
    assert maps is not None, "RPDO and TPDO set their maps in their constructor"
    return maps


def node_id_of(node: canopen.LocalNode | canopen.RemoteNode) -> int:
    """The CANopen node id (1..127) of a node built with one."""
    node_id = node.id
    assert node_id is not None, "every node here is built with its id"
    return node_id
