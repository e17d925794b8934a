"""Claiming a run directory's name for a run, from when its scenario is read until it is written.

A claimed run directory exists at once, empty, so a second run on the same name is refused before
it simulates anything; the written directory replaces the empty one whole
(:func:`~cnc_twin.run.run_dir.write_run_dir`). A mark beside it (``.<name>.claim-<pid>``) says
who claimed it: an empty folder whose claimer is gone (SIGKILL, a power cut) is taken over, not
refused. Light (no numpy): the command checks its ``--out`` with it before its imports.
"""

from __future__ import annotations

import os
from pathlib import Path


def claim_run_dir(run_dir: Path) -> Path:
    """Make ``run_dir`` now, empty (its parents too): the name is this run's (FileExistsError if it
    is taken). A claim is marked beside it (``.<name>.claim-<pid>``): an empty folder whose claimer
    died (SIGKILL, a power cut) is taken over, not refused.
    :func:`~cnc_twin.run.run_dir.write_run_dir` with ``claimed`` replaces the folder whole;
    :func:`release_run_dir` gives it up."""
    run_dir = Path(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    mine = _claim_mark(run_dir, os.getpid())
    try:
        run_dir.mkdir()
        mine.touch()
    except FileExistsError:
        if not _take_over(run_dir, mine):
            raise
    return run_dir


def _claim_mark(run_dir: Path, pid: int) -> Path:
    return run_dir.parent / f".{run_dir.name}.claim-{pid}"


def _take_over(run_dir: Path, mine: Path) -> bool:
    """Whether ``run_dir`` was an empty folder claimed by a process now gone, and is now ours
    (of two runs taking it over at once, one wins: the stale mark is renamed to ours)."""
    if not run_dir.is_dir() or any(run_dir.iterdir()):
        return False
    for mark_ in run_dir.parent.glob(f".{run_dir.name}.claim-*"):
        if not _claimer_gone(mark_):
            return False
        try:
            os.rename(mark_, mine)
            return True
        except OSError:
            return False
    return False


def release_run_dir(run_dir: Path) -> None:
    """Give up the claim on ``run_dir``: the folder removed if still empty (the run never got
    written), the claim's mark removed."""
    try:
        run_dir.rmdir()
    except OSError:  # written (not empty), or gone
        pass
    try:
        _claim_mark(run_dir, os.getpid()).unlink(missing_ok=True)
    except OSError:  # a folder turned read-only: the mark stays, a dead claimer's (taken over later)
        pass


def taken(run_dir: Path) -> bool:
    """Whether ``run_dir`` exists and is not an abandoned claim (an empty folder whose claimer is
    gone): what a run on that name is refused for."""
    run_dir = Path(run_dir)
    if not (run_dir.exists() or run_dir.is_symlink()):
        return False
    if not run_dir.is_dir() or any(run_dir.iterdir()):
        return True
    return not any(_claimer_gone(mark_) for mark_ in run_dir.parent.glob(f".{run_dir.name}.claim-*"))


def _claimer_gone(mark_: Path) -> bool:
    try:
        os.kill(int(mark_.name.rsplit("-", 1)[1]), 0)
    except ProcessLookupError:
        return True
    except (ValueError, PermissionError):
        pass
    return False
