"""A finished run as a rerun recording: the machine posed over time, paths, signals, events.

Entity tree (timelines ``sim_time`` [s] and ``period``)::

    /machine/<body>            Transform3D over time (world from body), from the trace's
    /machine/<body>/<geom>       encoder positions through MuJoCo's kinematics; geometry static
    /paths/commanded           tool-tip path the card commanded (LineStrips3D, static)
    /paths/actual              tool-tip path the machine made (static)
    /paths/planned             the ideal NURBS curve (curve programs, static)
    /force/arrow               pad force along the tool axis at the tip (Arrows3D over time)
    /axes/<X..C>/position      series command, actual [mm | deg]
    /axes/ferr                 series X..C, following error [counts]
    /axes/dac                  series X..C, DAC code [code]
    /axes/saturated            series X..C, 1 while the DAC is pinned at -2048 or 2047
    /feed                      series commanded, actual: tool-tip path speed [mm/min]
    /force/measured            load cell, tared [N]
    /controller/events         state changes and faults (TextLog)
    /whiteboard/counters       series fifo_fill [words], missed_exchanges, records_rejected
    /whiteboard/exchange_latency_us    DSP post -> planner answer, wall clock (recording only)

Series that share a plot share an entity (``Scalars`` with one value per series and row, named
by a static ``SeriesLines``): rerun's cost is mostly per ``send_columns`` call, so 12 calls per
stretch instead of 39 halve the export. Everything time-varying goes in bulk through
``send_columns`` (one call per entity and stretch). Series are sampled at the last tick of each
interpolation period (:class:`~cnc_twin.trace.trace.PeriodSamples`: all an export reads of a run),
body poses every ``POSE_INTERVAL``.
:func:`export_run` sends a finished run in one stretch; :mod:`cnc_twin.view.rerun_stream` streams a
run in progress to a recording process, stretch by stretch, with the same result.
"""

from __future__ import annotations

import math
import sys
import uuid
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from cnc_twin.core.axes import AXES, joint_name
from cnc_twin.core.config import Scenario
from cnc_twin.core.axes import HOME_KEYFRAME
from cnc_twin.machine.model_file import load_model
from cnc_twin.trace.trace import PeriodSamples, Trace
from cnc_twin.view.path_views import camera_on, plane_paths, planes_moved, program_strips
from cnc_twin.whiteboard.status import DspState

PLANNED = object()
"""default of ``RunExporter.start(planned=)``: compute the planned path from the scenario"""
POSE_INTERVAL = 0.004
"""3D poses, paths and the force arrow: one sample per 4 ms at most (the eye needs no more)"""
STATE_NAMES = DspState.NAMES


def default_blueprint(views: list[PathView] = (), camera: tuple[np.ndarray, np.ndarray] | None = None,
                      figures: list[str] = ()) -> rrb.Blueprint:
    """3D machine view (its camera on ``camera``: eye, target [m], if given), the plane views of
    the path (``views``) and the run's plots (``figures``: names under ``/figures``) and the
    event log on the left; time series grouped by concern on the right."""
    position = [rrb.TimeSeriesView(name=f"{a} command / actual", origin=f"/axes/{a}",
                                   contents=[f"/axes/{a}/position"]) for a in AXES]
    ferr = rrb.TimeSeriesView(name="following error [counts]", origin="/axes", contents=["/axes/ferr"])
    dac = rrb.TimeSeriesView(name="DAC [code] and saturation", origin="/axes",
                             contents=["/axes/dac", "/axes/saturated"])
    eye = None if camera is None else rrb.EyeControls3D(position=camera[0], look_target=camera[1], eye_up=[0, 0, 1])
    machine = rrb.Spatial3DView(name="machine", origin="/", contents=["/machine/**", "/paths/**", "/force/arrow"],
                                eye_controls=eye)
    plane_views = [rrb.Spatial2DView(name=f"{v.plane} path [mm], contour error x{v.factor}",
                                     origin=f"/path_views/{v.plane}") for v in views]
    plane_views += [rrb.Spatial2DView(name=name, origin=f"/figures/{name}") for name in figures]
    left = [machine] + ([rrb.Horizontal(*plane_views)] if plane_views else []) + \
        [rrb.TextLogView(name="controller", origin="/controller")]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(*left, row_shares=[3, 3, 1] if plane_views else [3, 1]),
            rrb.Vertical(
                rrb.Grid(*position),
                rrb.Horizontal(ferr, dac),
                rrb.Horizontal(
                    rrb.TimeSeriesView(name="feed [mm/min]", origin="/feed"),
                    rrb.TimeSeriesView(name="pad force [N]", origin="/force", contents=["/force/measured"]),
                    rrb.TimeSeriesView(name="whiteboard", origin="/whiteboard",
                                       contents=["/whiteboard/counters"]),
                    rrb.TimeSeriesView(name="exchange latency [us]", origin="/whiteboard",
                                       contents=["/whiteboard/exchange_latency_us"]),
                ),
                row_shares=[3, 2, 2],
            ),
            column_shares=[2, 3],
        ),
        collapse_panels=True,
    )


