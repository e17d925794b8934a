"""A finished run as a rerun recording: the machine posed over time, paths, signals, events.

Entity tree (timelines ``sim_time`` [s] and ``period``)::

    /machine/<body>            Transform3D over time (world from body), from the trace's
    /machine/<body>/<geom>       encoder positions through MuJoCo's kinematics; geometry static
    /paths/commanded           tool-tip path the card commanded (LineStrips3D, static)
    /paths/actual              tool-tip path the machine made (static)
    /paths/planned             the ideal NURBS curve (curve programs, static)
    /force/arrow               pad force along the tool axis at the tip (Arrows3D over time)
    /axes/<X..C>/command, /actual      [mm | deg]
    /axes/<X..C>/ferr                  [counts]
    /axes/<X..C>/dac                   [code]
    /axes/<X..C>/saturated             1 while the DAC is pinned at -2048 or 2047
    /feed/commanded, /feed/actual      tool-tip path speed [mm/min]
    /force/measured                    load cell, tared [N]
    /controller/events                 state changes and faults (TextLog)
    /whiteboard/fifo_fill [words], /whiteboard/missed_exchanges, /whiteboard/records_rejected
    /whiteboard/exchange_latency_us    DSP post -> planner answer, wall clock (recording only)

Everything time-varying goes in bulk through ``send_columns`` (one call per entity), after the
run, so recording costs the servo loop nothing. Body poses and series are sampled once per
interpolation period (decimated further for runs longer than ``MAX_SAMPLES`` periods).
"""

from __future__ import annotations

import math
import uuid
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from cnc_twin import mujoco_c
from cnc_twin.axes import AXES, joint_name
from cnc_twin.config import NurbsProgram, Scenario
from cnc_twin.plant import HOME_KEYFRAME, load_model
from cnc_twin.record import Trace
from cnc_twin.whiteboard.status import DspState

POSE_INTERVAL = 0.004
"""3D poses, paths and the force arrow: one sample per 4 ms at most (the eye needs no more)"""
STATE_NAMES = DspState.NAMES


def default_blueprint() -> rrb.Blueprint:
    """3D machine view and event log on the left; time series grouped by concern on the right."""
    position = [rrb.TimeSeriesView(name=f"{a} command / actual", origin=f"/axes/{a}",
                                   contents=[f"/axes/{a}/command", f"/axes/{a}/actual"]) for a in AXES]
    ferr = rrb.TimeSeriesView(name="following error [counts]", origin="/axes", contents=[f"/axes/{a}/ferr" for a in AXES])
    dac = rrb.TimeSeriesView(name="DAC [code] and saturation", origin="/axes",
                             contents=[f"/axes/{a}/{s}" for a in AXES for s in ("dac", "saturated")])
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(name="machine", origin="/", contents=["/machine/**", "/paths/**", "/force/arrow"]),
                rrb.TextLogView(name="controller", origin="/controller"),
                row_shares=[3, 1],
            ),
            rrb.Vertical(
                rrb.Grid(*position),
                rrb.Horizontal(ferr, dac),
                rrb.Horizontal(
                    rrb.TimeSeriesView(name="feed [mm/min]", origin="/feed"),
                    rrb.TimeSeriesView(name="pad force [N]", origin="/force", contents=["/force/measured"]),
                    rrb.TimeSeriesView(name="whiteboard", origin="/whiteboard",
                                       contents=["/whiteboard/fifo_fill", "/whiteboard/missed_exchanges",
                                                 "/whiteboard/records_rejected"]),
                    rrb.TimeSeriesView(name="exchange latency [us]", origin="/whiteboard",
                                       contents=["/whiteboard/exchange_latency_us"]),
                ),
                row_shares=[3, 2, 2],
            ),
            column_shares=[2, 3],
        ),
        collapse_panels=True,
    )


