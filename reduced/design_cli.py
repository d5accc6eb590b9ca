"""`dfa design`: the polarity-inversion drive that holds a stroke (design.py), on a fitted
surrogate (`--model`, or one fitted and cached per parameter set: model_cache.py), written
as a protocol file (`--out`) and drawn (`--plot`)."""
from __future__ import annotations

import contextlib
import json
import sys

from dfa_model import cli as base
from dfa_model.cli import json_safe
from dfa_model.io.fileio import PLOT_FORMATS, check_writable, write_atomic


def add_model_flags(p) -> None:
    """--model and --family, shared by `dfa design` and `dfa hold`."""
    p.add_argument("--model", metavar="MODEL.json",
                   help="a fitted surrogate (dfa reduce --out); default: fit one for the parameters and cache it")
    p.add_argument("--family", choices=["lattice", "charge", "lumped"], default=None,
                   help="surrogate family when none is given with --model (default lattice, the most faithful; "
                        "charge for scheme = 'continuum-p0'; charge: 19 states, faster, less faithful held out)")


@contextlib.contextmanager
def surrogate_errors(name):
    """A surrogate whose integration stops (reduced.SurrogateError: maps that are not an
    actuator's, as in a damaged file) is an error of the command naming where the
    surrogate came from (`name`: its file, or the parameters it was fitted for), as the
    full model's SolverError is: one line, exit 2."""
    from .surrogate import SurrogateError
    try:
        yield
    except SurrogateError as exc:
        raise base.CLIError(f"{name}: {exc}; expected a surrogate that runs this drive (a damaged file: fit it again "
                            f"with dfa reduce)") from None


def surrogate_source(args) -> str:
    """Where a command's surrogate came from, for its errors: --model's file, or the
    parameters it was fitted for."""
    return args.model or args.params or f"--preset {args.preset}"


def params_and_surrogate(args, say):
    """(params, surrogate, note) of a design or hold command: the parameters from --preset
    or --params (or, with --model alone, the model's own), the surrogate from --model
    (checked: the same device) or the cache."""
    from dfa_model.io import parameters

    from .model_cache import surrogate_for
    from .files import load
    if args.model and not (args.preset or args.params):
        s = load(args.model)
        p = parameters.apply_sets(s.params, args.set)
        if args.set:
            from .model_cache import check_same_device
            check_same_device(s, p, args.model, "--set")
        return p, s, f"parameters and surrogate from {args.model}"
    p = base._params(args)
    name = args.params or f"preset {args.preset}"
    if args.set:
        name += " with --set " + " ".join(args.set)
    s, note = surrogate_for(p, args.family, args.model, name, progress=not getattr(args, "quiet", False), say=say)
    if args.model:
        note = f"surrogate from {args.model}" + (f"; {note}" if note else "")
    return p, s, note


def add_design_parser(subparsers):
    """`dfa design`: the subcommand's flags (register with the dfa command's subparsers)."""
    pd = subparsers.add_parser("design", help="polarity-inversion frequency window that holds the stroke")
    base._add_params_flags(pd)
    add_model_flags(pd)
    pd.add_argument("--voltage", type=base._number(0.0, 1e6, lo_open=True), required=True, metavar="V",
                    help="amplitude, V")
    pd.add_argument("--force", type=base._number(-1e6, 1e6), required=True, metavar="F", help="load, N")
    pd.add_argument("--max-ripple", type=base._number(0.0, lo_open=True), required=True, metavar="M",
                    help="peak-to-peak stroke over the last period, m")
    pd.add_argument("--max-drift", type=base._number(0.0, lo_open=True), required=True, metavar="D",
                    help="stroke lost against the uncharged static stroke by the end of the horizon, m")
    pd.add_argument("--horizon", type=base._number(0.0, 1e7, lo_open=True), required=True, metavar="S",
                    help="how long the stroke must be held, s")
    pd.add_argument("--slew-rate", type=base._number(0.0, lo_open=True), metavar="V_PER_S",
                    help="the source's slew rate, V/s (default: ideal switching)")
    pd.add_argument("--current-limit", type=base._number(0.0, lo_open=True), metavar="A",
                    help="the source's current limit, A")
    pd.add_argument("--out", metavar="DRIVE.toml", help="write the recommended drive as a protocol file")
    pd.add_argument("--plot", metavar="FILE.png", help="ripple and drift over frequency, the checks and the window")
    pd.add_argument("--quiet", action="store_true", help="no progress bar when a surrogate is fitted")
    pd.add_argument("--json", action="store_true", help="print the design as one JSON object on stdout (the summary goes to stderr)")
    pd.set_defaults(func=design_command)
    return pd


