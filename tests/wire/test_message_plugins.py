"""A package adds message types through the ``umbra.messages`` entry points: every process knows
them by name without the base layer importing the package, beside the base layer's own (the
vocabulary several domains speak, such as a planned path's)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

PLUGIN = '''
import numpy as np
from typing import ClassVar
from umbra.connectors.messages import Message

class WidgetReading(Message, frozen=True, kw_only=True):
    """A third party's message type."""
    FIELD_NOTES: ClassVar[dict[str, str]] = {"level": "m"}
    level: float = 0.0
    trace: np.ndarray = np.zeros(0)
'''

PROBE = """
import json, sys
from umbra.connectors.codec import Codec
from umbra.connectors.messages import message_types, registered_message_types
import numpy as np
before = sorted(m for m in sys.modules if m == "widget_msgs" or m.startswith("umbra.modules"))
types = message_types()
codec = Codec()
sample = types["WidgetReading"](level=2.5, trace=np.arange(3.0), seq=4)
back = codec.decode(codec.encode(sample))
path = codec.decode(codec.encode(types["VcrCommand"](action="play", path_id="p")))
print(json.dumps({
    "before": before,
    "registered": sorted(registered_message_types()),
    "module": types["WidgetReading"].__module__,
    "level": back.level, "trace": back.trace.tolist(), "seq": back.seq,
    "path": [type(path).__module__, path.path_id],
}))
"""


def _plugin_tree(root: Path, module: str = "widget_msgs", body: str = PLUGIN) -> None:
    (root / f"{module}.py").write_text(body)
    info = root / "widget_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: widget-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[umbra.messages]\nwidgets = {module}\n")


def _probe(root: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), str(REPO)]))
    return subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=60
    )


def test_an_entry_point_adds_message_types_every_process_knows(tmp_path: Path) -> None:
    _plugin_tree(tmp_path)
    done = _probe(tmp_path)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["before"] == []  # importing the base layer imports no plug-in and no domain
    assert out["module"] == "widget_msgs"
    assert out["level"] == 2.5 and out["trace"] == [0.0, 1.0, 2.0] and out["seq"] == 4
    assert out["path"] == ["umbra.connectors.path_messages", "p"]  # the base layer's own
    assert {"WidgetReading", "ToolPath", "Twist"} <= set(out["registered"])


def test_a_broken_plugin_is_named_and_the_others_still_load(tmp_path: Path) -> None:
    _plugin_tree(tmp_path, body="raise ImportError('no widgets today')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(REPO)]))
    code = "from umbra.connectors.messages import message_types; print(sorted(message_types()))"
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert "ToolPath" in done.stdout and "WidgetReading" not in done.stdout
    assert "entry point widgets = widget_msgs not loaded: no widgets today" in done.stderr
