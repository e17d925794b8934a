"""The injected-fault catalogue: one small run per fault, what the twin detected, the end state.

``python -m cnc_twin.studies.fault_catalog`` runs every case and prints the Markdown table of
``docs/faults.md``; ``tests/test_fault_catalog.py`` runs the same cases and checks each row's
expectation. A case is a scenario mapping (a short point-to-point program, or the bundled flat
plate polishing program for the force faults) with one fault injected.

Per case the runner measures:

- the fault the card raised (code, stop), and how long after the injection [ms];
- when the machine was at rest in FAULT [ms after the injection];
- for faults the card cannot see: what happened instead (how the run ended);
- leftovers: a planner process still alive, a whiteboard segment of this process (or of one
  that exited) still in ``/dev/shm``, a partial run directory (the run is written to a temporary
  folder and the check looks for anything but the finished run directory there).
"""

from __future__ import annotations

import copy
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cnc_twin.scenario.resources import scenarios_dir

_JOG = {"name": "fault_jog",
        "program": {"type": "point_to_point", "moves": [{"X": 200, "Y": 100, "feed": 12000}, {"X": 0, "Y": 0}]}}


_OBSTACLE = {"type": "collision", "at": 0.0, "position": [250, 125, 750], "size": [20, 20, 50]}


def _polish(max_time: float) -> dict[str, Any]:
    raw = yaml.safe_load((scenarios_dir() / "flat_plate_polish.yaml").read_text(encoding="utf-8"))
    raw["max_time"] = max_time
    return raw


@dataclass(frozen=True)
class Case:
    """One catalogue row: the fault as written in a scenario, and what must happen."""

    name: str
    fault: dict[str, Any] | None
    """the fault as written under ``faults:`` (None: the program itself provokes it)"""
    expect_code: str
    """fault code expected (``NONE``: the run finishes; the card does not see this fault)"""
    expect_stop: str | None
    within_ms: float
    """the fault must be raised within this long after the injection [ms]"""
    base: str = "jog"
    """``jog`` (2 s point-to-point) or ``polish`` (flat plate, contact from 4.8 s)"""
    extra: dict[str, Any] | None = None
    """more scenario keys (e.g. axis settings)"""
    note: str = ""

    def scenario(self) -> dict[str, Any]:
        raw = copy.deepcopy(_JOG) if self.base == "jog" else _polish(7.0)
        if self.extra:
            for key, value in self.extra.items():
                raw[key] = copy.deepcopy(value)
        raw["faults"] = [self.fault] if self.fault is not None else []
        return raw

    @property
    def injected_at(self) -> float:
        """Simulated time of the injection [s] (0 without one)."""
        return self.fault["at"] if self.fault is not None else 0.0


CASES = (
    Case("encoder count loss (5000 counts)", {"type": "encoder_loss", "at": 0.3, "axis": "X", "counts": 5000},
         "FOLLOWING_ERROR", "disable", 5.0),
    Case("encoder count loss (100 counts)", {"type": "encoder_loss", "at": 0.3, "axis": "X", "counts": 100},
         "NONE", None, 0.0, note="not seen: the machine ends 0.1 mm off (no index-pulse check)"),
    Case("encoder noise (+-50 counts, 0.2 s)",
         {"type": "encoder_noise", "at": 0.3, "axis": "Y", "amplitude": 50, "duration": 0.2},
         "NONE", None, 0.0, note="not seen: within the following-error limit"),
    Case("DAC stuck", {"type": "dac_stuck", "at": 0.3, "axis": "X"}, "FOLLOWING_ERROR", "disable", 1200.0,
         note="seen once the command has moved 3 mm from where the stuck speed carries the axis"),
    Case("DAC dead (0 V)", {"type": "dac_dead", "at": 0.3, "axis": "X"}, "FOLLOWING_ERROR", "disable", 60.0),
    Case("drive torque drop to 2 %", {"type": "torque_drop", "at": 0.1, "axis": "X", "fraction": 0.02},
         "FOLLOWING_ERROR", "disable", 300.0),
    Case("drive torque drop, following-error check off",
         {"type": "torque_drop", "at": 0.1, "axis": "X", "fraction": 0.02}, "DAC_SATURATION", "disable", 400.0,
         extra={"axes": {"X": {"following_error_limit": 0}}}),
    Case("axis collision (obstacle)", _OBSTACLE, "FOLLOWING_ERROR", "disable", 850.0,
         note="a box in the ram's path, there from t = 0; the ram reaches it at X 130.7 mm"),
    Case("axis collision, controlled stop", _OBSTACLE, "FOLLOWING_ERROR", "controlled", 850.0,
         extra={"supervisor": {"following_error_stop": "controlled"}},
         note="the drives stay on and hold the ram against the box"),
    Case("force sensor spike (+120 N, 5 ms)", {"type": "force_spike", "at": 5.0, "force": 120, "duration": 5},
         "FORCE_LIMIT", "retract", 2.0, base="polish"),
    Case("force sensor offset (+30 N)", {"type": "force_offset", "at": 5.0, "force": 30}, "RUN_TIMEOUT",
         "controlled", 2100.0, base="polish",
         note="not seen as such: the force loop backs the pad off and the path waits; the time limit ends the run"),
    Case("DSP task hang (20 ms)", {"type": "dsp_hang", "at": 0.3, "duration": 20}, "WATCHDOG", "disable", 6.0),
    Case("DSP task hang (3 ms, under the watchdog)", {"type": "dsp_hang", "at": 0.3, "duration": 3}, "NONE", None,
         0.0, note="not seen: the loops catch up"),
    Case("hard limit switch (soft limit widened)", None, "HARD_LIMIT", "disable", 4000.0,
         extra={"axes": {"X": {"soft_limits": [-400, 400]}},
                "program": {"type": "point_to_point", "moves": [{"X": 395, "feed": 6000}]}},
         note="no injection: X is sent to 395 mm, past its + limit switch at 390 mm"),
    Case("planner process killed", {"type": "planner_kill", "at": 0.3}, "PLANNER_LOST", "controlled", 2.0),
    Case("record bit flip", {"type": "record_bitflip", "at": 0.5, "bit": 77}, "NONE", None, 0.0,
         note="CRC rejects the record; the planner resends it"),
)


