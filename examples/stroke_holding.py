"""Holding a commanded stroke despite charge retention (reduced/holding.py).

V-shaped actuator of Table 1, 5 N load, x_ref = 0.8 mm, 300 s hold, on the full model:
open-loop DC at the static voltage for x_ref, 10 Hz polarity inversion at that voltage,
and the PI amplitude loop (tuned with python-control on the charge surrogate) driving a
10 Hz inversion; also DC amplitude adaptation (the alternative the loop does not use).
Then the same loop closed around the actuator FMU under fmpy. A second scenario steps
the load to 6 N at 150 s.

    python examples/stroke_holding.py [FIGURE]

Writes examples/figures/stroke_holding.png (default) and prints the tables.
"""
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import reduced  # noqa: E402
from dfa_model import preset  # noqa: E402
from reduced.holding import compare_hold, cosim_hold_fmu, tune_hold_controller  # noqa: E402

X_REF, F0, T = 0.8e-3, 5.0, 300.0
fig_path = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "figures" / "stroke_holding.png"
wall0 = time.perf_counter()

params = preset("vshape-table1")
c = tune_hold_controller(reduced.build(params, "charge"), X_REF, F0)
print(f"tuned on the surrogate: plant dx/dV = {c.plant_gain * 1e9:.1f} nm/V, mechanical pole {c.plant_pole:.0f} rad/s, "
      f"feedforward {c.v_ff:.1f} V")
print(f"PI kp = {c.kp:.4g} V/m, ki = {c.ki:.4g} V/(m s), crossover {c.gain_crossover:.2f} rad/s, "
      f"phase margin {c.phase_margin:.1f} deg, gain margin {c.gain_margin:.3g}  (sampled at {c.dt * 1e3:g} ms, "
      f"inversion {c.frequency:g} Hz)")


def load_step(t):
    return F0 if t < T / 2 else F0 + 1.0


scenarios = {"5 N": compare_hold(params, c, T, include_dc_loop=True),
             "5 N -> 6 N at 150 s": compare_hold(params, c, T, F=load_step)}

with tempfile.TemporaryDirectory(prefix="dfa_hold_") as tmp:
    from fmu import build_fmu
    wall = time.perf_counter()
    path = build_fmu(params, Path(tmp) / "DFAActuator.fmu")
    t_build = time.perf_counter() - wall
    fmu_runs = {"5 N": cosim_hold_fmu(path, c, duration=T),
                "5 N -> 6 N at 150 s": cosim_hold_fmu(path, c, F=load_step, duration=T)}

for name, cmp in scenarios.items():
    print(f"\n{name}: open-loop voltage {cmp['v_open']:.1f} V (full-model statics), metrics after 2 s")
    print(f"{'scheme':22s} {'rms dev um':>11s} {'max dev um':>11s} {'final um':>9s} {'mean|V| V':>10s} "
          f"{'power W':>8s} {'wall s':>7s}")
    rows = dict(cmp["metrics"])
    rows["closed loop (FMU)"] = fmu_runs[name].metrics(X_REF)
    for k, m in rows.items():
        print(f"{k:22s} {m['rms_dev'] * 1e6:11.3f} {m['max_dev'] * 1e6:11.3f} {m['final_error'] * 1e6:9.3f} "
              f"{m['mean_abs_V']:10.1f} {m['hard_switched_power']:8.3f} {m['wall_time']:7.2f}")
    ref, fm = cmp["runs"]["closed loop"], fmu_runs[name]
    print(f"FMU vs in-process closed loop: max |dx| = {np.max(np.abs(fm.x - ref.x)):.3g} m, "
          f"max |dA| = {np.max(np.abs(fm.A - ref.A)):.3g} V")
print(f"\nFMU build {t_build:.1f} s")

fig, ax = plt.subplots(3, 2, figsize=(12, 9), sharex=True, gridspec_kw={"height_ratios": [2, 2, 1.3]})
styles = {"open-loop DC": ("C3", "-"), "inversion": ("C1", "-"), "closed loop": ("C0", "-"),
          "DC loop": ("0.6", "-")}
for j, (name, cmp) in enumerate(scenarios.items()):
    for k, r in cmp["runs"].items():
        color, ls = styles[k]
        for i in (0, 1):
            ax[i, j].plot(r.t, r.x * 1e3, color=color, ls=ls, lw=0.8, label=r.label if i == 0 else None)
        ax[2, j].plot(r.t, r.A / 1e3, color=color, lw=0.8, label=r.label)
    fm = fmu_runs[name]
    for i in (0, 1):
        ax[i, j].plot(fm.t, fm.x * 1e3, color="k", ls="--", lw=0.8, label="closed loop, FMU (fmpy)" if i == 0 else None)
        ax[i, j].axhline(X_REF * 1e3, color="k", lw=0.6, ls=":", label="x_ref" if i == 0 else None)
    ax[1, j].set_ylim((X_REF - 20e-6) * 1e3, (X_REF + 20e-6) * 1e3)
    ax[0, j].set(title=f"vshape-table1, load {name}", ylabel="stroke (mm)")
    ax[1, j].set(ylabel="stroke (mm), zoom +-20 um")
    ax[2, j].set(xlabel="t (s)", ylabel="amplitude |V| (kV)")
    ax[0, j].legend(fontsize=7, loc="upper right")
ax[2, 0].legend(fontsize=7, loc="upper left")
fig.tight_layout()
fig_path.parent.mkdir(parents=True, exist_ok=True)
fig.savefig(fig_path, dpi=120)
print(f"wrote {fig_path}; total {time.perf_counter() - wall0:.1f} s")
