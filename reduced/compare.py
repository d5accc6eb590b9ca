"""Full model against surrogate on one protocol: errors, metrics of each, wall times.

Definitions (one implementation, used by `dfa compare`, the fitting and the report):
  stroke_rms_error    RMS of x_reduced - x_full over the run (m), integrated exactly on
                      the union of both records' points (both piecewise linear there)
  stroke_range        max - min of the full model's stroke (m)
  unzipping_speed_*   Sec. 3.1 definition over the hold window (StrokeMetrics) for DC;
                      under a square wave the same on the per-period peak stroke (from
                      the highest period's peak to the last period's, hold_speed): the
                      stroke itself swings every period, and with dead time drops to 0,
                      so its peak-to-end drop would measure the ripple's phase
  ripple_*            peak-to-peak stroke over the last period (m; StrokeMetrics.ripple);
                      None when the last stage is not periodic
  drift_*             stroke lost over the run (m, positive when lost; StrokeMetrics.drift):
                      the uncharged static stroke at the last stage's amplitude and the
                      final load, minus the mean stroke over the last period (the final
                      stroke when the last stage is not periodic)
"""
from __future__ import annotations

import math
import statistics
import time
import warnings

import numpy as np

from dfa_model import PhysicsWarning, simulate
from dfa_model.metrics import cycles
from dfa_model.numerics.solver import protocol_load
from dfa_model.waveforms import Bipolar, Unipolar

KEYS = ("stroke_rms_error", "stroke_range", "relative_rms_error", "unzipping_speed_full", "unzipping_speed_reduced",
        "ripple_full", "ripple_reduced", "drift_full", "drift_reduced", "wall_time_full", "wall_time_reduced",
        "speedup", "states")


def rms_difference(trace_a, trace_b) -> float:
    """RMS of a - b over their common span; both are sampled at the union of their
    points, between which a piecewise-linear difference is integrated exactly."""
    t0, t1 = max(trace_a.t0, trace_b.t0), min(trace_a.t1, trace_b.t1)
    t = np.union1d(trace_a.t, trace_b.t)
    t = t[(t >= t0) & (t <= t1)]
    if len(t) < 2 or t1 <= t0:
        return 0.0
    d = trace_a(t) - trace_b(t)
    dt = np.diff(t)
    # integral of a linear function squared over each interval
    integ = dt * (d[:-1] ** 2 + d[:-1] * d[1:] + d[1:] ** 2) / 3.0
    return float(math.sqrt(integ.sum() / (t[-1] - t[0])))


def hold_period(protocol):
    """Period of the hold stage's square wave, or None for DC."""
    for st in protocol.stages:
        if st.label == "hold" and isinstance(st.waveform, (Bipolar, Unipolar)):
            return 1.0 / st.waveform.frequency
    return None


def hold_span(protocol):
    """(t0, t1) of the hold stage, or the whole protocol."""
    return protocol.stage_span("hold") or (0.0, protocol.duration)


def hold_speed(res, protocol) -> float:
    """Unzipping speed over the hold (m/s; module docstring): Sec. 3.1 for DC, the
    per-period peak stroke's under a square wave with at least two whole periods."""
    period = hold_period(protocol)
    if period is None:
        return res.unzipping_speed
    t0, t1 = hold_span(protocol)
    c = cycles(res.trace, period, t0, min(t1, res.trace.t1))
    if len(c) < 2:
        return res.unzipping_speed
    k = int(np.argmax(c[:, 3]))
    return 0.0 if k == len(c) - 1 else float((c[k, 3] - c[-1, 3]) / (c[-1, 0] - c[k, 0]))


def _metrics(res, protocol):
    """(unzipping speed over the hold, ripple or None, drift) of a result (module docstring)."""
    T = res.period
    ripple = res.ripple() if T is not None and T <= res.trace.t1 - res.trace.t0 else None
    return hold_speed(res, protocol), ripple, float(res.drift)


REPEAT_BUDGET = 0.2     # s: a model is timed again (repeats) only while its runs took less


def _timed(run, repeats: int):
    """(result of run(), wall time): the median of up to `repeats` runs while they take
    under REPEAT_BUDGET in all (one run of a long protocol)."""
    t0 = time.perf_counter()
    out = run()
    ts = [time.perf_counter() - t0]
    while len(ts) < repeats and sum(ts) < REPEAT_BUDGET:
        t0 = time.perf_counter()
        run()
        ts.append(time.perf_counter() - t0)
    return out, statistics.median(ts)


