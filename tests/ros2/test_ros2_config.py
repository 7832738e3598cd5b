"""``--ros2-config FILE|DIR``: the ROS 2 session's zenoh configuration, read by the links' rules
(a bad file refused before anything starts, with where and why; a folder of ``umbra keys`` gives
each process its own ``PROCESS.json5``), and passed on by a launcher to its processes."""

from __future__ import annotations

import subprocess
import sys

import pytest

from umbra.connectors.errors import UserError
from umbra.runtime.ros2.run_args import child_args
from umbra.runtime.ros2.run_bridge import Ros2RunOptions

from .run_graph import write_graph


def test_a_bad_ros2_config_file_is_refused_before_the_run(tmp_path):
    bad = tmp_path / "ros2.json5"
    bad.write_text("{ mode: 'client', connect: { endpoints: [ }")
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "run", str(write_graph(tmp_path)),
         "--ros2-config", str(bad), "--duration", "1", "--out", str(tmp_path / "out")],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert f"{bad}" in done.stderr and "not a valid zenoh configuration" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "out" / "summary.json").exists()


def test_a_folder_gives_each_process_its_file_and_a_launcher_passes_it_on(tmp_path):
    (tmp_path / "vision.json5").write_text("{}")
    options = Ros2RunOptions(router="tls/127.0.0.1:7447", config_file=str(tmp_path))
    assert options.config_of("vision") == str(tmp_path / "vision.json5")
    with pytest.raises(UserError, match="no zenoh configuration for process `track`"):
        options.config_of("track")
    with pytest.raises(UserError, match="expected a zenoh configuration file for a run of one"):
        options.config_of(None)
    args = child_args(options)
    assert args[args.index("--ros2-config") + 1] == str(tmp_path)
    assert Ros2RunOptions().config_of("vision") is None
    assert "--ros2-config" not in child_args(Ros2RunOptions())