def _um(v):
    return "-" if v is None else f"{v * 1e6:.2f} um"


def _mw(v):
    return "-" if v is None else f"{v * 1e3:.3g} mW"


def header(d, source, family, note) -> list:
    """The provenance lines of a designed drive's protocol file."""
    from dfa_model import __version__
    lim = (f"slew rate {d.slew_rate:g} V/s" if d.slew_rate else "ideal switching") + \
        f" (ramp {d.t_ramp * 1e3:.4g} ms per inversion)"
    lines = [f"designed by dfa design (dfa-toolkit {__version__}) for {source}, on the {family} surrogate",
             f"({note})" if note else "",
             f"spec: ripple <= {_um(d.max_ripple)}, drift <= {_um(d.max_drift)} over {d.horizon:g} s at {d.V:g} V "
             f"against {d.F:g} N; {lim}",
             f"window {d.f_min:.4g} - {d.f_max:.4g} Hz; recommended {d.frequency:.6g} Hz, full-duty inversion "
             "started at the charge-balanced phase"]
    if d.verified:
        v = d.verified
        lines.append(f"full model over the horizon: ripple {_um(v['ripple'])}, drift {_um(v['drift'])}, input power "
                     f"{_mw(v['input_power'])}: {'meets' if v['meets'] else 'DOES NOT MEET'} the spec")
    return [ln for ln in lines if ln]


def design_command(args) -> int:
    """`dfa design`: surrogate, design, summary (and JSON, protocol file, plot)."""
    from .design import EDGE_PERIODS, design_inversion
    if args.out:
        check_writable("--out", args.out, ("toml",))
    if args.plot:
        check_writable("--plot", args.plot, PLOT_FORMATS)
    out = sys.stderr if args.json else sys.stdout     # --json: stdout is the JSON alone
    p, s, note = params_and_surrogate(args, lambda text: print(f"dfa: {text}", file=sys.stderr))
    with surrogate_errors(surrogate_source(args)):
        d = design_inversion(s, args.voltage, args.force, args.max_ripple, args.max_drift, args.horizon,
                             slew_rate=args.slew_rate, current_limit=args.current_limit, params=p)
    src = args.params or (f"preset {args.preset}" if args.preset else args.model)
    print(f"full-duty polarity inversion at {d.V:g} V, {d.F:g} N, held {d.horizon:g} s ({s.family} surrogate; "
          f"{note})", file=out)
    print(f"  static stroke {d.x_static * 1e3:.4f} mm, capacitance {d.capacitance * 1e12:.1f} pF, "
          f"ramp {d.t_ramp * 1e3:.4g} ms per inversion", file=out)
    print(f"  limits: ripple <= {_um(d.max_ripple)}, drift <= {_um(d.max_drift)} (stroke lost against the static "
          f"stroke)", file=out)
    if d.feasible:
        print(f"  window   {d.f_min:.4g} - {d.f_max:.4g} Hz", file=out)
        print(f"  use      {d.frequency:.4g} Hz, duty 1 (no dead time), started at phase {d.phase:.4g} (charge-"
              f"balanced): surrogate ripple {_um(d.ripple)}, drift {_um(d.drift)}", file=out)
        if d.verified:
            v = d.verified
            print(f"  full model at {d.frequency:.4g} Hz: ripple {_um(v['ripple'])}, drift {_um(v['drift'])}: "
                  f"{'meets' if v['meets'] else 'DOES NOT MEET'} the limits ({v['wall_time']:.2f} s)", file=out)
        pw = d.power
        print(f"  power    {_mw(pw['hard_switched_dissipation'])} dissipated by a hard-switched source (4 f C V^2); "
              f"{_mw(pw['input'])} delivered to the actuator by the drive as designed (full model, last period)",
              file=out)
        if d.reason != "ok":
            print(f"  note: {d.reason}", file=out)
    else:
        print(f"  no frequency meets the limits: {d.reason}", file=out)
    print(f"  wall time {d.wall_time:.2f} s", file=out)
    rc = 0
    if args.out:
        if d.feasible:
            written = d.protocol().save(args.out, header(d, src, s.family, note))
            who = f"--params {args.params}" if args.params else f"--preset {args.preset}" if args.preset else \
                "--params FILE"
            print(f"  wrote {written[0]} (replay: dfa simulate {who} --protocol {written[0]} --json)", file=out)
        else:
            # the design ran and is reported (the reason above, the JSON): not an input error (exit 2)
            # but a request it could not meet, as a sweep with failed runs: a warning and exit 1
            print("dfa: warning: --out: nothing written: no drive meets the limits", file=sys.stderr)
            rc = 1
    if args.plot:
        from .design import check_edges
        skipped = check_edges(p, d)     # the full model at the window's edges too: the picture's points
        plot_design(d, args.plot)
        if skipped:
            print(f"  (plot: no full-model point at {', '.join(f'{f:.3g} Hz' for f in skipped)}: more than "
                  f"{EDGE_PERIODS} periods over the horizon)", file=out)
        print(f"  wrote {args.plot}", file=out)
    if args.json:
        print(json.dumps(json_safe({**d.to_dict(), "surrogate": note, "protocol": args.out if d.feasible else None})))
    return rc