@dataclass
class Row:
    """What one case did. Times in ms after the injection (None where not applicable)."""

    case: Case
    code: str
    stop: str | None
    detected_ms: float | None
    at_rest_ms: float | None
    final_state: str
    message: str
    leftovers: list[str]
    extra: dict[str, float]

    @property
    def ok(self) -> bool:
        c = self.case
        if self.code != c.expect_code or self.stop != c.expect_stop or self.leftovers:
            return False
        if c.expect_code == "NONE":
            return self.final_state == "FINISHED"
        return self.final_state == "FAULT" and self.detected_ms is not None and self.detected_ms <= c.within_ms


def run_case(case: Case) -> Row:
    """Run one case from a scenario file in a temporary folder, write its run directory, and
    check what is left behind."""
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.run.twin import Twin
    from cnc_twin.whiteboard.block import leaked_segments, leftover_segments

    segments_before = set(leftover_segments())
    with tempfile.TemporaryDirectory(prefix="cnc_twin_fault_") as folder:
        path = Path(folder) / "scenario.yaml"
        path.write_text(yaml.safe_dump(case.scenario(), sort_keys=False), encoding="utf-8")
        scenario = load_scenario(path)
        twin = Twin(scenario)
        result = twin.run()
        runs = Path(folder) / "runs"
        runs.mkdir()
        result.write(runs / "run", recording=False)
        leftovers = [f"partial file {p.name}" for p in runs.iterdir() if p.name != "run"]
        if twin.process is not None and twin.process.poll() is None:
            leftovers.append("planner process alive")
        # only this process's segments (or orphans) count: another cnc-twin run on the machine
        # creates and unlinks its own while this case runs
        new_segments = set(leftover_segments()) - segments_before
        leftovers += [f"segment {name}" for name in sorted(leaked_segments(new_segments))]
        complete = {p.name for p in (runs / "run").iterdir()}
        if not {"scenario.yaml", "trace.parquet", "metrics.json"} <= complete:
            leftovers.append(f"run directory incomplete: {sorted(complete)}")
        positions = twin.plant.axis_positions()
    m = result.metrics
    fault = m["fault"]
    injected = case.injected_at
    extra = {}
    if case.fault is not None and case.fault["type"] == "encoder_loss" and case.expect_code == "NONE":
        # the card believes X is home; the machine is not
        extra["x_off_mm"] = (positions[0] - scenario.home[0]) * 1e3
    extra["sim_s"] = m["sim_time_s"]
    if fault is not None and fault["code"] == "FORCE_LIMIT":  # how far Z went up after the fault
        z = result.trace.columns()["actual_Z"]
        k = int(fault["time_s"] / scenario.timing.servo_period)
        extra["retract_mm"] = float(z[-1] - z[k]) / scenario.axes[2].counts_per_unit * 1e3
    if fault is None:
        return Row(case, "NONE", None, None, None, m["final_state"], "", leftovers, extra)
    at_rest = fault.get("at_rest_s")
    return Row(case, fault["code"], fault["stop"], (fault["time_s"] - injected) * 1e3,
               None if at_rest is None else (at_rest - injected) * 1e3, m["final_state"], fault["message"],
               leftovers, extra)


def markdown(rows: list[Row]) -> str:
    """The table of ``docs/faults.md``."""
    lines = ["| fault | detected as | after | stop | at rest after | end state | left behind | notes |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        c = r.case
        after = "-" if r.detected_ms is None else f"{r.detected_ms:.0f} ms"
        rest = "-" if r.at_rest_ms is None else f"{r.at_rest_ms:.0f} ms"
        code = "not detected" if r.code == "NONE" else f"`{r.code}`"
        note = c.note
        if "x_off_mm" in r.extra:
            note = f"{note} (measured {r.extra['x_off_mm']:.3f} mm)"
        if r.message:
            note = f"{note}; \"{r.message}\"" if note else f"\"{r.message}\""
        left = "nothing" if not r.leftovers else ", ".join(r.leftovers)
        lines.append(f"| {c.name} | {code} | {after} | {r.stop or '-'} | {rest} | {r.final_state} | {left} | {note} |")
    return "\n".join(lines)


def main() -> int:
    """``python -m cnc_twin.studies.fault_catalog``: every case run, the table printed; exit 1 if
    a case is not as expected."""
    rows = []
    for i, case in enumerate(CASES):
        print(f"[{i + 1}/{len(CASES)}] {case.name}", file=sys.stderr, flush=True)
        rows.append(run_case(case))
    print(markdown(rows))
    bad = [r.case.name for r in rows if not r.ok]
    if bad:
        print(f"\nnot as expected: {', '.join(bad)}")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
