"""Message types and typed ports: what may be wired to what.

Everything a module author needs::

    from connectors import Module, Parameters, param, Input, Output, from_param, UserError
    from connectors.messages import Twist, Image
"""

from connectors.errors import UserError
from connectors.frames import FrameTree
from connectors.module import Module, ModuleContext
from connectors.params import Parameters, ParamProblem, param
from connectors.ports import Input, Output, Register, from_param

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
