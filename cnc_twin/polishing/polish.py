"""The twin's side of a surface polishing run: the workpiece model, the removal map, the metrics.

During the run, every ``preston.every`` interpolation periods, :class:`RemovalTracker` reads the
machine as MuJoCo has it (pad face centre and tool axis from the ``tool_site`` / ``pad`` frames,
the pad's linear and angular velocity, the normal force of every pad-workpiece contact) and adds
that interval's Preston removal to the map (:mod:`cnc_twin.polishing.removal`). It is the physics' truth,
not the card's measurement: the load cell and its ADC are what the force loop sees.

Metrics (``metrics.json`` key ``polish``): force tracking once the ramp is over (RMS and largest
error, % of the setpoint), the overshoot at first contact, time at reduced feed, and the removal
map's volume and uniformity, with the Preston integral for the whole run as a cross-check.
"""

from __future__ import annotations

import math
import time
from typing import Any

import mujoco
import numpy as np

from cnc_twin.core.config import Preston, SurfaceProgram
from cnc_twin.dsp.force import ForceState
from cnc_twin.motion.scurve import ramp_distance
from cnc_twin.geometry.surface import NurbsSurface, parameter_scales
from cnc_twin.trace.trace import Trace
from cnc_twin.polishing import removal_kernel as rk
from cnc_twin.polishing.removal import Patch, PrestonModel, RemovalGrid, sequential_sum, sliding_speed

CONTACT_SETTLE = 0.3
"""after the ramp, time within which the first-contact overshoot is judged [s]"""


def removal_grid(surface: NurbsSurface, spacing: float, scales: tuple[float, float]) -> tuple[RemovalGrid, np.ndarray]:
    """Points about ``spacing`` apart on the surface (cell centres of a (u, v) grid), and their
    (u, v), shape (m, 2). ``scales``: the surface's mean ``|S_u|``, ``|S_v|``
    (:func:`cnc_twin.geometry.surface.parameter_scales`)."""
    lu, lv = scales
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    nu = max(2, math.ceil((u1 - u0) * lu / spacing))
    nv = max(2, math.ceil((v1 - v0) * lv / spacing))
    du, dv = (u1 - u0) / nu, (v1 - v0) / nv
    # rows along v, columns along u: drawn as an image, u runs across like x on the plate grid
    u, v = np.meshgrid(u0 + du * (np.arange(nu) + 0.5), v0 + dv * (np.arange(nv) + 0.5), indexing="xy")
    u, v = u.ravel(), v.ravel()
    d = surface.derivatives(u, v, 1)
    cross = np.cross(d[(1, 0)], d[(0, 1)])
    points = d[(0, 0)]
    grid = RemovalGrid(points=points, normals=surface.normal(u, v), areas=np.linalg.norm(cross, axis=1) * du * dv,
                       shape=(nv, nu), extent=(float(points[:, 0].min()), float(points[:, 0].max()),
                                               float(points[:, 1].min()), float(points[:, 1].max())))
    return grid, np.column_stack([u, v])


