"""`dfa hold`: tune the stroke-holding loop on a surrogate and compare it, on the full
model, with open-loop DC and fixed-frequency inversion over a long hold (holding.py)."""
from __future__ import annotations

import json
import sys

import numpy as np

from dfa_model import cli as base
from dfa_model.io.fileio import check_writable, write_atomic

from dfa_model.cli import json_safe

from .design_cli import add_model_flags, params_and_surrogate


def add_hold_parser(subparsers):
    ph = subparsers.add_parser("hold", help="hold a commanded stroke: PI loop tuned on the surrogate, checked on the "
                                            "full model against open-loop DC and fixed inversion")
    base._add_params_flags(ph)
    ph.add_argument("--stroke", type=base._number(0.0, 1.0, lo_open=True), required=True, metavar="X",
                    help="commanded stroke, m")
    ph.add_argument("--force", type=base._number(-1e6, 1e6), required=True, metavar="F", help="load, N")
    ph.add_argument("--duration", type=base._number(0.0, 1e5, lo_open=True), default=300.0, metavar="S",
                    help="length of the hold, s (default 300)")
    ph.add_argument("--frequency", type=base._number(0.0, 1e3, lo_open=True), default=10.0, metavar="HZ",
                    help="polarity-inversion frequency of the drive, Hz (default 10)")
    ph.add_argument("--dt", type=base._number(0.0, 1.0, lo_open=True), metavar="S",
                    help="control step, s (default: the longest step <= 0.01 s that divides the half period)")
    add_model_flags(ph)
    ph.add_argument("--quiet", action="store_true", help="no progress bar when a surrogate is fitted")
    ph.add_argument("--plot", metavar="FILE.png", help="the three strokes and the loop's amplitude")
    ph.add_argument("--json", action="store_true", help="print controller and metrics as one JSON object on stdout (the summary goes to stderr)")
    ph.set_defaults(func=cmd_hold)
    return ph


# holding.py names its arguments; the command's errors name the flags that set them
FLAGS = {"x_ref": "--stroke", "F": "--force", "duration": "--duration", "frequency": "--frequency", "dt": "--dt"}


def _flag_error(exc) -> base.CLIError:
    """A holding.py ValueError ('x_ref: ...') as the command's error, named by its flag."""
    name, sep, rest = str(exc).partition(": ")
    return base.CLIError(f"{FLAGS[name]}: {rest}" if sep and name in FLAGS else str(exc))


def cmd_hold(args) -> int:
    from .frozen import as_model
    from .holding import check_hold, compare_hold, tune_hold_controller
    if args.plot:
        check_writable("--plot", args.plot, base.PLOT_FORMATS)
    def checked(p):
        model = as_model(p)
        if args.stroke >= model.kin.x_e:
            raise base.CLIError(f"--stroke: got {args.stroke:g} m, expected a value below the full stroke x_e = "
                                f"{model.kin.x_e:g} m")
        return model
    if args.preset or args.params:
        checked(base._params(args))        # before a surrogate is fitted
    p, s, note = params_and_surrogate(args, lambda text: print(f"dfa: {text}", file=sys.stderr))
    model = checked(p)
    try:
        c = tune_hold_controller(s, args.stroke, args.force, frequency=args.frequency, dt_control=args.dt)
        check_hold(c, args.duration)        # before the three runs on the full model
    except ValueError as exc:
        raise _flag_error(exc) from None
    out = sys.stderr if args.json else sys.stdout     # --json: stdout is the JSON alone
    print(f"PI loop tuned on the {s.family} surrogate ({note}) at {args.stroke * 1e3:g} mm, {args.force:g} N: "
          f"kp {c.kp:.4g} V/m, ki {c.ki:.4g} V/(m s), feedforward {c.v_ff:.0f} V, inversion {c.frequency:g} Hz; "
          f"phase margin {c.phase_margin:.0f} deg, crossover {c.gain_crossover:.3g} rad/s", file=out)
    try:
        cmp = compare_hold(model, c, args.duration)
    except ValueError as exc:
        raise _flag_error(exc) from None
    print(f"full model, {args.duration:g} s hold (deviation from the commanded stroke after 2 s):", file=out)
    print(f"  {'scheme':16s} {'rms um':>9s} {'max um':>9s} {'drift um':>9s} {'mean |V|':>9s} {'P_hs mW':>9s}", file=out)
    for name, m in cmp["metrics"].items():
        print(f"  {name:16s} {m['rms_dev'] * 1e6:9.2f} {m['max_dev'] * 1e6:9.2f} {m['drift'] * 1e6:9.2f} "
              f"{m['mean_abs_V']:9.0f} {m['hard_switched_power'] * 1e3:9.3g}", file=out)
    print("  (drift: stroke lost against the commanded stroke over the last inversion period, positive when lost; "
          "P_hs: what a hard-switched source spends)", file=out)
    if args.plot:
        _plot(cmp, args.plot, 1.0 / c.frequency if c.frequency else None)
        print(f"wrote {args.plot}", file=sys.stderr)
    if args.json:
        ctrl = {k: getattr(c, k) for k in ("kp", "ki", "v_ff", "v_max", "dt", "mode", "frequency", "phase_margin",
                                           "gain_margin", "gain_crossover")}
        print(json.dumps(json_safe({"controller": ctrl, "v_open": cmp["v_open"], "metrics": cmp["metrics"]})))
    return 0


