"""The module instances of a graph as checked: a known type, its parameters validated (every
problem at the key or value at fault), its ports resolved from them, its trigger inputs."""

from __future__ import annotations

from typing import Any

import pydantic

from umbra.connectors.params import Parameters, ParamProblem, short_repr
from umbra.runtime.graph.check_report import Report
from umbra.runtime.graph.plan import ModulePlan, PortInfo
from umbra.runtime.graph.spec import ModuleSpec
from umbra.runtime.hints import did_you_mean
from umbra.runtime.registry import Registry


def module_plan(mspec: ModuleSpec, registry: Registry, error: Report) -> ModulePlan | None:
    """``mspec`` checked into a plan, or None (its problems reported) when its type is unknown
    or its parameters invalid."""
    cls = registry.get(mspec.type)
    if cls is None:
        error(mspec.type_loc, registry.missing(mspec.type))
        return None
    params = _params(mspec, cls.Params, error)
    if params is None:
        return None
    problem = params.rate_problem(mspec.rate)
    if problem:
        error(mspec.rate_loc or mspec.loc, f"module `{mspec.name}` ({mspec.type}): {problem}")
    in_decls = cls.input_decls(params)
    inputs = _port_infos(in_decls, params)
    outputs = _port_infos(cls.output_decls(), params)
    triggers = [n for n, d in in_decls.items() if d.trigger]
    if mspec.trigger is not None:
        triggers = []
        for name in mspec.trigger:
            if name not in inputs:
                error(
                    mspec.trigger_loc,
                    f"`trigger` names `{name}`, which is not an input "
                    f"of `{mspec.name}` ({mspec.type})"
                    f"{did_you_mean(name, inputs)}",
                )
            else:
                triggers.append(name)
    return ModulePlan(mspec, cls, params, inputs, outputs, triggers, in_decls)


def _params(mspec: ModuleSpec, params_cls: type[Parameters], error: Report) -> Parameters | None:
    """The validated parameters of ``mspec``, or None with each problem reported where it is."""
    try:
        return params_cls(**mspec.params)
    except pydantic.ValidationError as exc:
        fields = list(params_cls.model_fields)
        for err in exc.errors():
            loc = err.get("loc") or ()
            key = str(loc[0]) if loc else ""
            if err["type"] == "extra_forbidden":
                error(
                    mspec.param_key_loc.get(key, mspec.params_loc),
                    f"unknown parameter `{key}` for {mspec.type} `{mspec.name}`"
                    f"{did_you_mean(key, fields)}",
                )
            elif err["type"] == "missing":
                error(mspec.params_loc, f"{mspec.type} `{mspec.name}` needs parameter `{key}`")
            elif not loc and isinstance(problem := _cause(err), ParamProblem):
                error(
                    mspec.param_val_loc.get(problem.field, mspec.params_loc),
                    f"parameters of `{mspec.name}`: {problem}",
                )
            elif err["type"] == "value_error" and _cause(err) is not None:
                where = ".".join(str(p) for p in loc)  # a validator's own message
                error(
                    mspec.param_val_loc.get(key, mspec.params_loc),
                    f"parameter `{where}` of `{mspec.name}`: {_cause(err)}",
                )
            else:
                where = ".".join(str(p) for p in loc)
                error(
                    mspec.param_val_loc.get(key, mspec.params_loc),
                    f"parameter `{where}` of `{mspec.name}`: {err['msg']}, "
                    f"found {short_repr(err.get('input'))}",
                )
        return None
    except (TypeError, ValueError) as exc:  # a module's own validator
        error(mspec.params_loc, f"parameters of `{mspec.name}`: {exc}")
        return None


def _cause(err: Any) -> BaseException | None:
    """The exception a validator raised, kept by pydantic in the error's context."""
    ctx = err.get("ctx") or {}
    return ctx.get("error") if isinstance(ctx.get("error"), BaseException) else None


def _port_infos(decls: dict[str, Any], params: Any) -> dict[str, PortInfo]:
    """Declared ports with their frame and joint names resolved from ``params``."""
    return {
        name: PortInfo(name, d.msg_type, d.resolve_frame(params), d.resolve_joints(params))
        for name, d in decls.items()
    }
