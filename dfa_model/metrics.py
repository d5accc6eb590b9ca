"""Metrics of a stroke record (functions of arrays, shared by results and recordings).

unzipping speed (Sec. 3.1, 4.3.2): |time average of dx/dt| over the unzipping window,
i.e. |x(t1) - x(t0)| / (t1 - t0). The window is the hold stage when a charge reset
precedes it (the paper's experimental definition); for a bare voltage step it starts
at the stroke's peak, because the first tens of ms are zipping, not unzipping
(averaging from t = 0 would measure the static stroke instead).
"""
from __future__ import annotations

import numpy as np


def _interp(t, x, tq):
    return float(np.interp(tq, t, x))


def time_mean(t, x, t0, t1):
    """Time-weighted mean of x over [t0, t1] (trapezoid on the samples, with the
    window ends interpolated)."""
    if t1 <= t0:
        return float(np.interp(t0, t, x))
    inside = (t > t0) & (t < t1)
    tt = np.concatenate([[t0], t[inside], [t1]])
    xx = np.concatenate([[_interp(t, x, t0)], x[inside], [_interp(t, x, t1)]])
    return float(np.trapezoid(xx, tt) / (t1 - t0))


def unzipping_speed(t, x, t0=None, t1=None):
    """|x(t1) - x(t0)| / (t1 - t0) (m/s); t0 defaults to the time of peak stroke."""
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    if t1 is None:
        t1 = t[-1]
    if t0 is None:
        t0 = float(t[int(np.argmax(x))])
    if t1 <= t0:
        return 0.0
    return abs(_interp(t, x, t1) - _interp(t, x, t0)) / (t1 - t0)


def cycles(t, x, period, t0, t1):
    """Per-cycle (start time, mean, min, max) over whole periods in [t0, t1]."""
    n = int(np.floor((t1 - t0) / period + 1e-9))
    out = []
    for k in range(n):
        a, b = t0 + k * period, t0 + (k + 1) * period
        inside = (t >= a) & (t <= b)
        xs = np.concatenate([[_interp(t, x, a)], x[inside], [_interp(t, x, b)]])
        out.append((a, time_mean(t, x, a, b), xs.min(), xs.max()))
    return np.array(out).reshape(-1, 4)


def ripple(t, x, period, t0, t1, last=5):
    """Peak-to-peak stroke within a period, mean over the last `last` periods (m)."""
    c = cycles(t, x, period, t0, t1)
    if len(c) == 0:
        return float("nan")
    c = c[-last:]
    return float(np.mean(c[:, 3] - c[:, 2]))


def drift(t, x, period, t0, t1, skip=1):
    """Slope of the per-cycle mean stroke against time (m/s), skipping `skip` cycles
    of start-up. Negative: the stroke creeps down cycle after cycle."""
    c = cycles(t, x, period, t0, t1)[skip:]
    if len(c) < 2:
        return float("nan")
    return float(np.polyfit(c[:, 0], c[:, 1], 1)[0])
