"""What the distribution installs: ONE top-level package, ``umbra``, whose subpackages are the
layout's folders (``connectors/`` -> ``umbra.connectors``, ``modules/`` -> ``umbra.modules``,
``runtime/`` -> ``umbra.runtime``), so no other distribution's top-level names can collide with
ours. Everything else is in ``pyproject.toml``; ``setup.py`` only computes what
``[tool.setuptools.packages.find]`` cannot: found packages under a prefix."""

from setuptools import find_packages, setup

FOLDERS = ("connectors", "modules", "runtime")  # each becomes umbra.<folder>

found = find_packages(include=[f"{top}*" for top in FOLDERS] + ["umbra"])
setup(
    packages=[p if p == "umbra" else f"umbra.{p}" for p in found],
    package_dir={"umbra": "umbra", **{f"umbra.{top}": top for top in FOLDERS}},
)