def _timelines(trace: Trace, ticks: np.ndarray) -> list:
    # computed for the ticks asked for only (the trace computes time and period for all on access)
    return [rr.TimeColumn("sim_time", duration=ticks * trace.servo_period),
            rr.TimeColumn("period", sequence=ticks // trace.ticks_per_period)]


def _axis_positions(trace: Trace, scenario: Scenario, ticks: np.ndarray, signal: np.ndarray) -> np.ndarray:
    """Axis positions [m | rad] at ``ticks`` from a counts signal (command or actual)."""
    return signal[ticks] / trace.counts_per_unit + np.asarray(scenario.home)


class _Kinematics:
    """Replays axis positions through the model: body poses and the tool tip."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self.data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, self.data, model.key(HOME_KEYFRAME).id)
        self.adr = [model.joint(joint_name(a)).qposadr[0] for a in AXES]
        self.tool = model.site("tool_site").id

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For q (n, 6): body positions (n, nbody, 3), quaternions wxyz (n, nbody, 4), tool tips
        (n, 3) and tool axes (n, 3, unit, tip -> spindle)."""
        m, d = self.model, self.data
        n = len(q)
        pos = np.empty((n, m.nbody, 3))
        quat = np.empty((n, m.nbody, 4))
        tips = np.empty((n, 3))
        axes = np.empty((n, 3))
        if mujoco_c.available():  # the same mj_kinematics calls, without a Python loop around them
            _replay(m._address, d._address, np.ascontiguousarray(q, dtype=np.float64), np.asarray(self.adr),
                    d.qpos, d.xpos, d.xquat, d.site_xpos, d.site_xmat, self.tool, pos, quat, tips, axes)
            return pos, quat, tips, axes
        for k in range(n):
            d.qpos[self.adr] = q[k]
            mujoco.mj_kinematics(m, d)
            pos[k], quat[k] = d.xpos, d.xquat
            tips[k] = d.site_xpos[self.tool]
            axes[k] = d.site_xmat[self.tool].reshape(3, 3)[:, 2]
        return pos, quat, tips, axes


if mujoco_c.IMPORT_ERROR is None:
    from numba import njit

    _mj_kinematics = mujoco_c.mj_kinematics

    @njit(cache=True)
    def _replay(model_ptr, data_ptr, q, adr, qpos, xpos, xquat, site_xpos, site_xmat, tool, pos, quat, tips,
                axes):  # pragma: no cover - compiled; the Python loop in _Kinematics.poses is its twin
        for k in range(q.shape[0]):
            for i in range(adr.shape[0]):
                qpos[adr[i]] = q[k, i]
            _mj_kinematics(model_ptr, data_ptr)
            pos[k] = xpos
            quat[k] = xquat
            tips[k] = site_xpos[tool]
            for r in range(3):
                axes[k, r] = site_xmat[tool, 3 * r + 2]


def _body_path(model: mujoco.MjModel, b: int) -> str:
    return f"/machine/{model.body(b).name or f'body{b}'}"


def log_geometry(rec: rr.RecordingStream, model: mujoco.MjModel) -> None:
    """The machine's visual and workpiece geoms, static, under their bodies (world geoms apart)."""
    for g in range(model.ngeom):
        b = model.geom_bodyid[g]
        name = model.geom(g).name or f"geom{g}"
        if b == 0:
            if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE:
                _log_geom(rec, model, g, f"/machine/world/{name}")
        elif model.geom_group[g] in (2, 3):
            _log_geom(rec, model, g, f"{_body_path(model, b)}/{name}")


def log_poses(rec: rr.RecordingStream, model: mujoco.MjModel, pos: np.ndarray, quat: np.ndarray, times: list) -> None:
    """Each body's pose over time (world from body)."""
    for b in range(1, model.nbody):
        rec.send_columns(_body_path(model, b), indexes=times,
                         columns=rr.Transform3D.columns(translation=pos[:, b], quaternion=quat[:, b][:, [1, 2, 3, 0]]))


def _log_geom(rec: rr.RecordingStream, model: mujoco.MjModel, g: int, path: str) -> None:
    size, center = model.geom_size[g], model.geom_pos[g]
    q = model.geom_quat[g]
    quaternion = rr.Quaternion(xyzw=[q[1], q[2], q[3], q[0]])
    color = (np.clip(model.geom_rgba[g], 0, 1) * 255).astype(np.uint8)
    kind = model.geom_type[g]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        rec.log(path, rr.Boxes3D(half_sizes=[size], centers=[center], quaternions=[quaternion], colors=[color],
                                 fill_mode="solid"), static=True)
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        rec.log(path, rr.Cylinders3D(lengths=[2 * size[1]], radii=[size[0]], centers=[center],
                                     quaternions=[quaternion], colors=[color], fill_mode="solid"), static=True)
    elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        rec.log(path, rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], centers=[center], colors=[color],
                                      fill_mode="solid"), static=True)


