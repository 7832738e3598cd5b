"""Message types and typed ports: what may be wired to what.

Everything a module author needs::

    from umbra.connectors import Module, Parameters, param, Input, Output, from_param, UserError
    from umbra.connectors.messages import Twist, Image
"""

from umbra.connectors.errors import UserError
from umbra.connectors.frames import FrameTree
from umbra.connectors.module import Module, ModuleContext
from umbra.connectors.params import Parameters, ParamProblem, param
from umbra.connectors.ports import Input, Output, Register, from_param

__all__ = [
    "FrameTree",
    "Input",
    "Module",
    "ModuleContext",
    "Output",
    "ParamProblem",
    "Parameters",
    "Register",
    "UserError",
    "from_param",
    "param",
]
