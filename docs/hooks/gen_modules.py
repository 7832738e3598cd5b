"""The module reference, generated from the declarations: ``umbra describe`` of every module type
the ``umbra.modules`` entry points register (run by the site's build hook, ``generated.py``)."""

from __future__ import annotations

from umbra.runtime.cli.cmd_describe import describe
from umbra.runtime.cli.cmd_modules import first_sentence
from umbra.runtime.registry import Registry

PAGE = "reference/modules.md"


def render() -> str:
    """The page: a table of every type with its first sentence, then each type's description."""
    registry = Registry()
    names = registry.names()
    out = [
        "# Module reference",
        "",
        "Every module type installed with umbra, as `umbra describe TYPE` prints it: ports "
        "(type, frame, joints, trigger, optional), parameters (type, default, unit, bounds, "
        "`tunable` or `safety`). This page is generated from the modules' declarations when "
        "the site is built; the declarations are the only place the ports and parameters are "
        "written.",
        "",
        "| type | does |",
        "| --- | --- |",
    ]
    for name in names:
        cls = registry.require(name)
        sentence = first_sentence(cls.__doc__ or "").replace("|", "\\|")
        out.append(f"| [{name}](#{_anchor(name)}) | {sentence} |")
    for name in names:
        out += [
            "",
            f"## {name} {{#{_anchor(name)}}}",
            "",
            "```text",
            describe(registry.require(name)),
            "```",
        ]
    return "\n".join(out) + "\n"


def _anchor(name: str) -> str:
    """A heading id for a type name (``REG_VEL`` -> ``type-reg_vel``)."""
    return "type-" + name.lower()
