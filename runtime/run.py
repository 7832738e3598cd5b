"""Running one process of a checked graph and reporting how it ended."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from umbra.connectors.json_text import json_text
from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links_api import LinkTransport
from umbra.runtime.scheduler import Scheduler, SchedulerOptions
from umbra.runtime.stats import RunResult
from umbra.runtime.stop_signals import install_stop_signals, restore_signals


def default_output_dir(plan: GraphPlan) -> Path:
    """``runs/<graph>-<YYYYmmdd-HHMMSS>`` under the current folder."""
    return Path("runs") / f"{plan.spec.name}-{time.strftime('%Y%m%d-%H%M%S')}"


def run_process(
    plan: GraphPlan,
    options: SchedulerOptions,
    transport: LinkTransport | None = None,
    prepare: Callable[[Scheduler], None] | None = None,
) -> RunResult:
    """Build and run one process (every module when ``options.process`` is None); always writes
    ``summary[-PROCESS].json`` into the output folder, whatever the outcome. ``prepare`` is called
    with the wired scheduler before it runs (the live server adds its sinks)."""
    options.output_dir.mkdir(parents=True, exist_ok=True)
    scheduler = Scheduler(plan, options, transport)
    # Until the summary is written, Ctrl-C and SIGTERM request a stop (the scheduler routes them
    # to itself while it runs): never a KeyboardInterrupt that skips the summary.
    old = install_stop_signals(scheduler.request_stop) if options.handle_signals else {}
    try:
        if prepare is not None:
            prepare(scheduler)
        try:
            result = scheduler.run()
        finally:
            if transport is not None:
                transport.close()
        write_summary(result, options.output_dir, options.process)
    finally:
        restore_signals(old)
    return result


def write_summary(result: RunResult, output_dir: Path, process: str | None) -> Path:
    """Write the run summary as JSON; returns the file's path."""
    name = "summary.json" if process is None else f"summary-{process}.json"
    path = output_dir / name
    path.write_text(json_text(result.as_dict(), indent=2, default=str))
    return path
