"""Span evaluation, compiled: NURBS curves, NURBS surfaces and surface paths for the card's stepper.

The evaluators :class:`~cnc_twin.geometry.nurbs.SpanEvaluator` (curves),
:class:`~cnc_twin.geometry.surface.SurfaceSpanEvaluator` (surfaces) and
:class:`~cnc_twin.geometry.surface_path.SurfacePathEvaluator` (a (u, v) curve on a surface) build
the coefficient blocks and call these functions; the card's stepper
(:mod:`cnc_twin.dsp.curve_stepper`) and the batch kernel call them on the ``ev`` tuple. A span's
rows are summed as ``((b0 + x b1) + x^2 b2) + ...``, a patch's monomial rows ``x^a y^b`` in row
order, then the quotient rule and the chain rule; ``tests/test_span_eval.py`` checks the results
against scipy's B-splines (:class:`~cnc_twin.geometry.nurbs.NurbsCurve`,
:class:`~cnc_twin.geometry.surface.NurbsSurface`).

A path's evaluator is one tuple, ``ev``::

    (starts, blocks, lo, hi, cd,                 the curve: span starts (spans,), coefficient
                                                 blocks (spans, p + 1, 3 (cd + 1)), domain, dimension
     starts_u, starts_v, patches, p, q, box)     the surface, or empty arrays for a plain curve:
                                                 patch starts (nu,), (nv,), patch blocks
                                                 (nu, nv, (p + 1)(q + 1), 24), degrees, domain box
                                                 (u0, u1, v0, v1)

For a surface path the curve is its (u, v) curve (``cd = 2``) and the point is ``S(u(t), v(t))``,
of dimension 3; for a plain curve the point is the curve's, of dimension ``cd``
(:func:`path_dim`). :func:`path_evaluate` also writes the surface tangents ``S_u``, ``S_v`` at the
point (the tool axis comes from them); a plain curve leaves them alone.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

WORK = 64
"""float64 work space the path functions need [elements]"""
NO_SURFACE = (np.zeros(0), np.zeros(0), np.zeros((0, 0, 1, 24)), 0, 0, np.zeros(4))
"""the surface part of a plain curve's ``ev``"""


@njit(cache=True)
def bisect_right(values, x):
    """``bisect.bisect_right`` on a sorted float64 array."""
    lo, hi = 0, values.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if x < values[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True)
def _homogeneous(starts, blocks, lo, hi, u, ncols, out):
    """``out[:ncols]`` = the span block's rows at ``u`` (clamped to ``[lo, hi]``), summed in order."""
    if u < lo:
        u = lo
    elif u > hi:
        u = hi
    i = bisect_right(starts, u) - 1
    x = u - starts[i]
    block = blocks[i]
    for c in range(ncols):
        out[c] = block[0, c]
    power = 1.0
    for j in range(1, block.shape[0]):
        power = power * x
        for c in range(ncols):
            out[c] = out[c] + power * block[j, c]


@njit(cache=True)
def curve_speed(starts, blocks, lo, hi, d, u, h):
    """``|C'(u)|``, as :meth:`~cnc_twin.geometry.nurbs.SpanEvaluator.speed`."""
    _homogeneous(starts, blocks, lo, hi, u, 2 * (d + 1), h)
    w, w1 = h[d], h[2 * d + 1]
    inv = 1.0 / w
    total = 0.0
    for k in range(d):
        v = (h[d + 1 + k] - w1 * h[k] * inv) * inv
        total += v * v
    return math.sqrt(total)


@njit(cache=True)
def evaluate_span(starts, blocks, lo, hi, d, u, h, c, c1, c2):
    """``C, C', C''`` at ``u`` into ``c, c1, c2``, as
    :meth:`~cnc_twin.geometry.nurbs.SpanEvaluator.evaluate`."""
    n = d + 1
    _homogeneous(starts, blocks, lo, hi, u, 3 * n, h)
    w, w1, w2 = h[d], h[n + d], h[2 * n + d]
    inv = 1.0 / w
    for k in range(d):
        c[k] = h[k] * inv
    for k in range(d):
        c1[k] = (h[n + k] - w1 * c[k]) * inv
    for k in range(d):
        c2[k] = (h[2 * n + k] - 2.0 * w1 * c1[k] - w2 * c[k]) * inv


@njit(cache=True)
def _patch_homogeneous(starts_u, starts_v, patches, p, q, box, u, v, ncols, out):
    """``out[:ncols]`` = the patch block's monomial rows at ``(u, v)`` (clamped to the box), summed
    in row order, as :meth:`SurfaceSpanEvaluator._homogeneous`."""
    if u < box[0]:
        u = box[0]
    elif u > box[1]:
        u = box[1]
    if v < box[2]:
        v = box[2]
    elif v > box[3]:
        v = box[3]
    i = bisect_right(starts_u, u) - 1
    j = bisect_right(starts_v, v) - 1
    x, y = u - starts_u[i], v - starts_v[j]
    block = patches[i, j]
    for c in range(ncols):
        out[c] = block[0, c]  # the first monomial is 1.0 * 1.0
    pa = 1.0
    row = 0
    for a in range(p + 1):
        if a > 0:
            pa = pa * x
        pb = 1.0
        for b in range(q + 1):
            if b > 0:
                pb = pb * y
            if row > 0:
                mono = pa * pb
                for c in range(ncols):
                    out[c] = out[c] + mono * block[row, c]
            row += 1