def log_paths(rec: rr.RecordingStream, scenario: Scenario, command_tips: np.ndarray, actual_tips: np.ndarray) -> None:
    """Commanded and actual tool-tip paths, and the planned curve for curve programs."""
    rec.log("/paths/commanded", rr.LineStrips3D([command_tips], colors=[[60, 120, 255]], radii=[0.0006]), static=True)
    rec.log("/paths/actual", rr.LineStrips3D([actual_tips], colors=[[255, 140, 0]], radii=[0.0004]), static=True)
    prog = scenario.program
    if isinstance(prog, NurbsProgram):
        from cnc_twin.path_metrics import tip_curve

        curve = tip_curve(prog)
        dense = curve.point(np.linspace(*curve.domain, 4000))
        rec.log("/paths/planned", rr.LineStrips3D([dense], colors=[[40, 200, 80]], radii=[0.0003]), static=True)


def log_axes(rec: rr.RecordingStream, trace: Trace, scenario: Scenario, ticks: np.ndarray, times: list) -> None:
    """Per axis: command and actual [mm | deg], following error [counts], DAC code."""
    for i, cfg in enumerate(scenario.axes):
        to_user = cfg.display_factor / cfg.counts_per_unit
        home = scenario.home[i] * cfg.display_factor
        dac = trace.dac[ticks, i]
        command, actual = trace.command[ticks, i], trace.actual[ticks, i]
        for name, values in (("command", command * to_user + home),
                             ("actual", actual * to_user + home),
                             ("ferr", command - actual),
                             ("dac", dac.astype(np.float64)),
                             ("saturated", ((dac <= -2048) | (dac >= 2047)).astype(np.float64))):
            rec.send_columns(f"/axes/{cfg.name}/{name}", indexes=times, columns=rr.Scalars.columns(scalars=values))


def log_events(rec: rr.RecordingStream, trace: Trace, metrics: dict) -> None:
    """Controller state changes (and the fault, if any) as text, at the tick they happened."""
    per_period = trace.period_signals.per_period("state")
    first_periods = np.flatnonzero(np.diff(per_period, prepend=-1))
    if len(first_periods) == 0:
        return
    changes = first_periods * trace.ticks_per_period  # the first tick of each period that changed state
    state = per_period[first_periods]
    texts = [f"state {STATE_NAMES.get(int(s), s)}" for s in state]
    levels = ["WARN" if s in (DspState.FEED_HOLD, DspState.STOPPING) else
              "ERROR" if s == DspState.FAULT else "INFO" for s in state]
    fault = metrics.get("fault")
    if fault:
        fault_tick = min(len(trace) - 1, math.ceil(fault["time_s"] / trace.servo_period - 1e-9))
        changes = np.append(changes, fault_tick)
        texts.append(f"fault {fault['code']}: {fault['message']}")
        levels.append("ERROR")
        order = np.argsort(changes, kind="stable")
        changes, texts, levels = changes[order], [texts[i] for i in order], [levels[i] for i in order]
    rec.send_columns("/controller/events",
                     indexes=_timelines(trace, changes),
                     columns=rr.TextLog.columns(text=texts, level=levels))


def log_latency(rec: rr.RecordingStream, scenario: Scenario, exchange_latency) -> None:
    """Exchange latency per answered exchange, at the period it answered."""
    if exchange_latency is None or len(exchange_latency[0]) == 0:
        return
    periods, latency_us = exchange_latency
    rec.send_columns("/whiteboard/exchange_latency_us",
                     indexes=[rr.TimeColumn("sim_time", duration=periods * scenario.timing.interpolation_period),
                              rr.TimeColumn("period", sequence=periods)],
                     columns=rr.Scalars.columns(scalars=latency_us))


