"""Look-ahead feed planning for a NURBS tool path: limit curve, critical points, S-curve blocks.

1. Sample the curve densely in arc length ``s`` (``s`` by Gauss-Legendre quadrature). At each
   sample the feed limit is the smallest of::

       programmed feed F
       chord error      (2 / T) sqrt(rho^2 - (rho - delta)^2),   rho = 1 / kappa
       normal accel     sqrt(A_n / kappa)
       normal jerk      (J_n / kappa^2)^(1/3)
       axis velocity    v_i / |t_i|                      t = dC/ds (unit tangent)
       axis accel       sqrt(0.5 a_i / |C_ss,i|)         C_ss = d2C/ds2 (half the budget: normal)
       axis jerk        (j_i / 3 / |C_sss,i|)^(1/3)  and  j_i / (9 A_t |C_ss,i|)
       curvature jump   sqrt(j_i T / |dC_ss,i|)   at a knot where C_ss jumps (a quadratic, a
                        repeated knot): the axis acceleration steps there within one period

   with the tangential limits ``A_t = min(A_path, 0.5 min_i a_i)`` and
   ``J_t = min(J_path, min_i j_i / 3)``, so the tangential and normal parts of every axis's
   acceleration and jerk add up to at most its limit. ``A_t`` trades ramps against turns:
   the second axis-jerk term lets a tight turn through faster with a smaller budget, and on a
   curve of many turns (CAM links, the published benchmark curves) a share of it runs 5-25 %
   faster. So each curve is tried with the shares :data:`BUDGET_SHARES` of the full budget and
   planned with the one of the least estimated time (:func:`traverse_time`, a rest-to-rest
   pass at the limit); the full budget unless a share saves :data:`BUDGET_GAIN` of it. Every
   limit holds whichever share is taken: the S-curve blocks ramp with that same ``A_t``.
2. Critical points: the local minima of the limit where it binds, plus start and end (at rest).
3. Bidirectional scan: each critical speed is lowered until a jerk-limited ramp can reach it
   from its neighbours within the distance between them.
4. Each block between critical points gets the fastest S-curve (:mod:`cnc_twin.motion.scurve`).
   Where a block's speed would exceed the limit curve, that sample becomes a critical point and
   steps 3-4 repeat.

The plan is a sequence of S-curve blocks covering the whole curve, starting and ending at rest.
Long curves are planned in windows (:func:`plan_feed_windows`), committing only blocks that a
later window cannot change, so the planner streams while it plans.
Units: SI (m, s). The tool axis is held fixed, so X/Y/Z move with the tool tip one to one.
"""

from __future__ import annotations

import hashlib
import math
import pickle
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnc_twin.core import disk_cache
from cnc_twin.core.config import AxisConfig, PathLimits
from cnc_twin.motion.scurve import SCurve, ramp_distance, reachable
from cnc_twin.geometry.nurbs import NurbsCurve

_GL_X, _GL_W = np.polynomial.legendre.leggauss(5)
BUDGET_SHARES = (1.0, 0.8, 0.65, 0.5, 0.4, 0.3)
"""shares of the full tangential acceleration budget a curve is tried with (``_sample``)"""
BUDGET_GAIN = 0.002
"""a smaller share is taken only when it saves this share of the curve's estimated time"""


@dataclass(frozen=True)
class FeedPlan:
    """S-curve blocks along the whole curve, and the sampled limit curve they respect.

    Attributes
    ----------
    blocks : consecutive blocks; lengths add up to the curve's length.
    s, u, limit : the samples: arc length [m], parameter, feed limit [m/s] (each shape (N,)).
    """

    blocks: tuple[SCurve, ...]
    s: np.ndarray
    u: np.ndarray
    limit: np.ndarray

    @property
    def duration(self) -> float:
        return sum(b.duration for b in self.blocks)

    @property
    def length(self) -> float:
        return float(self.s[-1])


