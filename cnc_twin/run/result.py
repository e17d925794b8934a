"""What a run produced (:class:`~cnc_twin.run.result.RunResult`): the trace, the metrics, and how to
write them."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core.config import Scenario
from cnc_twin.core.phases import mark
from cnc_twin.run.external_pc import STREAM_FILE, replay_text
from cnc_twin.run.run_dir import RECORDING_FILE, named_io, new_run_dir, write_run_dir
from cnc_twin.trace.trace import Trace


@dataclass
class RunResult:
    """What a run produced. Nothing is written to disk unless :meth:`write` is called."""

    scenario: Scenario
    trace: Trace
    metrics: dict[str, Any]
    run_dir: Path | None = field(default=None)
    model: Any = field(default=None, repr=False)
    """the compiled MJCF the run used (for exports)"""
    exchange_latency: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """(period, latency [us]) of every answered exchange: wall clock, so kept out of the trace"""
    removal: Any = field(default=None, repr=False)
    """the removal map of a surface polishing run (:class:`cnc_twin.polishing.removal.PrestonModel`)"""
    pc_stream: Any = field(default=None, repr=False)
    """what the PC side wrote, exchange by exchange (:class:`~cnc_twin.whiteboard.capture.PcStream`),
    when it was an outside program's (``cnc-twin serve``) or a replay of one: the run directory
    keeps it as ``pc_stream.bin``, named by its scenario's ``planner.replay``"""
    _figures: dict[str, bytes] | None = field(default=None, init=False, repr=False)

    @property
    def status(self) -> str:
        """``complete``, ``fault`` or ``interrupted``."""
        return self.metrics["status"]

    def dataframe(self):
        """The trace as a pandas DataFrame (columns as in trace.parquet); needs pandas installed."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("RunResult.dataframe() needs pandas: pip install 'cnc-twin[analysis]' "
                              "(from a clone: pip install '.[analysis]')") from None
        from cnc_twin.trace.layout import column_unit

        frame = pd.DataFrame(self.trace.columns())
        # as trace.parquet's metadata has them: each column's unit, counts per mm or deg per axis
        frame.attrs["units"] = {name: column_unit(name) for name in frame.columns}
        frame.attrs["counts_per_unit"] = {a.name: a.counts_per_unit / a.display_factor for a in self.scenario.axes}
        frame.attrs["position_units"] = {a.name: a.display_unit for a in self.scenario.axes}
        frame.attrs["scenario"] = self.scenario.name
        return frame

    def write(self, run_dir: str | Path | None = None, *, recording: bool | Callable[[], Path | None] = True,
              runs_dir: str | Path = "runs", claimed: bool = False) -> Path:
        """Write ``scenario.yaml`` (and the files it names that a re-run needs: a G-code program),
        ``trace.parquet``, ``metrics.json`` and, unless
        ``recording=False``, ``recording.rrd`` (rerun) to ``run_dir`` (a new folder; by default
        ``runs_dir/<name>-<UTC time>``, as the CLI names it), exported now. Returns the folder.

        ``recording`` may instead be a callable, called once the trace is written, that returns
        the path of a finished recording of this run to move in (one a
        :class:`~cnc_twin.view.rerun_stream.RecordingProcess` made during it, on the same file
        system), or None to export it now after all. ``claimed``: ``run_dir`` was claimed for this
        run (:func:`~cnc_twin.run.run_claim.claim_run_dir`), an empty folder the written one
        replaces."""
        def extra(folder: Path) -> None:
            from cnc_twin.run.program_kinds import write_run_files

            write_run_files(self.scenario.program, folder)
            if self.pc_stream is not None:
                (folder / STREAM_FILE).write_bytes(self.pc_stream.to_bytes())
            if self.removal is not None:
                self.removal.save(folder)
            for name, png in self.figures().items():
                (folder / f"{name}.png").write_bytes(png)
            mark("files")
            finished = recording() if callable(recording) else None
            if finished is not None:
                os.replace(finished, folder / RECORDING_FILE)
            elif recording:
                named_io(RECORDING_FILE, lambda: self.export_rerun(rrd=folder / RECORDING_FILE))
            mark("recording")
        if run_dir is None:
            run_dir = new_run_dir(runs_dir, self.scenario.name)
        scenario = self.scenario
        if self.pc_stream is not None:  # it runs again with the stream beside it
            scenario = replace(scenario, source_text=replay_text(scenario.source_text))
        self.run_dir = write_run_dir(Path(run_dir), scenario=scenario, trace=self.trace, metrics=self.metrics,
                                     extra=extra, claimed=claimed)
        return self.run_dir

    def export_rerun(self, *, rrd: Path | None = None, spawn: bool = False) -> None:
        """Write a rerun recording of the run and/or open it in a spawned viewer."""
        from cnc_twin.view.rerun_export import export_run

        export_run(self.trace, self.scenario, self.metrics, rrd=rrd, spawn=spawn, model=self.model,
                   exchange_latency=self.exchange_latency, figures=self.figures())

    def figures(self) -> dict[str, bytes]:
        """The run's plots as PNG bytes by name, for the run directory (``<name>.png``) and the
        recording: ``ballbar`` (the circular test's polar plot) when the scenario measures one."""
        if self._figures is None:
            self._figures = {}
            if self.scenario.ballbar is not None and "ballbar" in self.metrics:
                from cnc_twin.run.ballbar import ballbar_passes
                from cnc_twin.run.ballbar_plot import polar_plot_png

                test = self.scenario.ballbar
                passes = ballbar_passes(self.trace, test, self.scenario.timing.interpolation_period)
                self._figures["ballbar"] = polar_plot_png(passes, self.metrics["ballbar"], test)
        return self._figures