@njit(cache=True)
def _first_partials(h, s):
    """``S, S_u, S_v`` into ``s[0:9]`` from the block sum ``h`` (the quotient rule); ``1 / w``."""
    w, wu, wv = h[3], h[7], h[11]
    inv = 1.0 / w
    for k in range(3):
        s[k] = h[k] * inv
    for k in range(3):
        s[3 + k] = (h[4 + k] - wu * s[k]) * inv
    for k in range(3):
        s[6 + k] = (h[8 + k] - wv * s[k]) * inv
    return inv


@njit(cache=True)
def surface_tangents(starts_u, starts_v, patches, p, q, box, u, v, h, s):
    """``S, S_u, S_v`` at ``(u, v)`` into ``s[0:9]``, as the first three of
    :meth:`~cnc_twin.geometry.surface.SurfaceSpanEvaluator.evaluate` (the first 12 columns of the
    block are all they use)."""
    _patch_homogeneous(starts_u, starts_v, patches, p, q, box, u, v, 12, h)
    _first_partials(h, s)


@njit(cache=True)
def surface_evaluate(starts_u, starts_v, patches, p, q, box, u, v, h, s):
    """``S, S_u, S_v, S_uu, S_uv, S_vv`` at ``(u, v)`` into ``s[0:18]``, as
    :meth:`~cnc_twin.geometry.surface.SurfaceSpanEvaluator.evaluate`."""
    _patch_homogeneous(starts_u, starts_v, patches, p, q, box, u, v, 24, h)
    inv = _first_partials(h, s)
    wu, wv, wuu, wuv, wvv = h[7], h[11], h[15], h[19], h[23]
    for k in range(3):
        s[9 + k] = (h[12 + k] - 2.0 * wu * s[3 + k] - wuu * s[k]) * inv
    for k in range(3):
        s[12 + k] = (h[16 + k] - wu * s[6 + k] - wv * s[3 + k] - wuv * s[k]) * inv
    for k in range(3):
        s[15 + k] = (h[20 + k] - 2.0 * wv * s[6 + k] - wvv * s[k]) * inv


@njit(cache=True)
def path_dim(ev):
    """The dimension of the path's points: 3 on a surface, else the curve's."""
    return 3 if ev[7].shape[0] > 0 else ev[4]


@njit(cache=True)
def path_evaluate(ev, t, w, c, c1, c2, tangents):
    """``C, C', C''`` at ``t`` into ``c, c1, c2`` (``path_dim`` each); on a surface also ``S_u, S_v``
    into ``tangents[0:6]``. As :meth:`~cnc_twin.geometry.nurbs.SpanEvaluator.evaluate` or
    :meth:`~cnc_twin.geometry.surface_path.SurfacePathEvaluator.evaluate`. ``w``: work space of
    :data:`WORK`."""
    starts, blocks, lo, hi, cd, starts_u, starts_v, patches, p, q, box = ev
    if patches.shape[0] == 0:
        evaluate_span(starts, blocks, lo, hi, cd, t, w, c, c1, c2)
        return
    q0, q1, q2 = w[0:2], w[2:4], w[4:6]
    evaluate_span(starts, blocks, lo, hi, 2, t, w[6:15], q0, q1, q2)
    s = w[16:34]
    surface_evaluate(starts_u, starts_v, patches, p, q, box, q0[0], q0[1], w[34:58], s)
    u1, v1, u2, v2 = q1[0], q1[1], q2[0], q2[1]
    uu, uv2, vv = u1 * u1, 2.0 * u1 * v1, v1 * v1
    for k in range(3):
        c[k] = s[k]
    for k in range(3):
        c1[k] = s[3 + k] * u1 + s[6 + k] * v1
    for k in range(3):
        c2[k] = s[9 + k] * uu + s[12 + k] * uv2 + s[15 + k] * vv + s[3 + k] * u2 + s[6 + k] * v2
    for k in range(6):
        tangents[k] = s[3 + k]


@njit(cache=True)
def path_speed(ev, t, w):
    """``|C'(t)|``, as :meth:`~cnc_twin.geometry.nurbs.SpanEvaluator.speed` or
    :meth:`~cnc_twin.geometry.surface_path.SurfacePathEvaluator.speed`."""
    starts, blocks, lo, hi, cd, starts_u, starts_v, patches, p, q, box = ev
    if patches.shape[0] == 0:
        return curve_speed(starts, blocks, lo, hi, cd, t, w)
    q0, q1, q2 = w[0:2], w[2:4], w[4:6]
    evaluate_span(starts, blocks, lo, hi, 2, t, w[6:15], q0, q1, q2)
    s = w[16:25]
    surface_tangents(starts_u, starts_v, patches, p, q, box, q0[0], q0[1], w[34:58], s)
    u1, v1 = q1[0], q1[1]
    x = s[3] * u1 + s[6] * v1
    y = s[4] * u1 + s[7] * v1
    z = s[5] * u1 + s[8] * v1
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True)
def next_break(ev, t):
    """The first span start after ``t``; the domain's end if none."""
    starts, hi = ev[0], ev[3]
    i = bisect_right(starts, t)
    return starts[i] if i < starts.shape[0] else hi
