"""SIGUSR1 to a running ``umbra`` prints every thread's Python stack to stderr, and the run goes
on: what a process that does not stop is waiting for can be seen from outside."""

from __future__ import annotations

import json
import signal
import threading
from pathlib import Path

import pytest

from tests.poll import wait_for
from tests.runtime.fixtures import start_recording_run


@pytest.mark.skipif(not hasattr(signal, "SIGUSR1"), reason="needs POSIX signals")
def test_sigusr1_prints_every_threads_stack_and_the_run_goes_on(tmp_path: Path) -> None:
    proc, out = start_recording_run(tmp_path)
    lines: list[str] = []
    assert proc.stderr is not None
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    try:
        recording = out / "recording.mcap"
        wait_for(recording.exists, 30, "the recording file", 0.05)
        # The file is opened before the recorder's thread starts; once that thread has flushed
        # to it, the run's loop and that thread are both up.
        opened = recording.stat().st_size
        wait_for(lambda: recording.stat().st_size > opened, 30, "the recorder's first flush", 0.05)
        proc.send_signal(signal.SIGUSR1)
        wait_for(
            lambda: sum("most recent call first" in line for line in lines) >= 2,
            30,
            lambda: "two threads' stacks on stderr, found:\n" + "".join(lines),
        )
        assert proc.poll() is None, "".join(lines)  # the run went on
        dump = "".join(lines)
        # Which OS thread takes the signal (and so which one faulthandler calls "Current") is the
        # kernel's choice; what matters is that the scheduler's own frames are in the dump.
        assert 'scheduler.py", line' in dump, dump
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
    reader.join(timeout=5)
    assert proc.returncode == 130, "".join(lines)
    assert json.loads((out / "summary.json").read_text())["exit_code"] == 130
