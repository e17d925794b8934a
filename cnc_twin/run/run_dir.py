"""The run directory: ``scenario.yaml`` (the file as written), ``trace.parquet``, ``metrics.json``
and whatever a run adds (the rerun recording, the removal map).

It is written under a hidden temporary name and renamed when complete, so a directory with the
final name is always whole.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from cnc_twin.core.config import Scenario
from cnc_twin.core.phases import mark
from cnc_twin.trace.parquet import write_trace
from cnc_twin.trace.trace import Trace

TRACE_FILE = "trace.parquet"
METRICS_FILE = "metrics.json"
SCENARIO_FILE = "scenario.yaml"
RECORDING_FILE = "recording.rrd"


def new_run_dir(parent: str | Path, name: str) -> Path:
    """``parent/<name>-<UTC time>`` (``-2``, ``-3``, ... added if taken): a run directory's
    default name, the CLI's and :meth:`~cnc_twin.run.result.RunResult.write`'s."""
    parent = Path(parent)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    candidate = parent / f"{name}-{stamp}"
    n = 2
    while candidate.exists():
        candidate = parent / f"{name}-{stamp}-{n}"
        n += 1
    return candidate


def write_run_dir(run_dir: Path, *, scenario: Scenario, trace: Trace, metrics: dict[str, Any],
                  extra=None) -> Path:
    """Write the run directory atomically: a hidden temporary folder renamed when complete.

    ``trace``: a :class:`Trace`, written; or a long run's
    :class:`~cnc_twin.trace.trace_file.TraceFile`, its file moved in (copied if it is already in
    another run directory).

    ``extra(folder)`` may add files (the rerun recording) before the rename.
    """
    run_dir = Path(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = run_dir.parent / f".{run_dir.name}.partial-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    in_file = hasattr(trace, "move_to")  # a long run's trace, already in its file
    was = (trace.path, trace.staged) if in_file else None
    try:
        (tmp / SCENARIO_FILE).write_text(scenario.source_text, encoding="utf-8")
        # The trace is encoded beside the other files (Arrow works without the GIL while the
        # pictures render and the recording closes); the block waits for it, whatever happens.
        with ThreadPoolExecutor(max_workers=1) as background:
            if in_file:
                trace.move_to(tmp / TRACE_FILE)
                writing = None
            else:
                writing = background.submit(write_trace, trace, tmp / TRACE_FILE, scenario_name=scenario.name)
            if extra is not None:
                extra(tmp)
            if writing is not None:
                writing.result()
        mark("trace")
        _write_metrics(tmp / METRICS_FILE, metrics)
        mark("metrics")
        if run_dir.exists():
            raise FileExistsError(f"run directory {run_dir} already exists")
        os.replace(tmp, run_dir)
    except BaseException:
        if in_file and was[1] and trace.path != was[0]:  # the run's file goes back where it was, not lost
            shutil.move(trace.path, was[0])
            trace.path, trace.staged = was
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if in_file:
        trace.path = run_dir / TRACE_FILE
    return run_dir


def rewrite_metrics(run_dir: Path, metrics: dict[str, Any]) -> None:
    """Replace a written run directory's ``metrics.json`` atomically (staged beside it, then
    renamed): the file is whole whatever happens meanwhile."""
    staged = Path(run_dir) / f".{METRICS_FILE}.partial"
    _write_metrics(staged, metrics)
    os.replace(staged, Path(run_dir) / METRICS_FILE)


def _write_metrics(path: Path, metrics: dict[str, Any]) -> None:
    path.write_text(json.dumps(metrics, indent=2) + "\n", encoding="utf-8")


def mark_interrupted(run_dir: Path, metrics: dict, reason: str) -> None:
    """Mark a written run directory's ``metrics.json`` interrupted, with ``reason``."""
    metrics["status"], metrics["stop_reason"] = "interrupted", reason
    rewrite_metrics(run_dir, metrics)
