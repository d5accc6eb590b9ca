"""A stroke-holding loop built in python-control on the sampled surrogate, against the
compiled loop and the full model.

V-shaped actuator of Table 1, 4 N load, x_ref = 0.5 mm. The PI amplitude law of
reduced.holding (tuned on the surrogate) as a discrete python-control system
(HoldController.system), closed with
control.interconnect around `s.system(dt=...)` (the surrogate sampled every control step
with the inputs held: python-control's defaults are exact there, no ODE solver):

  (a) the amplitude driving a 10 Hz polarity inversion (what `dfa hold` designs);
  (b) the same gains on a DC amplitude, which the full model's interface charge turns into
      a growing oscillation - the sampled system shows it too.

Each loop also runs compiled on the surrogate (holding.simulate_hold_surrogate) and on
the full model (holding.simulate_hold).

    python examples/python_control_loop.py [--quick]

Writes examples/figures/python_control_loop.png and prints the table.
"""
import argparse
import dataclasses
import time
import warnings

import control
import numpy as np
from _common import plt, save

import reduced  # noqa: E402
from dfa_model import PhysicsWarning, preset  # noqa: E402
from reduced import holding  # noqa: E402

warnings.simplefilter("ignore", PhysicsWarning)
X_REF, F = 0.5e-3, 4.0


def python_control_loop(s, c, duration):
    loop = control.interconnect([s.system(dt=c.dt, name="plant"), c.system()], inputs=["force"],
                                outputs=["stroke", "voltage"], check_unused=False)
    T = np.arange(0.0, duration + c.dt / 2, c.dt)
    t0 = time.perf_counter()
    r = control.input_output_response(loop, T, np.full_like(T, F))
    return T, np.asarray(r.outputs[0]), time.perf_counter() - t0


def rms_dev(t, x, t_skip=2.0):
    return float(np.sqrt(np.mean((x[t > t_skip] - X_REF) ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10 s loops instead of 40 s")
    a = ap.parse_args()
    duration = 10.0 if a.quick else 40.0
    p = preset("vshape-table1")
    s = reduced.charge(p)
    c = holding.tune_hold_controller(s, X_REF, F, frequency=10.0)
    rows = []
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.5, 6))
    for ax, (label, cc) in zip(axes, (("10 Hz inversion", c), ("DC amplitude", dataclasses.replace(c, mode="dc")))):
        T, x_pc, w_pc = python_control_loop(s, cc, duration)
        comp = holding.simulate_hold_surrogate(s, cc, duration=duration)
        full = holding.simulate_hold(p, cc, duration=duration)
        rows.append((label, rms_dev(full.t, full.x), rms_dev(comp.t, comp.x), rms_dev(T, x_pc), full.wall_time,
                     comp.wall_time, w_pc))
        ax.plot(full.t, (full.x - X_REF) * 1e6, "k-", lw=1.0, label="full model (Python loop)")
        ax.plot(comp.t, (comp.x - X_REF) * 1e6, "C1--", lw=1.0, label="surrogate, compiled loop")
        ax.plot(T, (x_pc - X_REF) * 1e6, "C0:", lw=1.4, label="surrogate, python-control interconnect")
        late = [np.abs(v[t > 2.0] - X_REF).max() for t, v in ((full.t, full.x), (comp.t, comp.x), (T, x_pc))]
        lim = 1.3e6 * max(late)
        ax.set_ylim(-lim, lim)          # the tracking after the pull-in, not the pull-in itself
        ax.set_ylabel("stroke - x_ref (um)")
        ax.set_title(f"{label}: PI on the amplitude, sampled every {cc.dt * 1e3:g} ms", fontsize=10)
        ax.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    print(f"x_ref {X_REF * 1e3:g} mm, {F:g} N, {duration:g} s; PI kp {c.kp:.4g} V/m, ki {c.ki:.4g} V/(m s), "
          f"step {c.dt * 1e3:g} ms")
    print("| loop | RMS from x_ref after 2 s: full / compiled / python-control (um) | wall: full / compiled / "
          "python-control (s) |")
    print("|---|---|---|")
    for label, df, dc, dp, wf, wc, wp in rows:
        print(f"| {label} | {df * 1e6:.2f} / {dc * 1e6:.2f} / {dp * 1e6:.2f} | {wf:.2f} / {wc:.3f} / {wp:.2f} |")
    save(fig, "python_control_loop.png")


if __name__ == "__main__":
    main()