def _plot(cmp, path, period=None):
    """Stroke of the three schemes; below, the deviation from the commanded stroke of the
    two that hold it (on the stroke's scale they lie on top of each other): the ripple
    faint, its mean over each inversion period (`period`, s) bold; and the loop's
    amplitude."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, axd, axa) = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True, height_ratios=[3, 1.6, 1.3])
    held = {"inversion": dict(ls="--", lw=1.2), "closed loop": dict(lw=1.2)}
    x_ref = cmp["x_ref"]
    t_end = max(float(r.t[-1]) for r in cmp["runs"].values())
    t_settle = min(2.0, 0.2 * t_end)        # the pull-in's overshoot would set the deviation's scale
    lo, hi = np.inf, -np.inf
    for k, (name, r) in enumerate(cmp["runs"].items()):
        ax.plot(r.t, r.x * 1e3, label=name, color=f"C{k}", **held.get(name, dict(lw=1)))
        if name not in held:
            continue
        dev = (r.x - x_ref) * 1e6
        axd.plot(r.t, dev, color=f"C{k}", lw=0.5, alpha=0.3)
        late = dev[r.t >= t_settle]
        if late.size:
            lo, hi = min(lo, float(late.min())), max(hi, float(late.max()))
        if period and t_end > 2 * period:
            # the mean over each inversion period: the drift, without the ripple
            tg = np.arange(0.0, t_end, period / 50.0)
            dg = np.interp(tg, r.t, dev)
            m = np.convolve(dg, np.ones(50) / 50.0, mode="valid")
            axd.plot(tg[25:25 + len(m)], m, color=f"C{k}", label=f"{name} (period mean)", **held[name])
    ax.axhline(x_ref * 1e3, color="k", ls=":", lw=0.8, label="commanded")
    ax.set_ylabel("stroke (mm)")
    ax.legend(loc="best")
    ax.set_title("Holding a stroke on the full model")
    axd.axhline(0.0, color="k", ls=":", lw=0.8)
    axd.set_ylabel("stroke - commanded (um)")
    if np.isfinite(lo):
        pad = 0.1 * max(hi - lo, 1e-3)
        axd.set_ylim(lo - pad, hi + pad)
    if axd.get_legend_handles_labels()[0]:
        axd.legend(loc="best", fontsize="small")
    r = cmp["runs"]["closed loop"]
    axa.plot(r.t, r.A / 1e3, color="C2", lw=1)
    axa.set_ylabel("loop amplitude (kV)")
    axa.set_xlabel("time (s)")
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120, format=str(path).rsplit(".", 1)[-1]))
    plt.close(fig)