class RemovalTracker:
    """Accumulates the removal map from the MuJoCo state during a run.

    The figures it keeps (``totals``, float64, indexed as in
    :mod:`cnc_twin.polishing.removal_kernel`): contact time [s], the integral of the contact force
    [N s], updates, their wall-clock cost [ns], and the most pad contacts seen at once.
    """

    def __init__(self, preston: Preston, friction: float | None, surface: NurbsSurface, model: mujoco.MjModel,
                 data: mujoco.MjData, period: float, *, compiled: bool = True, grid: tuple | None = None):
        """``friction``: the pad's sliding friction coefficient on the workpiece; None = the model's.
        ``compiled``: each update in one compiled call (:func:`~cnc_twin.polishing.removal_kernel.tracker_update`);
        False: the numpy reference (the same numbers bit for bit). ``grid``: ``(scales, grid, uv)``
        as made for this surface and ``preston.grid_spacing`` already (else made here)."""
        from cnc_twin.machine import mujoco_c
        from cnc_twin.machine.workpiece import PAD_CONTACT_FIELDS, PAD_CONTACTS, pad_friction

        p = preston
        self.compiled = compiled and mujoco_c.available()
        self.surface = surface
        if grid is None:
            scales = parameter_scales(self.surface)[:2]
            grid = (scales, *removal_grid(self.surface, p.grid_spacing, scales))
        self.scales, self.grid, self.uv = grid
        self.model_removal = removal = PrestonModel(self.grid, preston_k=p.k, pad_radius=p.pad_radius,
                                                    pad_modulus=p.pad_modulus)
        self.model, self.data = model, data
        self.friction = friction if friction is not None else pad_friction(model)
        self.dt = p.every * period
        self.every = p.every
        self._site = model.site("tool_site").id
        self._pad_body = model.body("pad").id
        sensor = model.sensor(PAD_CONTACTS).id
        self._velocity = np.zeros(6)
        self.totals = np.zeros(rk.N_TOTALS)
        self.ids = np.array([self._site, self._pad_body, model.sensor_adr[sensor], model.sensor_intprm[sensor, 2],
                             PAD_CONTACT_FIELDS], dtype=np.int64)
        """the tool site, the pad body, the pad's contact sensor (its address in ``sensordata``, its
        slots, the values per slot), indexed as in :mod:`~cnc_twin.polishing.removal_kernel`"""
        params = np.zeros(rk.N_PARAMS)
        params[[rk.RADIUS, rk.SLAB, rk.MODULUS, rk.K_DT, rk.MU, rk.FRICTION_SPEED, rk.DT]] = (
            removal.pad_radius, removal.slab, removal.pad_modulus, removal.preston_k * self.dt, self.friction,
            FRICTION_SPEED, self.dt)
        params[[rk.BALL_R2, rk.MARGIN2]] = removal.ball_limits
        self.params = params
        points = len(self.grid.points)
        # the compiled update's ball of candidates: indices, packed rows, centre and size
        self._ball_idx, self._ball = np.zeros(points, dtype=np.intp), np.zeros((7, points))
        self._ball_state = np.array([np.inf, np.inf, np.inf, 0.0])
        self._boxes = rk.chunk_boxes(removal.packed)

    @property
    def calls(self) -> int:
        """updates so far"""
        return int(self.totals[rk.CALLS])

    @property
    def cost_ns(self) -> float:
        """their wall-clock cost [ns]"""
        return float(self.totals[rk.COST_NS])

    @property
    def force_time_integral(self) -> float:
        """integral of the pad's contact normal force over time [N s]"""
        return float(self.totals[rk.FORCE_TIME])

    @property
    def contact_time(self) -> float:
        """time with a contact patch [s]"""
        return float(self.totals[rk.CONTACT_TIME])

    def finished_map(self) -> PrestonModel:
        """The removal map, its contact time the run's (the compiled update keeps it in ``totals``)."""
        self.model_removal.contact_time = self.contact_time
        return self.model_removal

    def kernel_args(self, *, copies: bool = False) -> tuple:
        """The arguments of :func:`~cnc_twin.polishing.removal_kernel.tracker_update`; with
        ``copies``, copies of every array it writes (the pad's applied wrench, the map, the ball,
        the velocity, the totals), so a call changes nothing of the run's."""
        d = self.data
        written = (d.xfrc_applied, self.model_removal.depth, self._ball_idx, self._ball, self._ball_state,
                   self._velocity, self.totals)
        xfrc, depth, ball_idx, ball, ball_state, velocity, totals = (
            tuple(a.copy() for a in written) if copies else written)
        from cnc_twin.machine.mujoco_c import address

        return (address(self.model), address(d), d.sensordata, d.xmat, d.site_xpos, d.xipos, xfrc, self.ids,
                self.params, self.model_removal.packed, self._boxes, depth, ball_idx, ball, ball_state, velocity,
                totals)

    def contact_force(self) -> float:
        """Normal force of the pad's contacts along the tool axis [N] (a contact on a tile's side
        face, pushing sideways, does not press the pad onto the surface): from the pad's contact
        sensor, slot by slot in MuJoCo's contact order (what ``mj_contactForce`` gives per contact)."""
        adr, slots, fields = (int(x) for x in self.ids[[rk.SENSOR_ADR, rk.SLOTS, rk.FIELDS]])
        sd = self.data.sensordata
        ax = self.data.xmat[self._pad_body]
        found = int(sd[adr])
        self.totals[rk.MOST_CONTACTS] = max(self.totals[rk.MOST_CONTACTS], found)
        total = 0.0
        for i in range(min(found, slots)):
            base = adr + fields * i
            total += sd[base + 1] * abs((sd[base + 4] * ax[2] + sd[base + 5] * ax[5]) + sd[base + 6] * ax[8])
        return float(total)

    def update(self) -> None:
        """Add the removal of the last ``every`` periods (called once per such interval)."""
        started = time.perf_counter_ns()
        if self.compiled:
            rk.tracker_update(*self.kernel_args())
        else:
            self._update_reference()
        self.totals[rk.COST_NS] += time.perf_counter_ns() - started

    def _update_reference(self) -> None:
        d = self.data
        force = self.contact_force()
        wrench = d.xfrc_applied[self._pad_body]
        wrench[:] = 0.0
        if force > 0.0:
            mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_SITE, self._site, self._velocity, 0)
            tip = d.site_xpos[self._site]
            axis = d.xmat[self._pad_body].reshape(3, 3)[:, 2]
            removal = self.model_removal
            patch = removal.patch(tip, axis, force, self._velocity[3:], self._velocity[:3])
            if patch is not None:
                removal.add(patch, self.dt)
                self.totals[rk.CONTACT_TIME] += self.dt
                wrench[:] = friction_wrench(patch, removal.grid.areas, tip, d.xipos[self._pad_body], self.friction)
            self.totals[rk.FORCE_TIME] += force * self.dt
        self.totals[rk.CALLS] += 1.0

    def warm_up(self) -> None:
        """Compile (or load) the compiled update before the run's clock starts: one update of the
        machine as it stands (the run's types), into copies of everything it writes."""
        if self.compiled:
            rk.tracker_update(*self.kernel_args(copies=True))


