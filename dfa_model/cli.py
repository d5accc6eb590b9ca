"""The `dfa` command (see README, 'Command line')."""
from __future__ import annotations

import argparse
import json
import sys
import warnings

from . import parameters
from .dielectrics import PhysicsWarning


class CLIError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        raise CLIError(message)


def _params(args):
    if args.preset and args.params:
        raise CLIError("give either --preset or --params, not both")
    if args.params:
        p = parameters.load(args.params)
    elif args.preset:
        p = parameters.preset(args.preset)
    else:
        raise CLIError("one of --preset NAME or --params FILE is required")
    return parameters.apply_sets(p, args.set)


def _protocol(args):
    from .waveforms import build_protocol
    return build_protocol(args.voltage, args.duration, args.waveform, args.frequency, args.duty, args.reset,
                          args.reset_frequency)


def cmd_params(args):
    if args.params:
        text = parameters.load(args.params).to_toml()
    else:
        text = parameters.preset_text(args.preset or "vshape-table1")
    sys.stdout.write(text)


def cmd_simulate(args):
    import numpy as np

    from .solver import simulate
    p = _params(args)
    proto = _protocol(args)
    if args.dt is not None and not (args.dt > 0):
        raise CLIError(f"--dt: got {args.dt:g}, expected a value > 0 (s)")
    t_eval = None
    if args.dt:
        n = int(np.floor(proto.duration / args.dt + 1e-9))
        t_eval = np.append(np.arange(n + 1) * args.dt, [] if abs(n * args.dt - proto.duration) < 1e-12 else [proto.duration])
    res = simulate(p, proto, load=args.force, t_eval=t_eval)
    if args.out:
        src = f"preset {args.preset}" if args.preset else f"params {args.params}"
        res.to_csv(args.out, comment=f"{src} {' '.join(args.set or [])}; voltage {args.voltage:g} V, "
                                     f"force {args.force:g} N, waveform {args.waveform}, reset {args.reset or 0:g} s, "
                                     f"duration {args.duration:g} s")
    if args.plot:
        res.plot(args.plot)
    if args.json:
        print(json.dumps(res.summary()))
    elif not args.out and not args.plot:
        sys.stdout.write(res.to_csv())
    else:
        s = res.summary()
        print(f"static stroke {s['static_stroke'] * 1e3:.4f} mm, final stroke {s['final_stroke'] * 1e3:.4f} mm, "
              f"unzipping speed {s['unzipping_speed'] * 1e6:.4f} um/s ({s['wall_time'] * 1e3:.1f} ms, "
              f"{s['steps']} steps)" + (f"; wrote {args.out}" if args.out else "") + (f", {args.plot}" if args.plot else ""),
              file=sys.stderr)


def cmd_sweep(args):
    from . import sweep
    p = _params(args)
    settings = {"voltage": args.voltage, "force": args.force, "waveform": args.waveform, "frequency": args.frequency,
                "duty": args.duty, "reset": args.reset, "reset_frequency": args.reset_frequency,
                "duration": args.duration}
    cases = sweep.grid(p, settings, **sweep.parse_vary(args.vary))
    executor = None
    client = None
    if args.scheduler:
        from dask.distributed import Client
        client = Client(args.scheduler)
        executor = client.get_executor()
    try:
        rows = sweep.run(cases, executor=executor, max_workers=args.workers, progress=not args.quiet)
    finally:
        if client is not None:
            client.close()
    if args.out:
        sweep.write_csv(rows, args.out)
    failed = [r for r in rows if r["status"] != "ok"]
    for r in rows:
        if r["status"] == "ok":
            print(f"{r['label']}: static {r['static_stroke'] * 1e3:.4f} mm, unzipping {r['unzipping_speed'] * 1e6:.4f} um/s")
        else:
            print(f"{r['label']}: FAILED {r['error']}")
    if failed:
        print(f"dfa: warning: {len(failed)} of {len(rows)} runs failed (listed above)", file=sys.stderr)
        return 1
    return 0


def cmd_fmu_build(args):
    try:
        from fmu import BuildError, build_fmu
    except ImportError as exc:
        raise CLIError(f"the fmu package is not available ({exc}); install with pip install 'dfa-toolkit[fmu]'")
    if not args.preset and not args.params:
        args.preset = "vshape-table1"
    p = _params(args)
    try:
        out = build_fmu(p, args.out)
    except BuildError as exc:
        raise CLIError(str(exc)) from None
    print(f"wrote {out} (FMI 2.0 co-simulation; inputs voltage, force; parameters from "
          f"{args.params or 'preset ' + args.preset})")