def compare(surrogate, protocol, load=None, full_result=None, rtol=None, repeats=1, inversions="average") -> dict:
    """Run the full model (the surrogate's actuator) and the surrogate on `protocol`
    with `load` (a Load or a constant force in N; default the protocol's own, else 0);
    returns the KEYS plus the two results under 'full' and 'reduced'. Wall times are
    each model's own, measured the same way: the median of `repeats` runs of each while
    they take under REPEAT_BUDGET (`dfa compare` times 5: one run of a sub-millisecond
    surrogate right after the full model measured the caches the full model left, 0.3-0.5
    ms of its 0.8). `inversions`: Surrogate.simulate's (fast full-duty inversions averaged
    or stepped)."""
    F = protocol_load(protocol, load)
    p = surrogate.params
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PhysicsWarning)
        if full_result is not None:
            full, wall_full = full_result, full_result.wall_time
        else:
            full, wall_full = _timed(lambda: simulate(p, protocol, load=F), repeats)
    kw = {"inversions": inversions} if rtol is None else {"rtol": rtol, "inversions": inversions}
    red, wall_red = _timed(lambda: surrogate.simulate(protocol, F, **kw), repeats)
    err = rms_difference(red.trace, full.trace)
    rng = float(full.trace.max() - full.trace.min())
    us_f, rp_f, dr_f = _metrics(full, protocol)
    red._x_static = full.x_static      # the same actuator's statics: computed once
    us_r, rp_r, dr_r = _metrics(red, protocol)
    out = {"stroke_rms_error": err, "stroke_range": rng, "relative_rms_error": err / rng if rng > 0 else None,
           "unzipping_speed_full": us_f, "unzipping_speed_reduced": us_r, "ripple_full": rp_f,
           "ripple_reduced": rp_r, "drift_full": dr_f, "drift_reduced": dr_r, "wall_time_full": wall_full,
           "wall_time_reduced": wall_red, "speedup": wall_full / wall_red if wall_red > 0 else None,
           "states": surrogate.n_states}
    # the front came within 2 % (in stroke) of the electrode end: the force comes from the
    # short unzipped rest, and the unzipping speed hinges on how the front leaves the
    # end - a stated breakdown of the surrogates (README, 'Surrogates')
    out["front_at_end"] = bool(full.peak_stroke >= 0.98 * surrogate.x_e)
    out["full"], out["reduced"] = full, red
    return out


def speed_error(row) -> float | None:
    """Relative unzipping-speed error of a compare() row (None if the full model's is 0)."""
    f = row["unzipping_speed_full"]
    return None if not f else abs(row["unzipping_speed_reduced"] / f - 1.0)


def drift_error(row) -> float | None:
    f = row["drift_full"]
    return None if not f else abs(row["drift_reduced"] / f - 1.0)


def plot(row, path, title=None):
    """Both strokes over time, the difference below."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    full, red = row["full"], row["reduced"]
    t = np.union1d(full.trace.t, red.trace.t)
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5), gridspec_kw={"height_ratios": [3, 1.3]})
    a1.plot(t, full.trace(t) * 1e3, "k-", lw=1.2, label="full model")
    a1.plot(t, red.trace(t) * 1e3, "C1--", lw=1.2, label=f"surrogate ({red.surrogate.family}, "
                                                      f"{red.surrogate.n_states} states)")
    for i, (t0, t1) in enumerate(getattr(red, "averaged_windows", [])):
        for ax in (a1, a2):
            ax.axvspan(t0, t1, color="0.92", lw=0, zorder=0,
                       label="surrogate cycle-averaged" if (ax is a1 and i == 0) else None)
    a1.set_ylabel("stroke (mm)")
    a1.legend(loc="best", fontsize=8)
    a1.set_title(title or f"relative RMS error {row['relative_rms_error'] * 100:.2f} %, "
                          f"speed-up {row['speedup']:.0f}x")
    a2.plot(t, (red.trace(t) - full.trace(t)) * 1e6, "C3-", lw=0.8)
    a2.axhline(0, color="0.6", lw=0.6)
    a2.set_ylabel("error (µm)")
    a2.set_xlabel("time (s)")
    fig.tight_layout()
    from dfa_model.io.fileio import write_atomic
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=130, format=str(path).rsplit(".", 1)[-1]))
    plt.close(fig)