FRICTION_SPEED = 1e-3
"""sliding speed below which the pad's friction fades linearly to zero (regularisation) [m/s]"""


def friction_wrench(patch: Patch, areas: np.ndarray, tip: np.ndarray, centre: np.ndarray, mu: float) -> np.ndarray:
    """Force and torque (6,) [N, N m] about ``centre`` (world frame) of the pad's sliding friction
    over its contact patch (the removal model's Winkler pressures): ``-mu p A v / max(|v|,
    FRICTION_SPEED)`` per point, ``v`` the pad's tangential sliding velocity there; ``areas`` the
    grid's point areas [m^2]."""
    v = patch.sliding
    f = v * (-mu * patch.pressure * areas[patch.index] / np.maximum(sliding_speed(v), FRICTION_SPEED))
    arm = patch.arm + (np.asarray(tip) - np.asarray(centre))[:, None]
    # sums term by term in order, as the compiled patch adds them (removal_kernel)
    return np.array([sequential_sum(f[0]), sequential_sum(f[1]), sequential_sum(f[2]),
                     sequential_sum(arm[1] * f[2] - arm[2] * f[1]), sequential_sum(arm[2] * f[0] - arm[0] * f[2]),
                     sequential_sum(arm[0] * f[1] - arm[1] * f[0])])


def polished_band(program: SurfaceProgram, uv: np.ndarray, scales: tuple[float, float]) -> np.ndarray:
    """Mask of the grid points in the raster's *middle band*: along the passes, farther from
    their ends than the pad radius plus the feed's ramp distance; across, from the first pass plus
    the pad radius to the last minus it. There every point saw every pass that reaches it at full
    feed (no start, stop or turn nearby), so the removal there shows the raster's own uniformity.
    For a spiral: the annulus between the pad radius from the start and the pad radius from the
    outer turn. ``scales`` as for :func:`removal_grid`."""
    lu, lv = scales
    pts = np.concatenate([np.asarray(c.control_points) for c in program.sections])
    r = program.preston.pad_radius
    x, y = uv[:, 0] * lu, uv[:, 1] * lv
    px, py = pts[:, 0] * lu, pts[:, 1] * lv
    if program.pattern == "spiral":
        cx, cy = 0.5 * (px.min() + px.max()), 0.5 * (py.min() + py.max())
        rho = np.hypot(x - cx, y - cy)
        outer = min(px.max() - cx, py.max() - cy)
        return (rho >= r) & (rho <= outer - r)
    along, across, p_along, p_across = (x, y, px, py) if program.direction == "u" else (y, x, py, px)
    # along the passes: clear of the turns by the pad radius plus the distance the feed needs to
    # come up to speed after one (and down before the next)
    lim = program.limits
    ramp = ramp_distance(lim.feed, 0.0, lim.tangential_acceleration, lim.tangential_jerk)
    a_lo, a_hi = p_along.min() + r + ramp, p_along.max() - r - ramp
    # across: the turns' control points bulge no further than the passes
    return (along >= a_lo) & (along <= a_hi) & (across >= p_across.min() + r) & (across <= p_across.max() - r)


