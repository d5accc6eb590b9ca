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
  - its waveform is a full-duty polarity inversion (Bipolar, duty 1) with equal shares of
    +V and -V: |V| stays at the amplitude but for the ramps and no mean voltage charges
    the interface, so the stroke barely ripples (a dead time or a pulse train lets it sag
    every period; an unequal share charges the interface under its mean, and the force's
    V q term then swings with the polarity - the stroke follows the larger force in one
    half period, and near the pull-in threshold that zips an actuator the mean force
    would leave open);
  - the ramps take at most RAMP_SHARE of the period;
  - the period is at most RATE_SHARE of the fastest electrical time constant of the
    zipped device at the stage's mean square voltage (the charges', the device voltage's
    behind R_s: the held Jacobian's diagonal), and at most P_RATE_SHARE of the
    polarization branch's (tau_p: a relaxation the field drives, its period mean exact to
    O((T / tau_p)^2) like the charges', and no slow material state of its own that the
    stroke's ripple could move);
  - it holds at least N_TAIL + MIN_AVERAGED whole periods;
  - at the stage's start (known only during the run: run() splits it there) every
    charge and polarization is below RIPPLE_SHARE of the charge whose V q force equals
    the V^2 force (|c1 / c0| q <= RIPPLE_SHARE |V| at every stroke): a reset after a DC
    hold starts charged, and its stroke swings with the polarity.

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
# ... / the polarization branch's time constant at most. At 0.01 every reset of a branch
# with tau_p <= 3.3 s was stepped (the lattice with the branch: 245 steps on the standard
# protocol, dfa compare 4.2). At 0.05, against the stepped run (both families; Table 1 and
# Fig. 10a at N = 161 with tau_p 1 s, Table 1 with 0.7 s, a non-preset V-shape with 1.5 s;
# resets + DC at 6 and 7 kV, 30 Hz for 10 s, 25 Hz from phase 0): at most 0.036 % of range
# apart, 4-80x fewer steps (docs/guide/surrogates.md)
P_RATE_SHARE = 0.05
RIPPLE_SHARE = 0.002  # the charges' V q force over the V^2 force at the window's start at most
RAMP_SHARE = 0.01     # the ramps' share of the period at most


def fastest_rate(s, W: float) -> float:
    """The largest |d(rate)/d(state)| over the electrical states (charges, polarizations,
    V_d) of surrogate s held zipped (x = x_e, uncharged) in averaged mode at the mean
    square voltage W (1/s): one over the fastest electrical time constant."""
    return max(rates(s, W))


def rates(s, W: float) -> tuple[float, float]:
    """fastest_rate over the charges and V_d, and over the polarizations (0 without the
    branch). Held zipped the material points are alike: the first stands for them all.
    Kept on the surrogate per W (rebuilt when its parameters were replaced)."""
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
    fastest = [0.0, 0.0]
    for name in ("V_d", "q_f", "P_f", "q_b", "P_b", "q_a", "P_a", "q_1", "P_1"):
        i = pos.get(name)
        if i is None:
            continue
        h = 1e-6 * sc[i]
        yp = y.copy()
        yp[i] += h
        sk.evaluate(yp, W, 0.0, s.tables, par, s._law, s._lawp, up, sk.HELD)
        k = 1 if name[0] == "P" else 0
        fastest[k] = max(fastest[k], abs(up[i] - base[i]) / h)
    if len(memo) > 16:
        memo.clear()
    memo[W] = (s.params, (fastest[0], fastest[1]))
    return fastest[0], fastest[1]


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
    if w.positive_share != 0.5:
        return None
    vm, W, g0 = period_means(w)
    r_q, r_P = rates(s, W)
    if T * r_q > RATE_SHARE or T * r_P > P_RATE_SHARE:
        return None
    return n - N_TAIL, vm, W, g0