class RunExporter:
    """Sends a run to a recording in stretches: :meth:`start`, :meth:`send` (any number of times,
    consecutive tick ranges), :meth:`finish`. ``export_run`` does all three at once; a live
    viewer gets each stretch as the run records it.

    Series are sampled at the last tick of each interpolation period; 3D poses, tool tips, feed
    and the force arrow every ``POSE_INTERVAL`` on one global grid, so stretches line up.
    """

    def __init__(self, scenario: Scenario, *, model: mujoco.MjModel | None = None):
        self.scenario = scenario
        self.model = model if model is not None else load_model(scenario.model_file)
        self.kin = _Kinematics(self.model)
        self.rec = rr.RecordingStream("cnc-twin", recording_id=str(uuid.uuid4()))
        timing = scenario.timing
        self.tpp = timing.ticks_per_period
        self.stride = max(1, round(POSE_INTERVAL / timing.interpolation_period))
        self.sent_ticks = 0
        self._tips: list[np.ndarray] = []
        self._command_tips: list[np.ndarray] = []
        self._last = None

    def start(self, *, rrd: Path | None = None, spawn: bool = False) -> None:
        """Open the sinks, log the blueprint, axes convention and static geometry."""
        blueprint = default_blueprint()
        if spawn:
            from cnc_twin.viewer import viewer_environment

            with viewer_environment():  # the viewer starts with usage analytics disabled
                self.rec.spawn(default_blueprint=blueprint)
        if rrd is not None:
            self.rec.save(str(rrd), default_blueprint=blueprint)
        self.rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        log_geometry(self.rec, self.model)

    def send(self, trace: Trace, upto: int) -> None:
        """Send ticks ``sent_ticks .. upto`` of ``trace`` (which must hold them)."""
        first = self.sent_ticks
        periods = np.arange(first // self.tpp, upto // self.tpp)
        if len(periods) == 0:
            return
        ticks = periods * self.tpp + self.tpp - 1
        if len(ticks) and ticks[-1] >= len(trace):
            ticks = ticks[ticks < len(trace)]
        self.sent_ticks = (periods[-1] + 1) * self.tpp
        sc, rec = self.scenario, self.rec
        times = _timelines(trace, ticks)
        log_axes(rec, trace, sc, ticks, times)
        rec.send_columns("/force/measured", indexes=times, columns=rr.Scalars.columns(scalars=trace.pad_force[ticks]))
        for name in ("fifo_fill", "missed_exchanges", "records_rejected"):
            rec.send_columns(f"/whiteboard/{name}", indexes=times,
                             columns=rr.Scalars.columns(scalars=trace.period_signals.per_period(name)[
                                 ticks // self.tpp].astype(np.float64)))
        pose_ticks = ticks[(ticks // self.tpp) % self.stride == 0]
        if len(pose_ticks) == 0:
            return
        pose_times = _timelines(trace, pose_ticks)
        pos, quat, tips, tool_axes = self.kin.poses(_axis_positions(trace, sc, pose_ticks, trace.actual))
        command_tips = self.kin.poses(_axis_positions(trace, sc, pose_ticks, trace.command))[2]
        log_poses(rec, self.model, pos, quat, pose_times)
        vectors = -tool_axes * (trace.pad_force[pose_ticks] * 1e-3)[:, None]  # 1 mm per N, into the work
        rec.send_columns("/force/arrow", indexes=pose_times, columns=rr.Arrows3D.columns(origins=tips, vectors=vectors))
        t = pose_ticks * trace.servo_period
        for name, pts in (("commanded", command_tips), ("actual", tips)):
            prev = self._last[name] if self._last else pts[:1]
            t_prev = self._last["t"] if self._last else t[:1] - self.stride * sc.timing.interpolation_period
            steps = np.diff(np.vstack([prev, pts]), axis=0)
            dt = np.diff(np.concatenate([t_prev, t]))
            speed = np.linalg.norm(steps, axis=1) / dt * 60e3
            rec.send_columns(f"/feed/{name}", indexes=pose_times, columns=rr.Scalars.columns(scalars=speed))
        self._last = {"commanded": command_tips[-1:], "actual": tips[-1:], "t": t[-1:]}
        self._tips.append(tips)
        self._command_tips.append(command_tips)

    def finish(self, trace: Trace, metrics: dict, exchange_latency=None) -> None:
        """Send the rest, the paths, controller events and exchange latency; flush and close."""
        self.send(trace, len(trace))
        if self._tips:
            log_paths(self.rec, self.scenario, np.vstack(self._command_tips), np.vstack(self._tips))
        log_events(self.rec, trace, metrics)
        log_latency(self.rec, self.scenario, exchange_latency)
        self.rec.flush()
        self.rec.disconnect()


def export_run(trace: Trace, scenario: Scenario, metrics: dict, *, rrd: Path | None = None,
               spawn: bool = False, model: mujoco.MjModel | None = None, exchange_latency=None) -> Path | None:
    """Write the run as a recording to ``rrd`` and/or open it in a spawned viewer.

    ``model``: the run's compiled MJCF, if at hand (otherwise compiled again from the scenario).
    """
    exporter = RunExporter(scenario, model=model)
    exporter.start(rrd=rrd, spawn=spawn)
    exporter.finish(trace, metrics, exchange_latency)
    return rrd