def force_metrics(trace: Trace, setpoint_n: float) -> dict[str, Any]:
    """Force tracking after the ramp, and the overshoot at first contact (``setpoint_n``: the
    programmed force [N], reported as it is; tracking is judged against the setpoint in effect in
    each period). Read a piece of the trace at a time (a run of hours is not held whole): the
    sums of each piece are added exactly."""
    servo_period = trace.servo_period
    settle = int(CONTACT_SETTLE / servo_period) if servo_period > 0 else 0
    sums = {"e2": [], "rel2": [], "force": []}
    worst_rel, tracked, reduced = 0.0, 0, 0
    first_ramp = first_track = None  # [tick]
    peak = -np.inf  # the force's peak from the first ramp to CONTACT_SETTLE after the first tracking
    for piece in trace.chunks():
        signals = piece.period_signals
        state, force = signals["force_state"], piece.pad_force
        track = state == ForceState.TRACK
        if first_ramp is None and np.any(state == ForceState.RAMP):
            first_ramp = piece.first + int(np.argmax(state == ForceState.RAMP))
        if first_track is None and np.any(track):
            first_track = piece.first + int(np.argmax(track))
            goal = float(signals["force_setpoint"][first_track - piece.first])  # the setpoint it tracks first
        if first_ramp is not None:
            stop = len(piece) if first_track is None else first_track + settle - piece.first
            window = force[max(0, first_ramp - piece.first):max(0, stop)]
            if len(window):
                peak = max(peak, float(np.max(window)))
        if not np.any(track):
            continue
        setpoint = signals["force_setpoint"][track]
        e = force[track] - setpoint
        rel = e / np.maximum(setpoint, 1e-9)
        sums["e2"].append(float(np.sum(e * e)))
        sums["rel2"].append(float(np.sum(rel * rel)))
        sums["force"].append(float(np.sum(force[track])))
        worst_rel = max(worst_rel, float(np.max(np.abs(rel))))
        tracked += int(np.count_nonzero(track))
        reduced += int(np.count_nonzero(signals["feed_factor"][track] < 1.0))
    out: dict[str, Any] = {"setpoint_n": setpoint_n}
    if not tracked:
        out["tracking"] = None
        return out
    out["tracking"] = {
        "rms_error_n": float(np.sqrt(math.fsum(sums["e2"]) / tracked)),
        "rms_error_pct": float(100.0 * np.sqrt(math.fsum(sums["rel2"]) / tracked)),
        "max_error_pct": float(100.0 * worst_rel),
        "mean_force_n": math.fsum(sums["force"]) / tracked,
        "time_s": float(tracked * servo_period),
    }
    if first_ramp is not None and first_ramp < first_track + settle:
        out["first_contact"] = {"time_s": float(first_ramp * servo_period), "peak_n": peak,
                                "overshoot_pct": float(100.0 * max(0.0, peak - goal) / goal)}
    out["reduced_feed_s"] = float(reduced * servo_period)
    return out


def removal_metrics(tracker: RemovalTracker, wall_time: float, band: np.ndarray | None = None) -> dict[str, Any]:
    """Volume and uniformity of the removal map, and the model's cost. ``band``: mask of the grid
    points whose uniformity counts (:func:`polished_band`); None = no such band."""
    model = tracker.model_removal
    touched_band = None if band is None else band & (model.depth > 0)
    out: dict[str, Any] = {
        "volume_mm3": model.volume() * 1e9,
        "touched": model.stats(),
        "middle_band": model.stats(touched_band) if touched_band is not None and np.any(touched_band) else None,
        "contact_time_s": tracker.contact_time,
        "most_pad_contacts": int(tracker.totals[rk.MOST_CONTACTS]),
        "force_time_integral_ns": tracker.force_time_integral,
        "grid_points": int(len(model.depth)),
        "updates": tracker.calls,
        "cost_us_per_update": tracker.cost_ns / max(1, tracker.calls) / 1e3,
        "cost_fraction_of_run": tracker.cost_ns / 1e9 / wall_time if wall_time > 0 else None,
        "preston_k": tracker.model_removal.preston_k,
    }
    return out


def preston_by_hand(trace: Trace, preston: Preston, spindle_speed: float) -> float:
    """Removed volume [m^3] by Preston's law in closed form: a flat pad of radius R spinning at
    the programmed speed w under the force setpoint, pressure uniform, feed negligible against
    the pad's own sliding speed (mean over the disc of w r = 2 w R / 3; ``spindle_speed`` w
    [rad/s])::

        V = k (2 w R / 3) integral F*(t) dt      over the ramps and the tracking

    The cross-check of the removal map on a flat plate (on a curved face the pressure is not
    uniform, and the formula does not apply)."""
    impulse = []
    for piece in trace.chunks():  # a piece at a time: a run of hours is not held whole
        state = piece.period_signals["force_state"]
        active = (state == ForceState.RAMP) | (state == ForceState.TRACK) | (state == ForceState.RAMP_DOWN)
        impulse.append(float(np.sum(piece.period_signals["force_setpoint"][active])))
    dt = trace.servo_period if len(trace) > 1 else 0.0
    impulse = math.fsum(impulse) * dt
    return preston.k * 2.0 * abs(spindle_speed) * preston.pad_radius / 3.0 * impulse
