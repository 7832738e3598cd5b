"""Every registered module type names its own ``Params`` as ``Module``'s argument, so the type
checker gives its ``self.params`` that class (``Module["Gain.Params"]``): one declaration, the
``Params`` class, and nothing that can drift from it."""

from __future__ import annotations

import typing

import pytest

from umbra.connectors.module import Module
from umbra.runtime.registry import Registry

REGISTRY = Registry()


def _params_argument(cls: type[Module]) -> object:
    """What ``cls`` gives ``Module`` as its argument, resolved (a forward reference evaluated in
    the namespace of the class's module, with the class itself in it)."""
    for klass in cls.__mro__:
        for base in getattr(klass, "__orig_bases__", ()):
            if typing.get_origin(base) is Module:
                (arg,) = typing.get_args(base)
                if isinstance(arg, typing.ForwardRef):
                    names = dict(vars(__import__(klass.__module__, fromlist=["_"])))
                    names[klass.__name__] = klass
                    return eval(arg.__forward_arg__, names)  # our own source
                return arg
    return None


@pytest.mark.parametrize("name", REGISTRY.names())
def test_the_module_names_its_own_params_as_its_base_argument(name: str) -> None:
    cls = REGISTRY.require(name)
    assert _params_argument(cls) is cls.Params, (
        f"{cls.__qualname__} declares {cls.Params.__qualname__} but gives Module "
        f'{_params_argument(cls)!r}: write `class {cls.__name__}(Module["{cls.__name__}.Params"])`'
    )
