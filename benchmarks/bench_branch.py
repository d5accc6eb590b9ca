"""The polarization branch's accuracy in N and its cost, against the plain model in the
same run (physics guide, "Polarization branch").

For each case, a reset (3 s at 30 Hz) and a 20 s hold at 6 kV and 5 N on Table 1: the RMS
of the stroke against the same model at N = 641, and the median wall time of one run at
1 kHz outputs (7 runs), for the model without a branch and with it. Prints the ratios
branch / plain.

    python benchmarks/bench_branch.py [--N 21,41,81] [--ref 641]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from dfa_model import Protocol, preset, simulate  # noqa: E402

CASES = {"plain": {}, "strong fast branch (chi_p 0.448, tau_p 0.116 s)": {"chi_p": 0.448, "tau_p": 0.116},
         "weak branch (chi_p 0.069, tau_p 0.35 s)": {"chi_p": 0.069, "tau_p": 0.35},
         "branch (chi_p 0.2, tau_p 1 s)": {"chi_p": 0.2, "tau_p": 1.0}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--N", default="21,41,81")
    ap.add_argument("--ref", type=int, default=641)
    a = ap.parse_args()
    Ns = [int(n) for n in a.N.split(",")]
    vs = preset("vshape-table1")
    proto = Protocol.reset_then_hold(6000, 20.0)
    t = np.linspace(0, 23, 23001)
    rows = {}
    for name, kw in CASES.items():
        ref = simulate(vs.replace(N=a.ref, **kw), proto, load=5.0, t_eval=t, rtol=1e-8, warn=False).x
        for N in Ns:
            p = vs.replace(N=N, **kw)
            x = simulate(p, proto, load=5.0, t_eval=t, warn=False).x
            walls = []
            for _ in range(7):
                t0 = time.perf_counter()
                simulate(p, proto, load=5.0, t_eval=t, warn=False)
                walls.append(time.perf_counter() - t0)
            rows[name, N] = (float(np.sqrt(np.mean((x - ref) ** 2))), float(np.median(walls)))
    print(f"stroke RMS against N = {a.ref} (um) and median wall time of one run (ms), reset + 20 s hold, "
          "1 kHz outputs")
    print(f"{'case':52s}" + "".join(f"  N={N:<4d} err / time" for N in Ns))
    for name in CASES:
        print(f"{name:52s}" + "".join(f"  {rows[name, N][0] * 1e6:7.2f} / {rows[name, N][1] * 1e3:6.1f}" for N in Ns))
    print("ratios branch / plain (error, time):")
    for name in list(CASES)[1:]:
        print(f"{name:52s}" + "".join(f"  {rows[name, N][0] / rows['plain', N][0]:7.2f} / "
                                      f"{rows[name, N][1] / rows['plain', N][1]:6.2f}" for N in Ns))


if __name__ == "__main__":
    main()
