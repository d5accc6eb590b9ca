"""Metrics over long polarity-inversion runs: ripple() and drift_rate() over runs of growing
length at 30 Hz (Table 1, 6 kV, 5 N), computed from the solver's trace (linear in the
run length), against the earlier sample-based algorithm (a boolean mask over all
samples per cycle: quadratic), timed in the same run on the same 1 ms output.

    python benchmarks/bench_metrics.py [--hours 1.0]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from dfa_model import Bipolar, PhysicsWarning, Protocol, preset, simulate  # noqa: E402

warnings.simplefilter("ignore", PhysicsWarning)
PERIOD = 1 / 30.0


def old_cycles(t, x, period, t0, t1):
    """The earlier algorithm (dfa_model.metrics before the trace): per cycle, a mask over
    every sample."""
    n = int(np.floor((t1 - t0) / period + 1e-9))
    out = []
    for k in range(n):
        a, b = t0 + k * period, t0 + (k + 1) * period
        inside = (t >= a) & (t <= b)
        xs = np.concatenate([[np.interp(a, t, x)], x[inside], [np.interp(b, t, x)]])
        tt = np.concatenate([[a], t[inside], [b]])
        out.append((a, np.trapezoid(xs, tt) / period, xs.min(), xs.max()))
    return np.array(out).reshape(-1, 4)


def old_ripple_drift(t, x, t1):
    c = old_cycles(t, x, PERIOD, 0.0, t1)
    return np.mean(c[-5:, 3] - c[-5:, 2]), np.polyfit(c[1:, 0], c[1:, 1], 1)[0]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=1.0, help="longest run (h)")
    args = ap.parse_args()
    p = preset("vshape-table1")
    simulate(p, Protocol.single(Bipolar(6000, 30.0), 0.2), load=5.0)      # compile
    print("30 Hz inversion, Table 1, 6 kV, 5 N; metrics ripple(1/30, last=5) + drift_rate(1/30)")
    print(f"{'run':>8} {'switches':>9} {'simulate':>9} {'trace metrics':>14} {'old, 1 ms samples':>18}")
    lengths = [10.0, 60.0, 600.0, args.hours * 3600.0]
    for T in lengths:
        t0 = time.perf_counter()
        r = simulate(p, Protocol.single(Bipolar(6000, 30.0), T), load=5.0)
        t_sim = time.perf_counter() - t0
        t0 = time.perf_counter()
        rip, dr = r.ripple(PERIOD, last=5), r.drift_rate(PERIOD)
        t_new = time.perf_counter() - t0
        old = "-"
        if T <= 60.0:      # quadratic: 60 s already takes seconds; 1 h took about 10 min
            rs = simulate(p, Protocol.single(Bipolar(6000, 30.0), T), load=5.0, t_eval=np.linspace(0, T, int(T * 1000) + 1))
            t0 = time.perf_counter()
            old_ripple_drift(rs.t, rs.x, T)
            old = f"{time.perf_counter() - t0:.3f} s"
        print(f"{T:>7.0f}s {int(T * 60):>9,} {t_sim:>8.2f}s {t_new * 1e3:>11.1f} ms {old:>18}   "
              f"(ripple {rip * 1e6:.3f} um, drift_rate {dr * 1e9:+.3f} nm/s)")


if __name__ == "__main__":
    main()
