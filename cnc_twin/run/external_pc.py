"""Someone else's PC program as a run's PC side (``cnc-twin serve``).

:class:`ExternalPc` stands where the twin's own planner process stands in
:meth:`~cnc_twin.run.twin.Twin.run` (given as its ``planners``): instead of starting a process and
handing it a job, it makes the run's attach folder (:class:`~cnc_twin.whiteboard.attach_point.AttachPoint`),
says where it is (``announce``), and lets the card wait for the program to attach (the magic word,
within ``planner.start_timeout``). Everything else is the run as always: the card's limits, the
faults (a program that stops answering or exits is a lost planner), the trace, the metrics.

The card keeps what the program wrote, exchange by exchange (:mod:`cnc_twin.whiteboard.capture`);
the run directory gets it as ``pc_stream.bin`` and a ``scenario.yaml`` whose ``planner.replay``
names it, so ``cnc-twin run RUN_DIR/scenario.yaml`` gives the same run again without the program.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import yaml

from cnc_twin.whiteboard.attach_point import AttachPoint

STREAM_FILE = "pc_stream.bin"
"""the PC program's stream in the run directory"""
OPEN_ENDED_MAX_TIME = 3600.0
"""[s] simulated: a served run's ``max_time`` when the scenario sets none and the PC program
announced no program length (0)"""


class ExternalPc:
    """The PC side of one served run: an outside program that attaches through an attach folder.

    ``folder``: where to make the attach folder (must not exist), or None for a new one in the
    temporary directory; ``announce(folder)`` is called once it is ready for the program.
    """

    reusable = False
    capture = True
    popen = None
    """no process of the twin's (observers that look for one find none)"""

    def __init__(self, folder: Path | None = None, announce: Callable[[Path], None] | None = None):
        self.folder = folder
        self.announce = announce
        self.point: AttachPoint | None = None

    # the planner pool's interface, for Twin.run
    def acquire(self) -> "ExternalPc":
        return self

    def release(self, planner: "ExternalPc") -> None:
        self.close()

    # the planner process's interface
    def submit(self, shm_name: str, job) -> None:
        """Make the attach folder for the run's segment ``shm_name`` and say where it is (the job
        is the program's own business: nothing is handed over)."""
        self.point = AttachPoint(shm_name, self.folder)
        self.folder = self.point.folder
        if self.announce is not None:
            self.announce(self.folder)

    @property
    def bells(self) -> AttachPoint:
        return self.point

    def alive(self) -> bool:
        """False once the program has exited (its doorbell hung up)."""
        return self.point is not None and not self.point.pc_gone()

    def failure(self, timeout: float = 0.0) -> str | None:
        """Why the program failed: it does not say (its own output is its user's)."""
        return None

    def finish(self, timeout: float = 0.0) -> bool:
        return False

    def close(self) -> None:
        """Remove the attach folder and close the card's doorbells (again: nothing)."""
        if self.point is not None:
            self.point.close()

    def __enter__(self) -> "ExternalPc":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def replay_text(source_text: str) -> str:
    """The scenario's text with ``planner.replay`` naming :data:`STREAM_FILE`: the run directory's
    scenario, which runs the served run again with the twin's planner writing the same stream."""
    raw = yaml.safe_load(source_text) or {}
    planner = raw.get("planner") or {}
    raw["planner"] = {**planner, "replay": STREAM_FILE}
    return yaml.safe_dump(raw, sort_keys=False)
