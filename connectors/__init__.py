"""Message types and typed ports: what may be wired to what.

Everything a module author needs::

    from umbra.connectors import Module, Parameters, param, Input, Output, from_param, UserError
    from umbra.connectors.messages import Twist, Image

Each name loads its submodule when first asked for, so that a light one (``umbra.connectors.
errors``, which the command line imports to start) does not load numpy and pydantic with it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from umbra.connectors.errors import UserError as UserError
    from umbra.connectors.frames import FrameTree as FrameTree
    from umbra.connectors.module import Module as Module
    from umbra.connectors.module import ModuleContext as ModuleContext
    from umbra.connectors.params import Parameters as Parameters
    from umbra.connectors.params import ParamProblem as ParamProblem
    from umbra.connectors.params import param as param
    from umbra.connectors.ports import Input as Input
    from umbra.connectors.ports import Output as Output
    from umbra.connectors.ports import Register as Register
    from umbra.connectors.ports import from_param as from_param

#: Each name of the package -> the submodule that defines it.
_HOMES = {
    "FrameTree": "frames",
    "Input": "ports",
    "Module": "module",
    "ModuleContext": "module",
    "Output": "ports",
    "ParamProblem": "params",
    "Parameters": "params",
    "Register": "ports",
    "UserError": "errors",
    "from_param": "ports",
    "param": "params",
}

__all__ = sorted(_HOMES)


def __getattr__(name: str) -> object:
    """``name`` from its submodule, imported now (PEP 562)."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{home}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})
