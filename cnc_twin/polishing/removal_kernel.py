"""The removal map's update, compiled: the contact patch, its Preston removal and the pad's
friction wrench in one call (:func:`removal_step`), and the whole update of
:class:`~cnc_twin.polishing.polish.RemovalTracker` from MuJoCo's data (:func:`tracker_update`: the
pad's contact force from its contact sensor, the tip's velocity, the ball of candidates, the
step, the wrench into ``xfrc_applied``), which the polishing batch calls between periods.

:meth:`~cnc_twin.polishing.removal.PrestonModel.patch`, :meth:`~cnc_twin.polishing.removal.PrestonModel.add`
and :func:`~cnc_twin.polishing.polish.friction_wrench` are the reference (numpy over the
candidate points). :func:`removal_step` does the same arithmetic point by point in a numba
kernel: every product and sum in the same order (the references add term by term:
``sequential_sum``, no BLAS dot, no einsum), the same stable sort and search for the touching
set, no fast-math; so the two agree bit for bit (``tests/test_removal_kernel.py``), and a
polishing run's trace is the same either way.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.machine import mujoco_c

# the whole update calls MuJoCo through mujoco_c's bindings: recompile when they change
purge_stale(__file__, [mujoco_c.__file__])

# the tracker's totals (float64): what RemovalTracker.update accumulates
CONTACT_TIME, FORCE_TIME, CALLS, COST_NS, MOST_CONTACTS = range(5)
N_TOTALS = 5
# the tracker's parameters (float64)
RADIUS, SLAB, MODULUS, K_DT, MU, FRICTION_SPEED, DT, BALL_R2, MARGIN2 = range(9)
N_PARAMS = 9
# the tracker's ids (int64): the tool site, the pad body, the contact sensor's address and slots
SITE, PAD_BODY, SENSOR_ADR, SLOTS, FIELDS = range(5)
_MJOBJ_SITE = 6
"""``mujoco.mjtObj.mjOBJ_SITE``"""


@njit(cache=True, error_model="numpy")
def removal_step(ball_idx, ball, tip, a, force, radius, slab, modulus, k_dt, v_tip, omega, centre, mu,
                 friction_speed, depth, wrench):
    """One update of the removal map ``depth`` (in place) and the pad's friction ``wrench`` (6,)
    about ``centre`` (written; zero without contact). ``ball_idx`` (m,), ``ball`` (7, m): the
    candidate points (x y z nx ny nz area) near the ``tip``; ``a`` the unit tool axis; ``force``
    [N]; ``k_dt`` Preston's k times the update's interval. Returns how many points got removal,
    or -1 when the pad touches none (no removal added, as the reference adds no patch)."""
    for i in range(6):
        wrench[i] = 0.0
    if not force > 0:
        return -1
    m = ball_idx.shape[0]
    r2max = radius * radius
    sel = np.empty(m, dtype=np.int64)
    hh = np.empty(m)
    k = 0
    for j in range(m):
        r0, r1, r2 = ball[0, j] - tip[0], ball[1, j] - tip[1], ball[2, j] - tip[2]
        h = (a[0] * r0 + a[1] * r1) + a[2] * r2
        rho2 = ((r0 * r0 + r1 * r1) + r2 * r2) - h * h
        facing = (a[0] * ball[3, j] + a[1] * ball[4, j]) + a[2] * ball[5, j]
        if rho2 <= r2max and abs(h) <= slab and facing > 0:
            sel[k] = j
            hh[k] = h
            k += 1
    if k == 0:
        return -1
    sel, h = sel[:k], hh[:k]  # views: compacted in place below
    c = force / modulus
    w_sum = 0.0
    ah = 0.0
    for i in range(k):
        w_sum += ball[6, sel[i]]
    if not w_sum > 0:
        return -1
    for i in range(k):
        ah += ball[6, sel[i]] * h[i]
    delta = (c - ah) / w_sum
    # drop the points below the pad at this level and solve again, until every point kept
    # touches (PrestonModel._contact: the same passes, the same sums in the same order)
    while True:
        n = 0
        for i in range(k):
            if h[i] + delta > 0:
                sel[n] = sel[i]
                h[n] = h[i]
                n += 1
        if n == k:
            break
        k = n
        w_sum = 0.0
        ah = 0.0
        for i in range(k):
            ah += ball[6, sel[i]] * h[i]
        for i in range(k):
            w_sum += ball[6, sel[i]]
        delta = (c - ah) / w_sum
    touched = pressed = 0
    f0 = f1 = f2 = t0 = t1 = t2 = 0.0
    d0, d1, d2 = tip[0] - centre[0], tip[1] - centre[1], tip[2] - centre[2]
    for i in range(k):
        p = modulus * (h[i] + delta)
        if not p > 0:
            continue
        pressed += 1
        j = sel[i]
        r0, r1, r2 = ball[0, j] - tip[0], ball[1, j] - tip[1], ball[2, j] - tip[2]
        n0, n1, n2 = ball[3, j], ball[4, j], ball[5, j]
        v0 = (omega[1] * r2 - omega[2] * r1) + v_tip[0]
        v1 = (omega[2] * r0 - omega[0] * r2) + v_tip[1]
        v2 = (omega[0] * r1 - omega[1] * r0) + v_tip[2]
        vn = (v0 * n0 + v1 * n1) + v2 * n2
        v0, v1, v2 = v0 - vn * n0, v1 - vn * n1, v2 - vn * n2
        speed = math.sqrt((v0 * v0 + v1 * v1) + v2 * v2)
        inc = k_dt * p * speed
        depth[ball_idx[j]] += inc
        if inc > 0:
            touched += 1
        scale = -mu * p * ball[6, j] / max(speed, friction_speed)
        fx, fy, fz = v0 * scale, v1 * scale, v2 * scale
        a0, a1, a2 = r0 + d0, r1 + d1, r2 + d2
        f0 += fx
        f1 += fy
        f2 += fz
        t0 += a1 * fz - a2 * fy
        t1 += a2 * fx - a0 * fz
        t2 += a0 * fy - a1 * fx
    if pressed == 0:  # the reference's patch is empty: no removal step, no wrench
        return -1
    wrench[0], wrench[1], wrench[2], wrench[3], wrench[4], wrench[5] = f0, f1, f2, t0, t1, t2
    return touched


@njit(cache=True, error_model="numpy")
def contact_force(sensordata, ids, ax0, ax1, ax2, totals):
    """The pad's contact normal force along the (not necessarily unit) axis ``ax`` [N], as
    :meth:`RemovalTracker.contact_force`: slot by slot of the contact sensor, in MuJoCo's contact
    order; ``totals[MOST_CONTACTS]`` keeps the most contacts seen."""
    adr, slots, fields = ids[SENSOR_ADR], ids[SLOTS], ids[FIELDS]
    found = int(sensordata[adr])
    if found > totals[MOST_CONTACTS]:
        totals[MOST_CONTACTS] = found
    total = 0.0
    for i in range(min(found, slots)):
        base = adr + fields * i
        dot = (sensordata[base + 4] * ax0 + sensordata[base + 5] * ax1) + sensordata[base + 6] * ax2
        total += sensordata[base + 1] * abs(dot)
    return total


@njit(cache=True, error_model="numpy")
def _refresh_ball(packed, tip, limit2, ball_idx, ball):
    """The grid points within the ball around ``tip`` into ``ball_idx`` / ``ball`` (their first
    columns); how many. As :meth:`PrestonModel._ball_around` and its gather."""
    n = 0
    for j in range(packed.shape[1]):
        r0, r1, r2 = packed[0, j] - tip[0], packed[1, j] - tip[1], packed[2, j] - tip[2]
        if (r0 * r0 + r1 * r1) + r2 * r2 <= limit2:
            ball_idx[n] = j
            for row in range(7):
                ball[row, n] = packed[row, j]
            n += 1
    return n


if mujoco_c.IMPORT_ERROR is None:
    _mj_object_velocity = mujoco_c.mj_objectVelocity

    @njit(cache=True, error_model="numpy")
    def tracker_update(model_ptr, data_ptr, sensordata, xmat, site_xpos, xipos, xfrc, ids, params, packed, depth,
                       ball_idx, ball, ball_state, velocity, totals):  # pragma: no cover - compiled
        """One update of the removal map from MuJoCo's data, as :meth:`RemovalTracker.update` on the
        reference path: ``xfrc[pad body]`` gets the friction wrench (zero without contact), ``depth``
        the removal, ``totals`` the figures. ``ball_state``: the ball's centre (3) and size;
        ``velocity`` (6,) scratch."""
        site, body = ids[SITE], ids[PAD_BODY]
        ax0, ax1, ax2 = xmat[body, 2], xmat[body, 5], xmat[body, 8]  # the pad's z axis
        force = contact_force(sensordata, ids, ax0, ax1, ax2, totals)
        wrench = xfrc[body]
        for i in range(6):
            wrench[i] = 0.0
        if force > 0.0:
            _mj_object_velocity(model_ptr, data_ptr, _MJOBJ_SITE, site, velocity.ctypes.data, 0)
            tip = site_xpos[site]
            norm = math.sqrt((ax0 * ax0 + ax1 * ax1) + ax2 * ax2)
            a = np.empty(3)
            a[0], a[1], a[2] = ax0 / norm, ax1 / norm, ax2 / norm
            o0, o1, o2 = tip[0] - ball_state[0], tip[1] - ball_state[1], tip[2] - ball_state[2]
            if not (o0 * o0 + o1 * o1) + o2 * o2 <= params[MARGIN2]:
                ball_state[3] = _refresh_ball(packed, tip, params[BALL_R2], ball_idx, ball)
                ball_state[0], ball_state[1], ball_state[2] = tip[0], tip[1], tip[2]
            n = int(ball_state[3])
            touched = removal_step(ball_idx[:n], ball[:, :n], tip, a, force, params[RADIUS], params[SLAB],
                                   params[MODULUS], params[K_DT], velocity[3:], velocity[:3], xipos[body], params[MU],
                                   params[FRICTION_SPEED], depth, wrench)
            if touched >= 0:
                totals[CONTACT_TIME] += params[DT]
            totals[FORCE_TIME] += force * params[DT]
        totals[CALLS] += 1.0


def no_tracker() -> tuple:
    """Arguments of :func:`tracker_update`'s types for a run without a removal map (never called)."""
    return (0, 0, np.zeros(1), np.zeros((1, 9)), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 6)),
            np.zeros(5, dtype=np.int64), np.zeros(N_PARAMS), np.zeros((7, 0)), np.zeros(0), np.zeros(0, dtype=np.intp),
            np.zeros((7, 0)), np.zeros(4), np.zeros(6), np.zeros(N_TOTALS))


def warm_up() -> None:
    """Compile (or load from the cache) before a run's clock starts."""
    ball = np.zeros((7, 1))
    ball[5, 0] = ball[6, 0] = 1.0
    removal_step(np.zeros(1, dtype=np.intp), ball, np.zeros(3), np.array([0.0, 0.0, 1.0]), 1.0, 1.0, 1.0, 1.0,
                 1.0, np.zeros(3), np.zeros(3), np.zeros(3), 0.5, 1e-3, np.zeros(1), np.zeros(6))
