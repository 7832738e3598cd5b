"""What the distribution installs: ONE top-level package, ``umbra``, whose subpackages are the
layout's folders (``connectors/`` -> ``umbra.connectors``, ``modules/`` -> ``umbra.modules``,
``runtime/`` -> ``umbra.runtime``), so no other distribution's top-level names can collide with
ours; plus ``umbra-smart-legacy-names.pth``, which keeps the old names importable for a
deprecation period (``umbra/legacy_names.py``). Everything else is in ``pyproject.toml``;
``setup.py`` only computes what ``[tool.setuptools.packages.find]`` cannot: found packages under
a prefix."""

from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

FOLDERS = ("connectors", "modules", "runtime")  # each becomes umbra.<folder>
PTH = "umbra-smart-legacy-names.pth"


class BuildPyWithPth(build_py):
    """``build_py`` that also puts the .pth file at the top of what is installed (a wheel's
    purelib root is site-packages)."""

    def run(self) -> None:
        super().run()
        Path(self.build_lib, PTH).write_text("import umbra\n")

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        return [*super().get_outputs(include_bytecode), str(Path(self.build_lib, PTH))]


found = find_packages(include=[f"{top}*" for top in FOLDERS] + ["umbra"])
setup(
    packages=[p if p == "umbra" else f"umbra.{p}" for p in found],
    package_dir={"umbra": "umbra", **{f"umbra.{top}": top for top in FOLDERS}},
    cmdclass={"build_py": BuildPyWithPth},
)