def plot_design(d, path, title=None) -> None:
    """Ripple and drift over frequency from the surrogate's scan, the full model's checks
    as points, the spec's lines, the window shaded and the recommendation marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    fig, (ar, ad) = plt.subplots(2, 1, sharex=True, figsize=(7.5, 6.2), height_ratios=[1, 1])
    sc = d.scan
    f = np.asarray(sc.get("frequency", []))
    if f.size:
        ar.plot(f, np.asarray(sc["ripple"]) * 1e6, "C0.-", lw=1.2, ms=3, label="surrogate (averaged), scan")
        ad.plot(f, np.asarray(sc["drift"]) * 1e6, "C0.-", lw=1.2, ms=3, label="surrogate (averaged), scan")
    ar.axhline(d.max_ripple * 1e6, color="C3", ls="--", lw=1, label=f"spec: ripple <= {d.max_ripple * 1e6:.3g} µm")
    ad.axhline(d.max_drift * 1e6, color="C3", ls="--", lw=1, label=f"spec: |drift| <= {d.max_drift * 1e6:.3g} µm")
    ad.axhline(-d.max_drift * 1e6, color="C3", ls="--", lw=1)
    ad.axhline(0.0, color="0.7", lw=0.6)
    for ax in (ar, ad):
        if d.feasible:
            ax.axvspan(d.f_min, d.f_max, color="C2", alpha=0.12, lw=0, label="window (surrogate)")
            ax.axvline(d.frequency, color="C2", lw=1.4, label=f"recommended {d.frequency:.3g} Hz")
        ax.set_xscale("log")
    shown = set()
    for c in d.checks:
        label = "full model: meets the spec" if c["meets"] else "full model: misses the spec"
        kw = dict(marker="o" if c["meets"] else "X", ms=8, ls="none", mec="k", color="C1" if c["meets"] else "C3",
                  label=None if label in shown else label)
        shown.add(label)
        ar.plot(c["frequency"], c["ripple"] * 1e6, **kw)
        ad.plot(c["frequency"], c["drift"] * 1e6, **kw)
    ar.set_ylabel("ripple (µm, peak to peak\nover the last period)")
    ad.set_ylabel("drift (µm, stroke lost\nagainst the static stroke)")
    ad.set_xlabel("inversion frequency (Hz)")
    if f.size:
        ar.set_yscale("log")
        lo = max(1e-3, 0.5 * min(np.min(sc["ripple"]), d.max_ripple) * 1e6)
        ar.set_ylim(lo, 2 * max(np.max(sc["ripple"]), d.max_ripple) * 1e6)
        span = max(np.max(np.abs(sc["drift"])), d.max_drift) * 1e6
        ad.set_ylim(-1.15 * min(span, 8 * d.max_drift * 1e6), 1.15 * min(span, 8 * d.max_drift * 1e6))
    ar.legend(fontsize=7, loc="upper right")
    ad.legend(fontsize=7, loc="lower left")
    ramp = f"ramps {d.t_ramp * 1e3:.3g} ms" if d.t_ramp > 0 else "ideal switching"
    ar.set_title(title or f"Drive design: {d.V / 1e3:g} kV, {d.F:g} N, {d.horizon:g} s horizon, {ramp}\n"
                          + (f"window {d.f_min:.3g}-{d.f_max:.3g} Hz" if d.feasible else "infeasible: " + d.reason[:80]),
                 fontsize=10)
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=130, format=str(path).rsplit(".", 1)[-1]))
    plt.close(fig)