def _timelines(ticks: np.ndarray, servo_period: float, ticks_per_period: int) -> list:
    return [rr.TimeColumn("sim_time", duration=ticks * servo_period),
            rr.TimeColumn("period", sequence=ticks // ticks_per_period)]


def _axis_positions(scenario: Scenario, counts: np.ndarray) -> np.ndarray:
    """Axis positions [m | rad] from counts (command or actual), shape (n, 6)."""
    counts_per_unit = np.array([a.counts_per_unit for a in scenario.axes])
    return counts / counts_per_unit + np.asarray(scenario.home)


class _Kinematics:
    """Replays axis positions through the model: body poses and the tool tip.

    ``compiled``: one numba call per batch (:mod:`cnc_twin.view.pose_replay`) where it works, else a
    Python loop around the same ``mj_kinematics`` calls (the same numbers, bit for bit).
    """

    def __init__(self, model: mujoco.MjModel, *, compiled: bool = True):
        if compiled:
            from cnc_twin.machine import mujoco_c  # imports numba: only where compiled replay is wanted

            compiled = mujoco_c.available()
        self.compiled = compiled
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
        if self.compiled:  # the same mj_kinematics calls, without a Python loop
            from cnc_twin.machine.mujoco_c import address
            from cnc_twin.view.pose_replay import replay

            replay(address(m), address(d), np.ascontiguousarray(q, dtype=np.float64), np.asarray(self.adr),
                    d.qpos, d.xpos, d.xquat, d.site_xpos, d.site_xmat, self.tool, pos, quat, tips, axes)
            return pos, quat, tips, axes
        for k in range(n):
            d.qpos[self.adr] = q[k]
            mujoco.mj_kinematics(m, d)
            pos[k], quat[k] = d.xpos, d.xquat
            tips[k] = d.site_xpos[self.tool]
            axes[k] = d.site_xmat[self.tool].reshape(3, 3)[:, 2]
        return pos, quat, tips, axes


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


COMMANDED_RGB, ACTUAL_RGB, PLANNED_RGB = (60, 120, 255), (255, 140, 0), (40, 200, 80)
"""the paths' colours, in 3D and in the plane views"""


@dataclass(frozen=True)
class PathView:
    """One plane view of the path: its plane, the contour error's magnification, the largest
    contour error in that plane [um]."""

    plane: str
    factor: int
    largest_um: float


def log_paths(rec: rr.RecordingStream, command_tips: np.ndarray, actual_tips: np.ndarray,
              on_path: np.ndarray) -> tuple[list[PathView], np.ndarray]:
    """Commanded and actual tool-tip paths in 3D [m], and in the planes the program's path moves in
    [mm] (``/path_views/<plane>``, the actual path's contour error magnified; ``on_path``: per tip
    sample, whether the card was on the program's path, see
    :func:`~cnc_twin.view.path_views.program_strips`). Returns the plane views and the commanded
    points they draw [m] (for the camera)."""
    rec.log("/paths/commanded", rr.LineStrips3D([command_tips], colors=[COMMANDED_RGB], radii=[0.0006]), static=True)
    rec.log("/paths/actual", rr.LineStrips3D([actual_tips], colors=[ACTUAL_RGB], radii=[0.0004]), static=True)
    strips = program_strips(command_tips, actual_tips, on_path)
    drawn = np.vstack([command for command, _ in strips]) if strips else command_tips
    views = []
    up = np.array([1.0, -1.0])  # rerun's 2D views point their vertical axis down
    for plane in planes_moved(drawn):
        commands, actuals, factor, largest = plane_paths(strips, plane)
        rec.log(f"/path_views/{plane}/commanded", rr.LineStrips2D([c * up for c in commands], colors=[COMMANDED_RGB],
                                                                   radii=rr.Radius.ui_points(1.5)), static=True)
        rec.log(f"/path_views/{plane}/actual", rr.LineStrips2D([a * up for a in actuals], colors=[ACTUAL_RGB],
                                                                radii=rr.Radius.ui_points(1.5)), static=True)
        views.append(PathView(plane, factor, largest * 1e3))
    return views, drawn


def log_planned_path(rec: rr.RecordingStream, points: np.ndarray | None) -> None:
    """``points`` from :func:`~cnc_twin.geometry.tip_path.planned_path`, if any."""
    if points is not None:
        rec.log("/paths/planned", rr.LineStrips3D([points], colors=[PLANNED_RGB], radii=[0.0003]), static=True)


WHITEBOARD_COUNTERS = ("fifo_fill", "missed_exchanges", "records_rejected")
"""the per-period whiteboard signals in ``/whiteboard/counters``, in this order"""


def log_series_names(rec: rr.RecordingStream, scenario: Scenario) -> None:
    """Static names of the series that share an entity (one per value in a row)."""
    names = {"/feed": ["commanded", "actual"], "/axes/ferr": list(AXES), "/axes/dac": list(AXES),
             "/axes/saturated": [f"{a} saturated" for a in AXES], "/whiteboard/counters": list(WHITEBOARD_COUNTERS)}
    for a in scenario.axes:
        names[f"/axes/{a.name}/position"] = [f"{a.name} command [{a.display_unit}]", f"{a.name} actual [{a.display_unit}]"]
    for path, series in names.items():
        rec.log(path, rr.SeriesLines(names=series), static=True)


def log_axes(rec: rr.RecordingStream, samples: PeriodSamples, scenario: Scenario, times: list) -> None:
    """Per axis command and actual [mm | deg]; following error [counts], DAC code and saturation
    of all axes."""
    counts_per_unit = np.array([a.counts_per_unit for a in scenario.axes])
    display = np.array([a.display_factor for a in scenario.axes])
    to_user, home = display / counts_per_unit, np.asarray(scenario.home) * display
    command = samples.command * to_user + home
    actual = samples.actual * to_user + home
    for i, cfg in enumerate(scenario.axes):
        rec.send_columns(f"/axes/{cfg.name}/position", indexes=times,
                         columns=rr.Scalars.columns(scalars=np.column_stack([command[:, i], actual[:, i]])))
    dac = samples.dac
    for name, values in (("ferr", samples.command - samples.actual),
                         ("dac", dac.astype(np.float64)),
                         ("saturated", ((dac <= -2048) | (dac >= 2047)).astype(np.float64))):
        rec.send_columns(f"/axes/{name}", indexes=times, columns=rr.Scalars.columns(scalars=values))


def log_events(rec: rr.RecordingStream, scenario: Scenario, per_period: np.ndarray, n_ticks: int,
               metrics: dict) -> None:
    """Controller state changes (and the fault, if any) as text, at the tick they happened.

    ``per_period``: the state of every period; ``n_ticks``: ticks the run recorded.
    """
    tpp, servo_period = scenario.timing.ticks_per_period, scenario.timing.servo_period
    first_periods = np.flatnonzero(np.diff(per_period, prepend=-1))
    if len(first_periods) == 0:
        return
    changes = first_periods * tpp  # the first tick of each period that changed state
    state = per_period[first_periods]
    texts = [f"state {STATE_NAMES.get(int(s), s)}" for s in state]
    levels = ["WARN" if s in (DspState.FEED_HOLD, DspState.STOPPING) else
              "ERROR" if s == DspState.FAULT else "INFO" for s in state]
    fault = metrics.get("fault")
    if fault:
        fault_tick = min(n_ticks - 1, math.ceil(fault["time_s"] / servo_period - 1e-9))
        changes = np.append(changes, fault_tick)
        texts.append(f"fault {fault['code']}: {fault['message']}")
        levels.append("ERROR")
        order = np.argsort(changes, kind="stable")
        changes, texts, levels = changes[order], [texts[i] for i in order], [levels[i] for i in order]
    rec.send_columns("/controller/events",
                     indexes=_timelines(changes, servo_period, tpp),
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
    """Sends a run to a recording in stretches: :meth:`~RunExporter.start`, :meth:`~RunExporter.send`
    (any number of times, consecutive stretches of :class:`~cnc_twin.trace.trace.PeriodSamples`),
    :meth:`~RunExporter.finish`. ``export_run`` does all
    three at once; :mod:`cnc_twin.view.rerun_stream` feeds one in its own process during the run.

    Series are sampled at the last tick of each interpolation period; 3D poses, tool tips, feed
    and the force arrow every ``POSE_INTERVAL`` on one global grid of periods, so the recording
    is the same however the run is cut into stretches.
    """

    def __init__(self, scenario: Scenario, *, model: mujoco.MjModel | None = None, compiled: bool = True):
        self.scenario = scenario
        self.model = model if model is not None else load_model(scenario.model_file)
        self.kin = _Kinematics(self.model, compiled=compiled)
        self.rec = rr.RecordingStream("cnc-twin", recording_id=str(uuid.uuid4()))
        timing = scenario.timing
        self.tpp = timing.ticks_per_period
        self.servo_period = timing.servo_period
        self.stride = max(1, round(POSE_INTERVAL / timing.interpolation_period))
        self.sent_periods = 0
        """the periods sent so far: the next stretch starts at this period"""
        self._states: list[np.ndarray] = []
        self._tips: list[np.ndarray] = []
        self._command_tips: list[np.ndarray] = []
        self._on_path: list[np.ndarray] = []
        self._last = None

    def start(self, *, rrd: Path | None = None, spawn: bool = False, planned=PLANNED) -> None:
        """Open the sinks (a file, a spawned viewer, or both), log the blueprint, axes convention
        and static geometry. ``planned``: the planned path if already computed (see
        :func:`~cnc_twin.geometry.tip_path.planned_path`; a recording process gets it so that it needs
        no scipy)."""
        if planned is PLANNED:
            from cnc_twin.geometry.tip_path import planned_path

            planned = planned_path(self.scenario)
        # framed on the planned path where there is one; :meth:`finish` frames the path as run
        blueprint = default_blueprint(camera=None if planned is None else camera_on(planned))
        if spawn:
            from cnc_twin.view.viewer import rerun_command, viewer_environment

            binary = rerun_command()[0]  # this environment's viewer, whether or not it is on PATH
            with viewer_environment():  # the viewer starts with usage analytics disabled
                rr.spawn(connect=False, executable_path=binary if binary != sys.executable else None)
            sinks = [rr.GrpcSink()] + ([rr.FileSink(str(rrd))] if rrd is not None else [])
            self.rec.set_sinks(*sinks, default_blueprint=blueprint)
        elif rrd is not None:
            self.rec.save(str(rrd), default_blueprint=blueprint)
        self.rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        log_geometry(self.rec, self.model)
        log_planned_path(self.rec, planned)
        log_series_names(self.rec, self.scenario)
        if self.kin.compiled:  # load the compiled replay now, before the first stretch
            self.kin.poses(np.asarray([self.scenario.home], dtype=np.float64))

    def send(self, samples: PeriodSamples) -> None:
        """Send the next stretch (it must start at period :attr:`sent_periods`)."""
        if samples.first != self.sent_periods:
            raise ValueError(f"stretch starts at period {samples.first}, expected {self.sent_periods}")
        if len(samples) == 0:
            return
        self.sent_periods += len(samples)
        self._states.append(samples.periods["state"])
        sc, rec, tpp = self.scenario, self.rec, self.tpp
        periods = samples.first + np.arange(len(samples))
        ticks = periods * tpp + (tpp - 1)
        times = _timelines(ticks, self.servo_period, tpp)
        log_axes(rec, samples, sc, times)
        rec.send_columns("/force/measured", indexes=times, columns=rr.Scalars.columns(scalars=samples.pad_force))
        counters = np.column_stack([samples.periods[name] for name in WHITEBOARD_COUNTERS]).astype(np.float64)
        rec.send_columns("/whiteboard/counters", indexes=times, columns=rr.Scalars.columns(scalars=counters))
        posed = np.flatnonzero(periods % self.stride == 0)
        if len(posed) == 0:
            return
        pose_ticks = ticks[posed]
        pose_times = _timelines(pose_ticks, self.servo_period, tpp)
        pos, quat, tips, tool_axes = self.kin.poses(_axis_positions(sc, samples.actual[posed]))
        command_tips = self.kin.poses(_axis_positions(sc, samples.command[posed]))[2]
        log_poses(rec, self.model, pos, quat, pose_times)
        force = samples.pad_force[posed]
        vectors = -tool_axes * (force * 1e-3)[:, None]  # 1 mm per N, into the work
        rec.send_columns("/force/arrow", indexes=pose_times, columns=rr.Arrows3D.columns(origins=tips, vectors=vectors))
        t = pose_ticks * self.servo_period
        speeds = []
        for name, pts in (("commanded", command_tips), ("actual", tips)):
            prev = self._last[name] if self._last else pts[:1]
            t_prev = self._last["t"] if self._last else t[:1] - self.stride * sc.timing.interpolation_period
            steps = np.diff(np.vstack([prev, pts]), axis=0)
            dt = np.diff(np.concatenate([t_prev, t]))
            speeds.append(np.linalg.norm(steps, axis=1) / dt * 60e3)
        rec.send_columns("/feed", indexes=pose_times, columns=rr.Scalars.columns(scalars=np.column_stack(speeds)))
        self._last = {"commanded": command_tips[-1:], "actual": tips[-1:], "t": t[-1:]}
        self._tips.append(tips)
        self._command_tips.append(command_tips)
        self._on_path.append(samples.periods["path_u"][posed] >= 0)

    def finish(self, n_ticks: int, metrics: dict, exchange_latency=None, figures: dict[str, bytes] | None = None
               ) -> None:
        """After the last stretch: the paths, controller events, exchange latency and the run's
        plots (``figures``: PNG bytes by name, as ``/figures/<name>``); flush and close.
        ``n_ticks``: ticks the run recorded."""
        figures = figures or {}
        for name, png in figures.items():
            self.rec.log(f"/figures/{name}", rr.EncodedImage(contents=png, media_type="image/png"), static=True)
        if self._tips:
            views, drawn = log_paths(self.rec, np.vstack(self._command_tips), np.vstack(self._tips),
                                     np.concatenate(self._on_path))
            # the layout again, now that the path is known: the camera on it, its plane views
            self.rec.send_blueprint(default_blueprint(views, camera_on(drawn), list(figures)), make_active=True,
                                    make_default=True)
        states = np.concatenate(self._states) if self._states else np.empty(0, np.int8)
        log_events(self.rec, self.scenario, states, n_ticks, metrics)
        log_latency(self.rec, self.scenario, exchange_latency)
        self.rec.disconnect()  # flushes and closes the sinks (a flush before it only costs time)


def export_run(trace: Trace, scenario: Scenario, metrics: dict, *, rrd: Path | None = None,
               spawn: bool = False, model: mujoco.MjModel | None = None, exchange_latency=None,
               figures: dict[str, bytes] | None = None) -> Path | None:
    """Write the run as a recording to ``rrd`` and/or open it in a spawned viewer.

    ``model``: the run's compiled MJCF, if at hand (otherwise compiled again from the scenario).
    """
    exporter = RunExporter(scenario, model=model)
    exporter.start(rrd=rrd, spawn=spawn)
    for piece in trace.chunks():  # a long run's file a piece at a time
        exporter.send(PeriodSamples.whole(piece))
    exporter.finish(len(trace), metrics, exchange_latency, figures)
    return rrd
