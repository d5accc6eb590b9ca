"""Step control shared by the full model's integrator (integrator.py, TR-BDF2) and the
surrogate's (surrogate_kernel.py, Rosenbrock-W): both are embedded pairs whose error
estimate is of third order, both land on the stops at the ends of the stroke, and both
record into a buffer that grows.
"""
from __future__ import annotations

import numpy as np

from .._jit import njit

GROW_MAX = 5.0      # the most a step may grow after an accepted step
GROW_MIN = 0.2      # ... and the least (an accepted step with an error near 1)


@njit(cache=True, inline="always")
def worst(a, b):
    """max(a, b) for error norms, NaN kept: max() drops a NaN second argument (numba and
    Python compare with >), so a norm over a state with one NaN component came out finite
    and the step passed."""
    return b if (b > a or b != b) else a


@njit(cache=True, inline="always")
def grow_factor(err, top=GROW_MAX):
    """The next step over this one after an accepted step with the scaled error err
    (<= 1): 0.9 err^(-1/3) (a third-order estimate), within [GROW_MIN, top]."""
    return min(top, max(GROW_MIN, 0.9 * err ** (-1.0 / 3.0) if err > 0 else top))


@njit(cache=True, inline="always")
def shrink_factor(err, floor):
    """The retried step over the rejected one (scaled error err > 1), at least `floor`."""
    return max(floor, 0.9 * err ** (-1.0 / 3.0))


@njit(cache=True, inline="always")
def stop_side(x, x_e):
    """The stop a stroke x lies beyond: -1 (below 0), +1 (above x_e), 0 (inside)."""
    if x < 0.0:
        return -1
    if x > x_e:
        return 1
    return 0


@njit(cache=True, inline="always")
def to_stop(x0, x1, x_e):
    """A step moving the stroke from x0 (inside) to x1: the event function (the distance
    to the stop it passes) at both ends, and that stop (-1, +1; 0: none passed, both 0)."""
    side = stop_side(x1, x_e)
    if side == 0:
        return 0.0, 0.0, 0
    xb = 0.0 if side < 0 else x_e
    return x0 - xb, x1 - xb, side


@njit(cache=True)
def grow(buf, nrow):
    """`buf`, or a copy twice as long, so that row `nrow` exists."""
    if nrow < buf.shape[0]:
        return buf
    nb = np.empty((2 * buf.shape[0], buf.shape[1]))
    nb[:buf.shape[0]] = buf
    return nb