def charge_limit(s, V: float) -> float:
    """The largest charge (C/m^2) a window may start with at amplitude V: RIPPLE_SHARE |V|
    over the largest |c1 / c0| of the force map."""
    hit = s.__dict__.get("_c1_over_c0")        # kept on the surrogate for its maps
    if hit is None or hit[0] is not s.tables:
        c0, c1 = s.tables[:, sk.C0], s.tables[:, sk.C1]
        ok = c0 > 0
        hit = s._c1_over_c0 = (s.tables, float(np.max(np.abs(c1[ok]) / c0[ok])) if ok.any() else math.inf)
    return RIPPLE_SHARE * abs(V) / hit[1] if hit[1] > 0 else math.inf


def _charge(s, y) -> float:
    """The largest |charge| or |polarization| of a kernel state (layer, wakes, points)."""
    q = np.abs(y[sk.QF:sk.NODE0 + 2 * s.n_points])
    q[sk.SM - sk.QF] = 0.0                      # the lag's anchor is a length, not a charge
    return float(q.max()) if q.size else 0.0


def plan(s, protocol: Protocol, load):
    """The kernel's inputs for `protocol` with its fast inversions averaged:
    (tb, v0, vs, f0, fs, w2, gof, windows), windows the averaged (t0, t1, V); None when
    no stage qualifies (the run is stepped as it is)."""
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
            windows.append((t, t + t_avg, abs(st.waveform.V)))
            marks.append((W, g0))
        t += st.duration
    if not windows:
        return None
    tb, v0, vs, f0, fs = merge(Piecewise.concat(parts), load.piecewise(protocol.duration))
    w2 = np.full(len(v0), -1.0)
    gof = np.zeros((len(v0), 2))
    tol = 1e-12 * max(protocol.duration, 1.0)
    for (ta, te, _), (W, g0) in zip(windows, marks):
        inside = (tb[:-1] >= ta - tol) & (tb[1:] <= te + tol)
        w2[inside] = W
        k0 = int(np.argmax(inside))
        gof[k0] = (g0, W)
        if k0 + inside.sum() < len(v0):
            gof[k0 + int(inside.sum())] = (-g0, W)
    return tb, v0, vs, f0, fs, w2, gof, windows


def _span(seg, a, b):
    """The segments of seg = (tb, v0, vs, f0, fs, *per-segment) within [a, b] (a and b
    breakpoints of tb)."""
    tb = seg[0]
    tol = 1e-12 * max(abs(tb[-1]), 1.0)
    if a <= tb[0] + tol and b >= tb[-1] - tol:
        return seg                      # all of it (one window from the start: 2.7 us of slicing)
    k0 = int(np.searchsorted(tb, a - tol))
    k1 = int(np.searchsorted(tb, b - tol)) if b < tb[-1] - tol else len(tb) - 1
    return (tb[k0:k1 + 1],) + tuple(v[k0:k1] for v in seg[1:])


def run(s, plan_, stepped, y, run_kernel):
    """Run a planned protocol: each averaged window is taken only if the state at its
    start carries at most charge_limit (module docstring), else its stage is stepped
    (`stepped()`: the protocol's own segments). run_kernel(segments, y, averaged) runs
    one call and returns (rec, steps, y_end). Returns (rec, steps, y_end, windows taken)."""
    tb, v0, vs, f0, fs, w2, gof, windows = plan_
    planned = (tb, v0, vs, f0, fs, w2, gof)
    starts = [w[0] for w in windows]
    cuts = ([] if starts[0] == tb[0] else [float(tb[0])]) + starts + [float(tb[-1])]
    recs, total, taken, base = [], 0, [], None
    for a, b in zip(cuts[:-1], cuts[1:]):
        w = next((w for w in windows if w[0] == a), None)
        if w is not None and _charge(s, y) > charge_limit(s, w[2]):
            if base is None:            # the protocol's own segments, stepped as they are
                base = stepped()
                base = base + (base[1] * base[1], np.zeros((len(base[1]), 2)))
            rec, steps, y = run_kernel(_span(base, a, b), y, False)
        else:
            rec, steps, y = run_kernel(_span(planned, a, b), y, True)
            if w is not None:
                taken.append(w[:2])
        recs.append(rec if not recs else rec[1:])      # each call records its start again
        total += steps
    return (recs[0] if len(recs) == 1 else np.concatenate(recs)), total, y, taken