def build_parser():
    ap = _Parser(prog="dfa", description="Dielectric fluid actuator model (continuum RC + 1-DOF mechanics).")
    sub = ap.add_subparsers(dest="command", parser_class=_Parser)
    pp = sub.add_parser("params", help="print a preset or a validated parameter file as TOML")
    pp.add_argument("--preset", choices=list(parameters.PRESETS))
    pp.add_argument("--params", metavar="FILE")
    pp.set_defaults(func=cmd_params)

    ps = sub.add_parser("simulate", help="simulate a protocol; write CSV, plot, JSON metrics")
    ps.add_argument("--preset", choices=list(parameters.PRESETS))
    ps.add_argument("--params", metavar="FILE")
    ps.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a parameter (repeatable)")
    ps.add_argument("--voltage", type=float, required=True, help="amplitude, V")
    ps.add_argument("--force", type=float, default=0.0, help="load opposing zipping, N (default 0)")
    ps.add_argument("--waveform", choices=["dc", "bipolar", "unipolar"], default="dc")
    ps.add_argument("--frequency", type=float, help="square-wave frequency, Hz")
    ps.add_argument("--duty", type=float, help="duty (bipolar: fraction of each half period on, default 1)")
    ps.add_argument("--reset", type=float, default=0.0, metavar="SECONDS",
                    help="charge reset first: bipolar square wave at the same voltage (Sec. 4.2)")
    ps.add_argument("--reset-frequency", type=float, default=30.0, metavar="HZ")
    ps.add_argument("--duration", type=float, help="seconds of the hold stage (after any reset)")
    ps.add_argument("--dt", type=float, default=1e-3, help="output sampling, s (default 1e-3; 0: every step)")
    ps.add_argument("--out", metavar="FILE.csv")
    ps.add_argument("--plot", metavar="FILE.png")
    ps.add_argument("--json", action="store_true", help="print metrics as one JSON object")
    ps.set_defaults(func=cmd_simulate)

    pw = sub.add_parser("sweep", help="run a grid of variants in parallel (local processes or Dask)")
    pw.add_argument("--preset", choices=list(parameters.PRESETS))
    pw.add_argument("--params", metavar="FILE")
    pw.add_argument("--set", action="append", metavar="KEY=VALUE")
    pw.add_argument("--vary", action="append", metavar="KEY=V1,V2,...",
                    help="a parameter key, or voltage/force/reset/duration/frequency/duty/theta0 (repeatable: grid)")
    pw.add_argument("--voltage", type=float, required=True)
    pw.add_argument("--force", type=float, default=0.0)
    pw.add_argument("--waveform", choices=["dc", "bipolar", "unipolar"], default="dc")
    pw.add_argument("--frequency", type=float)
    pw.add_argument("--duty", type=float)
    pw.add_argument("--reset", type=float, default=0.0)
    pw.add_argument("--reset-frequency", type=float, default=30.0)
    pw.add_argument("--duration", type=float)
    pw.add_argument("--workers", type=int, help="local processes (default: all cores)")
    pw.add_argument("--scheduler", metavar="ADDRESS", help="run on a dask.distributed scheduler")
    pw.add_argument("--out", metavar="FILE.csv", help="one row per variant: varied values, metrics, status")
    pw.add_argument("--quiet", action="store_true", help="no progress bar")
    pw.set_defaults(func=cmd_sweep)

    pf = sub.add_parser("fmu", help="FMI 2.0 co-simulation FMU of the model")
    fsub = pf.add_subparsers(dest="fmu_command", parser_class=_Parser, required=True)
    pb = fsub.add_parser("build", help="build the FMU (parameter start values from a preset or file)")
    pb.add_argument("--preset", choices=list(parameters.PRESETS), help="default: vshape-table1")
    pb.add_argument("--params", metavar="FILE")
    pb.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a parameter (repeatable)")
    pb.add_argument("--out", metavar="FILE.fmu", default="DFAActuator.fmu")
    pb.set_defaults(func=cmd_fmu_build)
    return ap


def main(argv=None):
    from .solver import SolverError
    from .waveforms import WaveformError
    ap = build_parser()
    try:
        args = ap.parse_args(argv)
        if not getattr(args, "command", None):
            ap.print_help()
            return 2
        if getattr(args, "dt", None) == 0:
            args.dt = None
        with warnings.catch_warnings():
            warnings.simplefilter("always", PhysicsWarning)
            warnings.showwarning = lambda m, c, *a, **k: print(f"dfa: warning: {m}", file=sys.stderr)
            rc = args.func(args)
        return rc or 0
    except (CLIError, parameters.ParameterError, WaveformError, SolverError, ValueError) as exc:
        print(f"dfa: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("dfa: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
