"""Fast polarity inversion, cycle-averaged inside a surrogate run.

A charge reset (the paper's 3 s at 30 Hz) is 180 inversions; stepped as they are, each is
a kernel step of its own, and they were 180 of the standard protocol's 217 steps. Where
the period is short against every electrical time constant, the averaged form
(averaged.py: the charge is linear in V, so the period mean <V> drives the period-mean
charge, and the force's V^2 term takes the period's mean square <V^2>) is exact to
O((T / tau)^2), and one averaged segment replaces the stage's periods but its last
N_TAIL, which are stepped as they are: the stroke's ripple and the stage's end are the
real waveform's.

A stage is averaged when all of these hold (else it is stepped as it is):
  - its waveform is a full-duty polarity inversion (Bipolar, duty 1): |V| stays at the
    amplitude but for the ramps, so the stroke barely ripples (a dead time or a pulse
    train lets it sag every period: the averaged force would be wrong);
  - the ramps take at most RAMP_SHARE of the period;
  - the period is at most RATE_SHARE of the fastest electrical time constant of the
    zipped device at the stage's mean square voltage (the charges', the polarization
    branch's, the device voltage's behind R_s: the held Jacobian's diagonal);
  - it holds more than N_TAIL + MIN_AVERAGED whole periods.

At the window's start the period-mean charge is the real one plus b g0 (g0 the drive's
phase offset, waveforms.period_means; b the charges' input gains), at its end
(whole periods later, the same phase) the real charge is the mean minus b g0: the kernel
applies both (surrogate_kernel.integrate's gof). In the window the records hold period
means: the stroke's, the voltage <V> and the current without its switching spikes
(`SurrogateResult.averaged_windows` lists the windows).
"""
from __future__ import annotations

import math

import numpy as np

from dfa_model.numerics import surrogate_kernel as sk
from dfa_model.waveforms import Bipolar, Piecewise, Protocol, merge, period_means

N_TAIL = 4            # periods stepped as they are at the end of an averaged stage (averaged.N_TAIL)
MIN_AVERAGED = 4      # fewer averaged periods than this are not worth the window's two offsets
RATE_SHARE = 0.01     # period / fastest electrical time constant at most
RAMP_SHARE = 0.01     # the ramps' share of the period at most


def fastest_rate(s, W: float) -> float:
    """The largest |d(rate)/d(state)| over the electrical states (charges, polarizations,
    V_d) of surrogate s held zipped (x = x_e, uncharged) in averaged mode at the mean
    square voltage W (1/s): one over the fastest electrical time constant. Held zipped
    the material points are alike: the first stands for them all. Kept on the surrogate
    per W (rebuilt when its parameters were replaced)."""
    memo = s.__dict__.setdefault("_rates", {})
    hit = memo.get(W)
    if hit is not None and hit[0] is s.params:
        return hit[1]
    par = s.par(averaged=True, lag=False)
    y = np.zeros(s.ny)
    y[sk.X] = s.x_e
    y[-2] = math.sqrt(W)
    if s.series:
        y[sk.VD] = y[-2]
    base, up = np.zeros(s.ny), np.zeros(s.ny)
    sk.evaluate(y, W, 0.0, s.tables, par, s._law, s._lawp, base, sk.HELD)
    sc = s.scales(max(math.sqrt(W), 100.0))
    pos = dict(s._names)
    fastest = 0.0
    for name in ("V_d", "q_f", "P_f", "q_b", "P_b", "q_a", "P_a", "q_1", "P_1"):
        i = pos.get(name)
        if i is None:
            continue
        h = 1e-6 * sc[i]
        yp = y.copy()
        yp[i] += h
        sk.evaluate(yp, W, 0.0, s.tables, par, s._law, s._lawp, up, sk.HELD)
        fastest = max(fastest, abs(up[i] - base[i]) / h)
    if len(memo) > 16:
        memo.clear()
    memo[W] = (s.params, fastest)
    return fastest


def _averaged_span(s, stage):
    """(n_averaged_periods, <V>, <V^2>, g0) when `stage` is averaged (module docstring),
    else None."""
    w = stage.waveform
    if type(w) is not Bipolar or w.duty != 1.0:
        return None
    T = w.period
    n = math.floor(stage.duration / T + 1e-9)
    if n < N_TAIL + MIN_AVERAGED:
        return None
    if w.slew_rate is not None and 2.0 * w.ramp_time(2.0 * abs(w.V)) > RAMP_SHARE * T:
        return None
    vm, W, g0 = period_means(w)
    if T * fastest_rate(s, W) > RATE_SHARE:
        return None
    return n - N_TAIL, vm, W, g0


def plan(s, protocol: Protocol, load):
    """The kernel's inputs for `protocol` with its fast inversions averaged:
    (tb, v0, vs, f0, fs, w2, gof, windows), windows the averaged (t0, t1); None when no
    stage qualifies (the run is stepped as it is)."""
    parts, windows, marks = [], [], []
    t = 0.0
    for st in protocol.stages:
        span = _averaged_span(s, st)
        if span is None:
            parts.append(st.waveform.piecewise(st.duration).shifted(t))
        else:
            n_avg, vm, W, g0 = span
            t_avg = n_avg * st.waveform.period
            # one segment at the period mean, then the tail from the drive's own phase
            # (whole periods later: where the stage started)
            parts += [Piecewise(np.array([t, t + t_avg]), np.array([vm]), np.zeros(1)),
                      st.waveform.piecewise(st.duration - t_avg).shifted(t + t_avg)]
            windows.append((t, t + t_avg))
            marks.append((W, g0))
        t += st.duration
    if not windows:
        return None
    tb, v0, vs, f0, fs = merge(Piecewise.concat(parts), load.piecewise(protocol.duration))
    w2 = np.full(len(v0), -1.0)
    gof = np.zeros((len(v0), 2))
    tol = 1e-12 * max(protocol.duration, 1.0)
    for (ta, te), (W, g0) in zip(windows, marks):
        inside = (tb[:-1] >= ta - tol) & (tb[1:] <= te + tol)
        w2[inside] = W
        k0 = int(np.argmax(inside))
        gof[k0] = (g0, W)
        if k0 + inside.sum() < len(v0):
            gof[k0 + int(inside.sum())] = (-g0, W)
    return tb, v0, vs, f0, fs, w2, gof, windows
