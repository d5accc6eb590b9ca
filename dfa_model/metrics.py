"""Metrics of a stroke record, shared by simulation results and recordings.

Each takes a `StrokeTrace` (trace.py): for a simulation, the solver's own piecewise
quadratic x(t) over its accepted steps, so no metric depends on the output sampling;
for a recording, its samples joined linearly (`StrokeTrace.from_samples(t, x)`). All run
in time linear in the record's length.

unzipping speed (Sec. 3.1, 4.3.2): |x(t1) - x(t0)| / (t1 - t0) over the unzipping
window. The window is the hold stage when a charge reset precedes it (the paper's
experimental definition); for a bare voltage step it starts at the stroke's peak,
because the first tens of ms are zipping, not unzipping (averaging from t = 0 would
measure the static stroke instead).
"""
from __future__ import annotations

import numpy as np

from .numerics.trace import StrokeTrace


def as_trace(t, x=None) -> StrokeTrace:
    """A StrokeTrace, or one built from samples (t, x)."""
    return t if isinstance(t, StrokeTrace) else StrokeTrace.from_samples(t, x)


def time_mean(trace: StrokeTrace, t0: float, t1: float) -> float:
    """Time mean of x over [t0, t1] (x(t0) if the window is empty)."""
    return float(trace.mean(t0, t1))


def unzipping_speed(trace: StrokeTrace, t0: float | None = None, t1: float | None = None) -> float:
    """|x(t1) - x(t0)| / (t1 - t0) (m/s); t0 defaults to the time of peak stroke, t1 to
    the end."""
    t1 = trace.t1 if t1 is None else t1
    t0 = trace.argmax() if t0 is None else t0
    if t1 <= t0:
        return 0.0
    return float(abs(trace(t1) - trace(t0)) / (t1 - t0))


def cycles(trace: StrokeTrace, period: float, t0: float, t1: float) -> np.ndarray:
    """Per-cycle rows (start time, mean, min, max) over the whole periods in [t0, t1]."""
    if not (period > 0):
        raise ValueError(f"period: got {period!r}, expected a value > 0 (s)")
    n = int(np.floor((t1 - t0) / period + 1e-9))
    if n <= 0:
        return np.empty((0, 4))
    a = t0 + period * np.arange(n)
    b = a + period
    lo, hi = trace.extrema(a, b)
    return np.column_stack([a, trace.mean(a, b), lo, hi])


def last_periods(trace: StrokeTrace, period: float, n: int = 1, t_end: float | None = None):
    """(ripple, mean) over the last `n` whole periods ending at t_end (default the end of
    the record): the mean peak-to-peak stroke within a period and the time mean of the
    stroke over the last one (m). The one definition of ripple and of the end's period
    mean (README, 'Words with one meaning'): the full model, the surrogates, `dfa design`
    and `dfa compare` all take them from here."""
    t1 = trace.t1 if t_end is None else t_end
    c = cycles(trace, period, t1 - n * period, t1)
    if len(c) == 0:
        raise ValueError(f"period: {period:g} s is longer than the record ({trace.t1 - trace.t0:g} s)")
    return float(np.mean(c[:, 3] - c[:, 2])), float(c[-1, 1])


def drift_rate(trace: StrokeTrace, period: float, t0: float, t1: float, skip: int = 1) -> float:
    """Rate at which the per-period mean stroke is lost (m/s, positive when the stroke
    creeps down): minus the slope of a straight line through the per-period means over
    [t0, t1], skipping `skip` periods of start-up; NaN with fewer than two periods."""
    c = cycles(trace, period, t0, t1)[skip:]
    if len(c) < 2:
        return float("nan")
    return float(-np.polyfit(c[:, 0], c[:, 1], 1)[0])
