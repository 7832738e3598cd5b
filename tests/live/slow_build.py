"""A module that is slow to build (as one loading a model or opening a device is), for the tests of
runs whose processes come up late. Registered in the test's child processes the way a third-party
package registers its modules: through an ``umbra.modules`` entry point (:func:`plugin_env`)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from umbra.connectors import Input, Module, ModuleContext, Parameters, param
from umbra.connectors.messages import Scalar

REPO = Path(__file__).resolve().parents[2]


class SlowBuild(Module):
    """Takes ``build_s`` seconds to build, then reads its input and does nothing with it."""

    TYPE = "SlowBuild"

    class Params(Parameters):
        build_s: float = param(0.0, "time its construction takes", unit="s", ge=0)

    input = Input(Scalar, trigger=True, doc="any scalar")

    def __init__(self, name: str, params: Parameters, context: ModuleContext | None = None) -> None:
        super().__init__(name, params, context)
        time.sleep(self.params.build_s)

    def step(self, now: float) -> None:
        self.input.get(now)


def plugin_env(root: Path, runtime_dir: Path) -> dict[str, str]:
    """An environment in which child processes see :class:`SlowBuild` (a dist-info under ``root``
    with its entry point) and keep their run files and secrets in ``runtime_dir`` (a user folder
    of the test's own: runs of other tests on this host are not seen)."""
    dist = root / "umbra_slow_build-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: umbra-slow-build\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[umbra.modules]\nSlowBuild = tests.live.slow_build:SlowBuild\n"
    )
    runtime_dir.mkdir(parents=True, exist_ok=True)
    runtime_dir.chmod(0o700)
    path = os.pathsep.join([str(root), str(REPO), os.environ.get("PYTHONPATH", "")])
    return dict(
        os.environ,
        PYTHONPATH=path.rstrip(os.pathsep),
        PYTHONUNBUFFERED="1",
        XDG_RUNTIME_DIR=str(runtime_dir),
    )