def sample_curve(curve: NurbsCurve, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``u`` about ``spacing`` apart in arc length, and their arc lengths ``s``."""
    a, b = curve.domain
    breaks = np.unique(curve.knots)
    us = []
    for lo, hi in zip(breaks[:-1], breaks[1:]):
        length = curve.arc_length(lo, hi)
        n = max(8, math.ceil(length / spacing))
        us.append(np.linspace(lo, hi, n + 1)[:-1])
    u = np.concatenate(us + [[b]])
    mid, half = 0.5 * (u[1:] + u[:-1]), 0.5 * (u[1:] - u[:-1])
    nodes = mid[:, None] + half[:, None] * _GL_X[None, :]
    speed = np.linalg.norm(curve.derivatives(nodes.ravel(), 1)[1], axis=1).reshape(nodes.shape)
    s = np.concatenate([[0.0], np.cumsum(half * (speed @ _GL_W))])
    return u, s


def axis_derivatives(q: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First three derivatives of axis positions ``q`` (N, k) with respect to arc length ``s``."""
    d1 = np.gradient(q, s, axis=0)
    d2 = np.gradient(d1, s, axis=0)
    return d1, d2, np.gradient(d2, s, axis=0)


def tangential_budget(limits: PathLimits, axis_q: np.ndarray | None, s: np.ndarray,
                      axis_limits) -> tuple[float, float]:
    """(A_t, J_t): with the axes given, scaled by each axis's largest ``|dq/ds|`` (a rotary axis can
    turn more than one radian per metre of path); else the tool-tip budget of ``limits``."""
    if axis_q is None:
        return limits.tangential_acceleration, limits.tangential_jerk
    d1 = np.abs(axis_derivatives(axis_q, s)[0]).max(axis=0)
    v_lim, a_lim, j_lim = (np.asarray(x) for x in axis_limits)
    a_t = min(limits.path_acceleration, float(np.min(0.5 * a_lim / np.maximum(d1, 1e-12))))
    j_t = min(limits.path_jerk, float(np.min(j_lim / 3.0 / np.maximum(d1, 1e-12))))
    return a_t, j_t


def _limit_terms(curve: NurbsCurve, u: np.ndarray, s: np.ndarray, limits: PathLimits, period: float,
                 axis_q: np.ndarray | None, axis_limits) -> tuple[np.ndarray, np.ndarray]:
    """The feed limit at each sample (see the module docstring) as ``(rest, coupling)`` [m/s,
    m^2/s^3], each (N,): the limit is ``min(rest, coupling / A_t)``. ``coupling / A_t`` is the jerk
    term ``j_i / (9 A_t |C_ss,i|)`` (the tangential acceleration times the curvature), the only
    one that depends on the tangential budget.

    With ``axis_q`` (the machine axes along the samples, shape (N, k)) and ``axis_limits``
    ((velocity, acceleration, jerk) per axis), the axis terms use those axes' derivatives with
    respect to arc length (numerical) instead of the tool tip's: the limits after kinematics.
    """
    _, d1, d2 = curve.derivatives(u, 2)
    tangent, c_ss = _arc_length_derivatives(d1, d2)
    kappa = np.linalg.norm(c_ss, axis=1)
    c_sss = np.gradient(c_ss, s, axis=0)
    tiny = 1e-300
    f = np.full(len(u), limits.feed)
    rho = 1.0 / np.maximum(kappa, tiny)
    delta = limits.chord_tolerance
    chord = np.where(rho > delta / 2, (2.0 / period) * np.sqrt(np.maximum(2 * rho * delta - delta * delta, 0.0)), np.inf)
    f = np.minimum(f, chord)
    f = np.minimum(f, np.sqrt(limits.normal_acceleration / np.maximum(kappa, tiny)))
    f = np.minimum(f, np.cbrt(limits.normal_jerk / np.maximum(kappa * kappa, tiny)))
    if axis_q is None:
        q1, q2, q3 = tangent, c_ss, c_sss
        v_lim, a_lim, j_lim = limits.axis_velocity, limits.axis_acceleration, limits.axis_jerk
        f = np.minimum(f, knot_jerk_limit(curve, u, j_lim, period))
    else:
        q1, q2, q3 = axis_derivatives(axis_q, s)
        v_lim, a_lim, j_lim = axis_limits
    coupling = np.full(len(u), np.inf)
    f = np.minimum(f, axis_velocity_caps(q1, v_lim).min(axis=1))
    for i in range(q1.shape[1]):
        f = np.minimum(f, np.sqrt(0.5 * a_lim[i] / np.maximum(np.abs(q2[:, i]), tiny)))
        f = np.minimum(f, np.cbrt(j_lim[i] / 3.0 / np.maximum(np.abs(q3[:, i]), tiny)))
        coupling = np.minimum(coupling, j_lim[i] / (9.0 * np.maximum(np.abs(q2[:, i]), tiny)))
    return f, coupling


def axis_velocity_caps(q1: np.ndarray, v_lim) -> np.ndarray:
    """Each axis's feed limit ``v_i / |q1_i|`` [m/s] at each sample, shape (N, k): ``q1`` the
    axes' derivatives with respect to arc length (N, k) (the unit tangent for X/Y/Z), ``v_lim``
    their velocity limits (k,)."""
    return np.asarray(v_lim, dtype=np.float64)[None, :] / np.maximum(np.abs(q1), 1e-300)


FEED_CAP_SAMPLES = 257
"""points per curve at which :func:`curve_feed_cap` reads the tangent"""


def curve_feed_cap(c, axes: Sequence[AxisConfig]) -> tuple[float, int] | None:
    """``(cap [m/s], axis)`` when the curve program ``c``'s feed is more than X/Y/Z's velocity limits
    allow anywhere along it (the planner's axis-velocity term, :func:`axis_velocity_caps`, at
    :data:`FEED_CAP_SAMPLES` points): ``cap`` the fastest it may go at its best point and ``axis``
    (0..2) the one that holds it there; else None. A curve with a varying tool axis is left out (its axes are not the tip's); a feed at or
    below every linear axis's limit is never capped, so most programs cost nothing here."""
    limits = np.array([a.max_velocity for a in axes[:3]])
    if c.axis_curve is not None or c.limits.feed <= limits.min():
        return None
    curve = NurbsCurve(c.control_points, c.weights, c.knots, c.degree)
    d1 = curve.derivatives(np.linspace(*curve.domain, FEED_CAP_SAMPLES), 1)[1]
    tangent = d1 / np.maximum(np.linalg.norm(d1, axis=1), 1e-300)[:, None]
    per_axis = axis_velocity_caps(tangent, limits)  # (samples, 3) [m/s]
    caps = per_axis.min(axis=1)
    best = int(np.argmax(caps))
    if c.limits.feed > caps[best] * (1.0 + 1e-9):
        return float(caps[best]), int(np.argmin(per_axis[best]))
    return None


def _arc_length_derivatives(d1: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit tangent ``C_s``, ``C_ss``) from the parametric derivatives ``C'``, ``C''`` (each (N, 3))."""
    sigma = np.linalg.norm(d1, axis=1)
    tangent = d1 / sigma[:, None]
    return tangent, (d2 - np.sum(tangent * d2, axis=1)[:, None] * tangent) / (sigma**2)[:, None]


def knot_jerk_limit(curve: NurbsCurve, u: np.ndarray, j_lim, period: float) -> np.ndarray:
    """The feed limit [m/s] at the samples that are knots where the curve's curvature jumps (a
    quadratic, or a knot repeated to C1): there each axis's acceleration changes by
    ``v^2 |dC_ss,i|`` within one period, a jerk of about ``v^2 |dC_ss,i| / T`` in the commanded
    positions, so ``v <= sqrt(j_i T / |dC_ss,i|)``. Infinite elsewhere (and where the jump is
    round-off: a C2 knot)."""
    out = np.full(len(u), np.inf)
    a, b = curve.domain
    inner = [k for k in np.unique(curve.knots) if a < k < b]
    if not inner:
        return out
    eps = 1e-9 * (b - a)
    knots = np.asarray(inner)
    sides = []
    for side in (knots - eps, knots + eps):
        _, d1, d2 = curve.derivatives(side, 2)
        sides.append(_arc_length_derivatives(d1, d2)[1])
    jump = np.abs(sides[1] - sides[0])  # (knots, 3) [1/m]
    scale = np.max(np.abs(np.concatenate(sides)), axis=0) + 1.0  # round-off is relative to C_ss itself
    jump = np.where(jump > 1e-6 * scale, jump, 0.0)
    with np.errstate(divide="ignore"):
        limit = np.min(np.sqrt(np.asarray(j_lim)[:3][None, :] * period / jump), axis=1)
    at = np.clip(np.searchsorted(u, knots), 0, len(u) - 1)
    np.minimum.at(out, at, limit)
    return out


def _local_minima(limit: np.ndarray, feed: float) -> list[int]:
    out = []
    for j in range(1, len(limit) - 1):
        if limit[j] < feed and limit[j] < limit[j - 1] and limit[j] <= limit[j + 1]:
            out.append(j)
    return out


def _plan_range(s: np.ndarray, limit: np.ndarray, a: int, b: int, v_a: float, v_b: float,
                limits: PathLimits, a_t: float, j_t: float) -> tuple[list[SCurve], list[int], list[float]]:
    """Plan samples a..b from speed v_a to v_b: (blocks, critical indices, critical speeds).

    Each round plans every block between critical points, then makes the sample where each block
    most exceeds the limit curve a critical point too. A violation is never at a critical point
    (each block starts and ends at or below the limit there), so the critical set grows every
    round and the loop ends after at most ``b - a`` rounds: with every sample critical, no block
    can exceed the limit at a sample.
    """
    inner = [a + j for j in _local_minima(limit[a:b + 1], limits.feed)]
    critical = sorted({a, b, *inner})
    # A round re-plans every block, but a new critical point changes only the speeds near it:
    # blocks with the same ends and speeds as in an earlier round are taken from here.
    planned: dict[tuple, tuple[SCurve, int | None]] = {}
    while True:
        speeds = [v_a if j == a else v_b if j == b else float(limit[j]) for j in critical]
        lengths = [float(s[q] - s[p]) for p, q in zip(critical[:-1], critical[1:])]
        for i in range(len(lengths)):  # forward scan
            speeds[i + 1] = min(speeds[i + 1], reachable(speeds[i], lengths[i], a_t, j_t, speeds[i + 1]))
        for i in range(len(lengths) - 1, -1, -1):  # backward scan
            speeds[i] = min(speeds[i], reachable(speeds[i + 1], lengths[i], a_t, j_t, speeds[i]))
        blocks = []
        violations = set()
        for i, (p, q) in enumerate(zip(critical[:-1], critical[1:])):
            key = (p, q, speeds[i], speeds[i + 1])
            if key not in planned:
                cap = float(np.max(limit[p:q + 1]))
                block = SCurve.plan(lengths[i], speeds[i], speeds[i + 1], v_max=min(cap, limits.feed), a_max=a_t,
                                    j_max=j_t)
                planned[key] = (block, _worst_excess(block, s[p:q + 1] - s[p], limit[p:q + 1]))
            block, worst = planned[key]
            blocks.append(block)
            if worst is not None:
                violations.add(p + worst)
        if not violations:
            return blocks, critical, speeds
        grown = set(critical) | violations
        if len(grown) == len(critical):  # cannot happen (see above); never loop for ever
            raise FeedPlanningError(f"the feed plan exceeds the limit at a critical point "
                                    f"(s = {s[min(violations)] * 1e3:.3f} mm)")
        critical = sorted(grown)


class FeedPlanningError(RuntimeError):
    """The planner could not plan a feed that keeps the limits (a bug if it ever happens)."""


@dataclass(frozen=True)
class _Samples:
    """A curve sampled for planning: parameters, arc lengths, the feed limit, tangential budgets."""

    u: np.ndarray
    s: np.ndarray
    limit: np.ndarray
    a_t: float
    j_t: float


def _sample(curve: NurbsCurve, limits: PathLimits, period: float, axis_path, axis_limits) -> _Samples:
    u, s = sample_curve(curve, min(limits.feed * period, 0.5e-3))
    axis_q = None if axis_path is None else axis_path(u)
    a_full, j_t = tangential_budget(limits, axis_q, s, axis_limits)
    rest, coupling = _limit_terms(curve, u, s, limits, period, axis_q, axis_limits)
    # the tangential budget the curve runs fastest with: a smaller one ramps slower but lets
    # the feed through tight turns faster (the jerk term A_t * kappa); the full one unless a
    # smaller share saves time
    best = None
    for share in BUDGET_SHARES:
        a_t = share * a_full
        limit = np.minimum(rest, coupling / a_t)
        time = _traverse_time(s, limit, a_t)
        if best is None or time < best[0] * (1.0 - BUDGET_GAIN):
            best = (time, a_t, limit)
    _, a_t, limit = best
    return _Samples(u, s, limit, a_t, j_t)


def _windows(sm: _Samples, limits: PathLimits, window: float):
    s, limit, a_t, j_t = sm.s, sm.limit, sm.a_t, sm.j_t
    stop = ramp_distance(limits.feed, 0.0, a_t, j_t)
    last = len(s) - 1
    a, v_a = 0, 0.0
    span = max(window, 3.0 * stop)
    while True:
        b = min(last, int(np.searchsorted(s, s[a] + span)))
        blocks, critical, speeds = _plan_range(s, limit, a, b, v_a, 0.0, limits, a_t, j_t)
        if b == last:
            yield blocks
            return
        keep = [i for i, j in enumerate(critical) if i > 0 and s[b] - s[j] >= stop]
        if not keep:
            span *= 2.0  # the window held no committable block: widen it
            continue
        k = keep[-1]
        yield blocks[:k]
        a, v_a = critical[k], speeds[k]


PLANS_KIND, SAMPLES_KIND = "plans", "plan-samples"
"""the disk cache's folders of plans and of sampled curves (:mod:`cnc_twin.core.disk_cache`)"""
SAMPLES_KEPT = 8
"""sampled curves a process keeps for a later run (:func:`sample_limits`' ``key``; they are large)"""
_SAMPLES: OrderedDict[bytes, _Samples] = OrderedDict()


def _kept(kept: OrderedDict, key: bytes | None, kind: str, most: int):
    """What ``kept`` holds under ``key`` (now its most recently used), else what an earlier process
    kept on disk under it (:mod:`cnc_twin.core.disk_cache`, ``kind``; kept here too from now on),
    or None."""
    if key is None:
        return None
    if key in kept:
        kept.move_to_end(key)
        return kept[key]
    found = disk_cache.load(kind, _disk_name(key))
    if found is not None:
        _remember(kept, key, found, most)
    return found


def _keep(kept: OrderedDict, key: bytes | None, value, most: int, kind: str) -> None:
    """Keep ``value`` under ``key`` (None: keep nothing) here and on disk for later processes."""
    if key is not None:
        _remember(kept, key, value, most)
        disk_cache.store(kind, _disk_name(key), value)


def _remember(kept: OrderedDict, key: bytes, value, most: int) -> None:
    """``value`` under ``key`` in ``kept``, the least recently used beyond ``most`` dropped."""
    kept[key] = value
    while len(kept) > most:
        kept.popitem(last=False)


def _disk_name(key: bytes) -> str:
    """The entry's name on disk: the key of the inputs with the code's (other code may plan otherwise)."""
    return hashlib.sha256(disk_cache.code_digest().encode() + key).hexdigest()


def sample_limits(curve: NurbsCurve, limits: PathLimits, *, period: float, axis_path=None,
                  axis_limits=None, key: bytes | None = None) -> _Samples:
    """The curve sampled for planning with its feed limit: the bulk of the work before the first
    window (the planner does it before it reports ready, :class:`~cnc_twin.planner.curve_program.CurvePlan`).
    ``key`` (:func:`plan_key`): the samples taken under the same key earlier in this process, if
    kept (the last :data:`SAMPLES_KEPT`), or by an earlier process (the disk cache), as
    :func:`plan_feed_windows` keeps its plans.

    :rtype: ``_Samples``
    """
    samples = _kept(_SAMPLES, key, SAMPLES_KIND, SAMPLES_KEPT)
    if samples is None:
        samples = _sample(curve, limits, period, axis_path, axis_limits)
        _keep(_SAMPLES, key, samples, SAMPLES_KEPT, SAMPLES_KIND)
    return samples


def traverse_time(samples: _Samples) -> float:
    """The curve's time at its feed limit with the tangential acceleration budget, from rest to
    rest [s]: a forward and a backward pass over the samples (no jerk limit, so a lower bound of
    the planned time; the program's length estimate is taken from it).

    :type samples: ``_Samples``
    """
    return _traverse_time(samples.s, samples.limit, samples.a_t)


def _traverse_time(s: np.ndarray, limit: np.ndarray, a: float) -> float:
    ds = np.diff(s)
    w = np.minimum(limit, 1e150) ** 2  # v^2, which grows by at most 2 a ds a sample: with
    w[0] = w[-1] = 0.0                  # c = 2 a s, w_i = min over k <= i of (w_k - c_k) + c_i
    c = 2.0 * a * s
    w = np.minimum(w, np.minimum.accumulate(w - c) + c)
    w = np.minimum(w, (np.minimum.accumulate((w + c)[::-1]) - c[::-1])[::-1])
    v = np.sqrt(np.maximum(w, 0.0))
    mean = 0.5 * (v[1:] + v[:-1])
    return float(np.sum(ds / np.maximum(mean, 1e-9)))


PLANS_KEPT = 256
"""window plans a process keeps for a later run (:func:`plan_feed_windows`' ``key``)"""
_PLANS: OrderedDict[bytes, list] = OrderedDict()


def plan_key(*inputs) -> bytes:
    """A key for :func:`plan_feed_windows` from everything its plan depends on (picklable values:
    the path's definition, the limits, the period, the window, the kinematics' parameters)."""
    return hashlib.sha256(pickle.dumps(inputs, protocol=pickle.HIGHEST_PROTOCOL)).digest()


def plan_feed_windows(curve: NurbsCurve, limits: PathLimits, *, period: float, window: float = 0.1,
                      axis_path=None, axis_limits=None, samples: _Samples | None = None, key: bytes | None = None):
    """Plan the curve window by window; yields lists of committed S-curve blocks in path order.

    Each window of about ``window`` metres is planned to end at rest. Blocks up to the last
    critical point farther from the window's end than the stopping distance from full feed are
    unaffected by that forced stop (the backward scan cannot reach them), so they are final and
    identical to a whole-curve plan's; the next window starts there at the committed speed.
    ``samples``: from :func:`sample_limits`, if already taken.

    ``key`` (:func:`plan_key` of the plan's inputs): a plan completed under the same key in this
    process (the last :data:`PLANS_KEPT`), or by an earlier one (kept on disk with the code's
    digest, :mod:`cnc_twin.core.disk_cache`, unless ``CNC_TWIN_CACHE=off``), is handed out again
    instead of planned (the same blocks: a pooled planner serving a sweep whose gains change the
    card, not the path; a second run of the same program); a completed plan is kept under it.
    None: plan, keep nothing.

    :type samples: ``_Samples`` or None
    """
    planned = _kept(_PLANS, key, PLANS_KIND, PLANS_KEPT)
    if planned is not None:
        yield from planned
        return
    if samples is None:
        samples = _sample(curve, limits, period, axis_path, axis_limits)
    planned = []
    for blocks in _windows(samples, limits, window):
        planned.append(blocks)
        yield blocks
    _keep(_PLANS, key, planned, PLANS_KEPT, PLANS_KIND)  # complete: a run that stops early keeps nothing


def plan_feed(curve: NurbsCurve, limits: PathLimits, *, period: float, window: float | None = None,
              axis_path=None, axis_limits=None) -> FeedPlan:
    """Plan the whole curve from rest to rest (in windows when ``window`` is given [m]).

    ``axis_path(u) -> (N, k)`` and ``axis_limits`` plan against the machine axes after
    kinematics (a varying tool axis); by default the tool tip's X/Y/Z limits apply.
    """
    sm = _sample(curve, limits, period, axis_path, axis_limits)
    if window is None:
        blocks = _plan_range(sm.s, sm.limit, 0, len(sm.s) - 1, 0.0, 0.0, limits, sm.a_t, sm.j_t)[0]
    else:
        blocks = [b for chunk in _windows(sm, limits, window) for b in chunk]
    return FeedPlan(blocks=tuple(blocks), s=sm.s, u=sm.u, limit=sm.limit)


def _worst_excess(block: SCurve, s_local: np.ndarray, limit: np.ndarray) -> int | None:
    """Index (into the block's samples) where the block's speed most exceeds the limit, or None."""
    t = np.linspace(0.0, block.duration, max(64, 4 * len(s_local)))
    s, v = block.positions_and_speeds(t)
    v_at = np.interp(s_local, s, v)
    excess = v_at - limit * (1.0 + 1e-9)
    j = int(np.argmax(excess))
    return j if excess[j] > 0 else None
