"""Starting loads only what starting needs: the base layer, ``umbra --help`` and ``umbra check``
import no numeric, vision, web, 3-D or network stack that only a running module uses (those are
imported where they are used: in ``start()``, in the function that needs them).

Each case is a fresh interpreter; ``-X importtime`` names every module it imported, whatever way
the process ends (the CLI leaves through ``os._exit``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: Stacks only a running module needs (top-level package names).
NUMERIC_AND_VISION = {"scipy", "cv2", "matplotlib", "skimage", "PIL", "ruckig", "toppra"}
WEB_3D_AND_NETWORK = {"zenoh", "fastapi", "uvicorn", "starlette", "websockets", "viser", "mcap"}


def _imported(*args: str) -> tuple[set[str], subprocess.CompletedProcess[str]]:
    """Top-level names of the packages a fresh ``python -X importtime ARGS`` imported."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    names = {
        line.rsplit("|", 1)[-1].strip().split(".")[0]
        for line in done.stderr.splitlines()
        if line.startswith("import time:")
    }
    return names, done


def test_the_base_layer_imports_no_numeric_vision_or_network_stack() -> None:
    names, done = _imported(
        "-c",
        "import umbra.connectors, umbra.connectors.messages, umbra.connectors.frames\n"
        "from umbra.connectors import FrameTree, Module, Parameters, param\n"
        "print(FrameTree().names, Module.__name__)",
    )
    assert done.returncode == 0 and done.stdout.strip() == "set() Module", done.stderr[-2000:]
    assert {"umbra", "numpy", "pydantic"} <= names  # the probe sees what was imported
    assert names & (NUMERIC_AND_VISION | WEB_3D_AND_NETWORK) == set()


def test_checking_the_pickup_graph_loads_its_module_types_but_not_what_they_run() -> None:
    names, done = _imported("-m", "umbra.runtime.cli.main", "check", "graphs/tool_pickup.yaml")
    assert done.returncode == 0 and ": ok: graph `tool_pickup`" in done.stdout, done.stderr[-3000:]
    assert names & (NUMERIC_AND_VISION | WEB_3D_AND_NETWORK) == set()


def test_help_runs_no_command_and_imports_no_stack() -> None:
    """``umbra --help`` reads each command's declared NAME and HELP from its source: no command
    module is run, so neither numpy nor pydantic nor any stack a command uses is loaded."""
    names, done = _imported("-m", "umbra.runtime.cli.main", "--help")
    assert done.returncode == 0 and "usage: umbra" in done.stdout, done.stderr[-2000:]
    assert names & (NUMERIC_AND_VISION | WEB_3D_AND_NETWORK | {"numpy", "pydantic"}) == set()
    assert "\n    sketch " in done.stdout and "\n    run " in done.stdout, done.stdout
