"""C's ``long double`` arithmetic where LinuxCNC's interpreter uses it: angles through ``M_PIl``
(the trig functions of expressions, ``acos`` / ``asin`` in degrees, an inverse-time arc's turn),
through numpy's ``longdouble`` (x87 extended precision on x86-64, as LinuxCNC's).

numpy is imported on the first such computation, not with the reader: most programs need none,
and importing numpy is most of ``cnc-twin gcode``'s start-up (about 40 ms of it).
"""

from __future__ import annotations

import functools


@functools.cache
def _numpy():
    import numpy  # here, not at the top: see the module's docstring

    return numpy


@functools.cache
def pi_long():
    """``M_PIl``: pi as a C ``long double``."""
    return _numpy().longdouble("3.141592653589793238462643383279502884")


def extended(value: float):
    """``value`` as a C ``long double`` (exact: a double fits)."""
    return _numpy().longdouble(value)


def trig(name: str, degrees: float) -> float:
    """``sin`` / ``cos`` / ``tan`` (``name``) of an angle in degrees as LinuxCNC computes it:
    ``sin((x * M_PIl) / 180.0)`` in long double (C++ picks ``sinl`` for a long double argument),
    rounded to double at the end; ``sin[-180]`` is then +5e-20, not -1.2e-16, and the sign shows
    in four decimals."""
    np = _numpy()
    return float(getattr(np, name)(np.longdouble(degrees) * pi_long() / np.longdouble(180.0)))


def to_degrees(radians: float) -> float:
    """``(r * 180.0) / M_PIl`` as LinuxCNC writes it: a double product, a long double quotient."""
    return float(_numpy().longdouble(radians * 180.0) / pi_long())
