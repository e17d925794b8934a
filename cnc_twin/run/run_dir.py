"""The run directory: ``scenario.yaml`` (the file as written), ``trace.parquet``, ``metrics.json``
and whatever a run adds (the rerun recording, the removal map).

It is written under a hidden temporary name and renamed when complete, so a directory with the
final name is always whole.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from cnc_twin.core.config import Scenario
from cnc_twin.core.errors import ResourceError
from cnc_twin.core.phases import mark
from cnc_twin.run.run_claim import claim_run_dir, release_run_dir
from cnc_twin.trace.parquet import write_trace
from cnc_twin.trace.trace import Trace

TRACE_FILE = "trace.parquet"
METRICS_FILE = "metrics.json"
SCENARIO_FILE = "scenario.yaml"
RECORDING_FILE = "recording.rrd"


def new_run_dir(parent: str | Path, name: str, *, claim: bool = False) -> Path:
    """``parent/<name>-<UTC time>`` (``-2``, ``-3``, ... added if taken): a run directory's
    default name, the CLI's and :meth:`~cnc_twin.run.result.RunResult.write`'s; with ``claim``,
    made empty at once (:func:`~cnc_twin.run.run_claim.claim_run_dir`), so two runs started in the
    same second get two."""
    parent = Path(parent)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    candidate = parent / f"{name}-{stamp}"
    n = 2
    while True:
        if claim:
            try:
                return claim_run_dir(candidate)
            except FileExistsError:
                pass
        elif not candidate.exists():
            return candidate
        candidate = parent / f"{name}-{stamp}-{n}"
        n += 1


ROOM_FACTOR = 3.0
"""the files a run writes, at most, per byte of its raw signals: trace.parquet about 0.6, the
recording about 1.2 (measured on jog_axes and nurbs_circle), with a margin"""
ROOM_SPARE = 4 << 20
"""[bytes] room beyond the estimate: metrics, the scenario, the pictures"""


def check_room(run_dir: Path, twin, planned: int, *, recording: bool) -> None:
    """Refuse (:class:`~cnc_twin.core.errors.ResourceError`) a run whose files would not fit where
    its run directory is: the estimate from ``planned`` periods (the program's length the planner
    announced), against the space free there."""
    from cnc_twin.trace.layout import raw_bytes

    timing = twin.scenario.timing
    raw = raw_bytes((planned + 2) * timing.ticks_per_period, planned + 2)
    need = int(raw * (ROOM_FACTOR if recording else ROOM_FACTOR / 3.0)) + ROOM_SPARE
    free = shutil.disk_usage(run_dir if run_dir.exists() else run_dir.parent).free
    if free < need:
        raise ResourceError(run_dir, f"not enough room for this run's files: about {need / 1e6:.1f} MB needed "
                            f"({planned * timing.interpolation_period:g} s of program), {free / 1e6:.1f} MB free")


def keep_after_failed_write(run_dir: Path, metrics: dict[str, Any], exc: OSError) -> str:
    """After writing ``run_dir`` failed with ``exc`` (its partial files already removed): keep
    ``metrics.json`` there with the run's status and why it was not written, if even that fits.
    Returns one line: which file, why, what was kept."""
    where = Path(exc.filename).name if getattr(exc, "filename", None) else "the run directory"
    reason = f"not written: {where}: {exc.strerror or exc}"
    try:
        run_dir.mkdir(exist_ok=True)
        _write_metrics(run_dir / METRICS_FILE, {**metrics, "written": False, "write_error": reason})
        return f"{reason}; kept: {METRICS_FILE} (the run's status and this reason)"
    except OSError:
        try:
            (run_dir / METRICS_FILE).unlink(missing_ok=True)
        except OSError:  # read-only: nothing was written either
            pass
        release_run_dir(run_dir)
        return f"{reason}; nothing could be kept"


def named_io(name: str, write) -> None:
    """``write()``, a failure to write turned into an OSError that names the file ``name`` when it
    names none, with the system's words for its errno: Arrow's OSErrors name no file and say only
    "Detail: [errno 28]"; rerun's are RuntimeErrors saying "(os error 28)". Other errors pass."""
    try:
        write()
    except (OSError, RuntimeError) as exc:
        if isinstance(exc, OSError) and exc.filename:
            raise
        found = re.search(r"(?:\[errno|os error) (\d+)", str(exc))
        number = (exc.errno if isinstance(exc, OSError) else None) or (int(found.group(1)) if found else None)
        if number is None and not isinstance(exc, OSError):
            raise  # not an I/O failure
        raise OSError(number, os.strerror(number) if number else str(exc), name) from exc


def write_run_dir(run_dir: Path, *, scenario: Scenario, trace: Trace, metrics: dict[str, Any],
                  extra=None, claimed: bool = False) -> Path:
    """Write the run directory atomically: a hidden temporary folder renamed when complete.

    ``trace``: a :class:`~cnc_twin.trace.trace.Trace`, written; or a long run's
    :class:`~cnc_twin.trace.trace_file.TraceFile`, its file moved in (copied if it is already in
    another run directory).

    ``extra(folder)`` may add files (the rerun recording) before the rename. ``claimed``: the run
    claimed ``run_dir`` (:func:`~cnc_twin.run.run_claim.claim_run_dir`): the whole directory
    replaces that empty one.
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
        named_io(SCENARIO_FILE, lambda: (tmp / SCENARIO_FILE).write_text(scenario.source_text, encoding="utf-8"))
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
                named_io(TRACE_FILE, writing.result)
        mark("trace")
        _write_metrics(tmp / METRICS_FILE, metrics)
        mark("metrics")
        if run_dir.exists() and not (claimed and run_dir.is_dir() and not any(run_dir.iterdir())):
            raise FileExistsError(f"run directory {run_dir} already exists")
        os.replace(tmp, run_dir)  # onto the claimed empty folder too: rename(2) replaces it
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
