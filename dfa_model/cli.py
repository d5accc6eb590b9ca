"""The `dfa` command (see README, 'Command line' and 'Reliability').

Every input is checked before any work starts: flags, parameters, output paths, and
resource limits (limits.py). Bad input prints one line, `dfa: error: ...`, naming the
flag or key and its valid range, and exits with status 2. Physics outside the model's
comfort zone prints `dfa: warning: ...` and still returns a result. Anything else is a
bug: one line `dfa: internal error: ...` and status 70 (the traceback with DFA_DEBUG=1).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
import warnings

from . import limits
from .io import parameters
from .physics.dielectrics import PhysicsWarning
from .io.fileio import PLOT_FORMATS, OutputError, check_writable

EXIT_USAGE, EXIT_SOFTWARE = 2, 70
SCHEDULER_TIMEOUT = 10.0     # s to reach a dask scheduler


class CLIError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # "-1e6", "-inf" are values, not options (argparse only knew "-1" and "-1.5")
        self._negative_number_matcher = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)

    def error(self, message):  # one line, no usage dump
        m = re.match(r"argument (\S+): ignored explicit argument (.*)", message)
        if m:                  # argparse's wording for "--json=1"
            message = f"argument {m.group(1)}: takes no value, expected {m.group(1)} alone (got {m.group(2)})"
        raise CLIError(message)


def _number(lo=None, hi=None, lo_open=False, integer=False):
    """argparse type: a finite number in range, with the range in the error."""
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"got {text!r}, expected a number") from None
        rng = []
        if lo is not None:
            rng.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            rng.append(f"<= {hi:g}")
        want = ("an integer" if integer else "a finite number") + (" " + " and ".join(rng) if rng else "")
        bad = (not math.isfinite(v) or (integer and v != int(v)) or (lo is not None and (v < lo or (lo_open and v == lo)))
               or (hi is not None and v > hi))
        if bad:
            raise argparse.ArgumentTypeError(f"got {text}, expected {want}")
        return int(v) if integer else v
    return parse


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


# the flags a protocol file replaces
DRIVE_FLAGS = ("voltage", "waveform", "frequency", "duty", "reset", "reset_frequency", "duration")


def _protocol(args):
    """The run's protocol: the --protocol file, or the one the drive flags describe."""
    from .waveforms import build_protocol
    if getattr(args, "protocol", None):
        given = [f"--{k.replace('_', '-')}" for k in DRIVE_FLAGS if getattr(args, k, None) not in (None, False)
                 and not (k == "waveform" and args.waveform == "dc") and not (k == "reset" and args.reset == 0)]
        if given:
            raise CLIError(f"--protocol: the protocol file describes the whole drive; remove {', '.join(given)}")
        from .io.protocol_file import load
        return load(args.protocol)
    if args.voltage is None:
        raise CLIError("--voltage: required (amplitude, V), or --protocol FILE")
    return build_protocol(args.voltage, args.duration, args.waveform, args.frequency, args.duty, args.reset,
                          args.reset_frequency)


def _load(args, proto):
    """The run's load: --force if given (it replaces a protocol file's [load], said on
    stderr when they differ), else the protocol file's, else 0 N."""
    from .waveforms import Load
    if args.force is None:
        return proto.load if proto.load is not None else Load(0.0)
    if proto.load is not None and not (proto.load.k_load == 0 and not callable(proto.load.F)
                                       and not hasattr(proto.load.F, "times") and proto.load.F == args.force):
        print(f"dfa: note: --force {args.force:g} N replaces the protocol file's [load]", file=sys.stderr)
    return Load(args.force)


def _describe_drive(args, proto, load) -> str:
    """One line saying what was run (the CSV's comment, the plot's title)."""
    from .io.plotting import describe_load
    if getattr(args, "protocol", None):
        return f"protocol {args.protocol} ({proto.duration:g} s), {describe_load(load)}"
    return (f"voltage {args.voltage:g} V, {describe_load(load)}, waveform {args.waveform}, reset {args.reset or 0:g} s, "
            f"duration {args.duration:g} s")


def _process_start() -> float:
    """time.perf_counter() at this process's start: from /proc (Linux, 10 ms resolution),
    else when this module was imported (after the interpreter's own start-up)."""
    try:
        with open("/proc/self/stat") as f:
            ticks = float(f.read().rsplit(")", 1)[1].split()[19])    # field 22, starttime
        age = time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf("SC_CLK_TCK")
        if 0.0 <= age < 3600.0:
            return time.perf_counter() - age
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    return _IMPORTED


_IMPORTED = time.perf_counter()


def cmd_params(args):
    if args.params and args.preset:
        raise CLIError("give either --preset or --params, not both")
    if args.params:
        text = parameters.load(args.params).to_toml()
    else:
        text = parameters.preset_text(args.preset or "vshape-table1")
    sys.stdout.write(text)


def _output_times(duration, dt):
    """Output times every dt over [0, duration] (and the end), after the memory check."""
    import numpy as np

    from .physics.equations import NREC
    n = math.floor(duration / dt + 1e-9)
    limits.check_rows("--dt", n + 2, NREC, f"--dt {dt:g} s over {duration:g} s; use a larger --dt, or 0 for "
                                           "the solver's own steps")
    return np.append(np.arange(n + 1) * dt, [] if abs(n * dt - duration) < 1e-12 else [duration])


def cmd_simulate(args):
    from .numerics.solver import SolverError, simulate
    p = _params(args)
    proto = _protocol(args)
    if args.out:
        check_writable("--out", args.out)
    if args.plot:
        check_writable("--plot", args.plot, PLOT_FORMATS)
    t_eval = _output_times(proto.duration, args.dt) if args.dt else None
    src = f"preset {args.preset}" if args.preset else f"params {args.params}"
    load = _load(args, proto)
    comment = f"{' '.join([src] + list(args.set or []))}; {_describe_drive(args, proto, load)}"
    try:
        # --json reports the source's input power: the energy record (about 1.7x the run's time)
        res = simulate(p, proto, load=load, t_eval=t_eval, max_steps=args.max_steps, energy=bool(args.json))
    except SolverError as exc:
        part = exc.partial
        if args.out and part is not None and part.t.size:     # never lose what was computed
            part.to_csv(args.out, comment=comment + f"\nPARTIAL: {exc}")
            raise CLIError(f"{exc}; the partial result (up to t = {part.t[-1]:.6g} s) is in {args.out}") from None
        raise
    if args.out:
        res.to_csv(args.out, comment=comment)
    if args.plot:
        res.plot(args.plot, source=" ".join([src] + list(args.set or [])))
    if args.json:
        from ._jit import MODE
        # wall_time: the simulation alone; startup_time: the process until the run began
        # (interpreter, imports, checks, and numba's compilation or cache load if any)
        started = res.started - _process_start()
        print(json.dumps(json_safe({**res.summary(), **res.drive_summary(), "startup_time": started,
                                     "kernels": MODE})))
    elif not args.out and not args.plot:
        sys.stdout.write(res.to_csv())
    else:
        from .io.plotting import periodic_hold
        s = res.summary()
        held, pulses = "", periodic_hold(res)
        if res.period is not None and res.period <= proto.duration:
            held = (f", ripple {res.ripple() * 1e6:.3f} um, drift {res.drift * 1e6:.3f} um (stroke lost against the "
                    f"uncharged static {res.x_static * 1e3:.4f} mm)")
        # a square wave held: the rate the per-period mean stroke is lost at, not the DC hold's chord
        speed = (f"unzipping speed {s['unzipping_speed'] * 1e6:.4f} um/s" if pulses is None else
                 f"drift rate {pulses[1] * 1e6:.4f} um/s (per-period mean)" if math.isfinite(pulses[1]) else
                 "drift rate - (under two periods held)")
        print(f"static stroke {s['static_stroke'] * 1e3:.4f} mm, final stroke {s['final_stroke'] * 1e3:.4f} mm, "
              f"{speed}{held} ({s['wall_time'] * 1e3:.1f} ms, "
              f"{s['steps']} steps)" + (f"; wrote {args.out}" if args.out else "") + (f", {args.plot}" if args.plot else ""),
              file=sys.stderr)


def _dask_executor(address):
    """A dask.distributed client for `address`, or a one-line error within SCHEDULER_TIMEOUT."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise CLIError("--scheduler: dask.distributed is not installed; pip install 'dfa-toolkit[dask]'") from None
    try:
        return Client(address, timeout=SCHEDULER_TIMEOUT)
    except Exception as exc:   # OSError, TimeoutError, ValueError for a malformed address
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CLIError(f"--scheduler: cannot reach {address!r} within {SCHEDULER_TIMEOUT:g} s ({detail})") from None


def cmd_sweep(args):
    from . import sweep
    p = _params(args)
    if args.out:
        check_writable("--out", args.out)
    if args.voltage is None:
        raise CLIError("--voltage: required (amplitude, V)")
    settings = {"voltage": args.voltage, "force": 0.0 if args.force is None else args.force, "waveform": args.waveform, "frequency": args.frequency,
                "duty": args.duty, "reset": args.reset, "reset_frequency": args.reset_frequency,
                "duration": args.duration}
    axes = sweep.parse_vary(args.vary)
    cases = sweep.grid(p, settings, **axes)
    # a protocol no case changes is checked once, here; varied values are reported per case
    if not set(axes) & {"voltage", "duration", "waveform", "frequency", "duty", "reset", "reset_frequency"}:
        _protocol(args)
    client = _dask_executor(args.scheduler) if args.scheduler else None
    try:
        rows = sweep.run(cases, executor=client.get_executor() if client else None, max_workers=args.workers,
                         progress=not args.quiet)
    finally:
        if client is not None:
            client.close()
    if args.out:
        try:
            sweep.write_csv(rows, args.out)
        except OSError as exc:         # the runs are done: keep their results
            import tempfile
            fd, keep = tempfile.mkstemp(prefix="dfa_sweep_", suffix=".csv")
            os.close(fd)
            sweep.write_csv(rows, keep)
            raise CLIError(f"--out: cannot write {args.out} ({exc.strerror}); the results are in {keep}") from None
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


def json_safe(v):
    """v for json.dumps: non-finite numbers become null (JSON has no NaN or Infinity),
    NumPy scalars plain Python ones; dicts and lists recursively. One cleaner for every
    subcommand's --json."""
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_safe(x) for x in v]
    if isinstance(v, float) or type(v).__module__ == "numpy" and hasattr(v, "dtype") and v.dtype.kind == "f":
        v = float(v)
        return v if math.isfinite(v) else None
    if type(v).__module__ == "numpy" and hasattr(v, "dtype") and v.dtype.kind in "biu":
        return v.item()
    return v


def _add_protocol_flags(ps, protocol_file=False):
    V = limits.MAX_VOLTAGE
    ps.add_argument("--voltage", type=_number(-V, V), required=not protocol_file,
                    help="amplitude, V" + (" (or --protocol FILE)" if protocol_file else ""))
    if protocol_file:
        ps.add_argument("--protocol", metavar="DRIVE.toml",
                        help="the drive as a protocol file (docs/reference/protocol-file.md), instead of --voltage, "
                             "--waveform, --frequency, --duty, --reset, --duration")
    ps.add_argument("--force", type=_number(-limits.MAX_FORCE, limits.MAX_FORCE), default=None,
                    help="load opposing zipping, N (default: the protocol file's [load], else 0)")
    ps.add_argument("--waveform", choices=["dc", "bipolar", "unipolar"], default="dc")
    ps.add_argument("--frequency", type=_number(0.0, 1e6, lo_open=True), help="square-wave frequency, Hz")
    ps.add_argument("--duty", type=_number(0.0, 1.0, lo_open=True),
                    help="bipolar: share of each half period at full voltage (default 1: no dead time); unipolar: "
                         "share of each period on (default 0.5)")
    ps.add_argument("--reset", type=_number(0.0, limits.MAX_DURATION), default=0.0, metavar="SECONDS",
                    help="charge reset first: bipolar square wave at the same voltage (Sec. 4.2)")
    ps.add_argument("--reset-frequency", type=_number(0.0, 1e6, lo_open=True), metavar="HZ",
                    help="frequency of the reset (default 30 Hz; only with --reset)")
    ps.add_argument("--duration", type=_number(0.0, limits.MAX_DURATION, lo_open=True),
                    help="seconds of the hold stage (after any reset)")


def _add_params_flags(ps, preset_help=None):
    ps.add_argument("--preset", choices=list(parameters.PRESETS), help=preset_help)
    ps.add_argument("--params", metavar="FILE")
    ps.add_argument("--set", action="append", metavar="KEY=VALUE", help="override a parameter (repeatable)")


BUILTIN = ("params", "simulate", "sweep")


def build_parser(plugins=True, command=None):
    """The `dfa` parser; plugins: with the commands other packages register (only
    `command`'s when it names one of them, else all)."""
    ap = _Parser(prog="dfa", description="Dielectric fluid actuator model (continuum RC + 1-DOF mechanics).")
    sub = ap.add_subparsers(dest="command", parser_class=_Parser)
    pp = sub.add_parser("params", help="print a preset or a validated parameter file as TOML")
    pp.add_argument("--preset", choices=list(parameters.PRESETS))
    pp.add_argument("--params", metavar="FILE")
    pp.set_defaults(func=cmd_params)

    ps = sub.add_parser("simulate", help="simulate a protocol; write CSV, plot, JSON metrics")
    _add_params_flags(ps)
    _add_protocol_flags(ps, protocol_file=True)
    ps.add_argument("--dt", type=_number(0.0), default=1e-3, help="output sampling, s (default 1e-3; 0: every step)")
    ps.add_argument("--max-steps", type=_number(1, 1e9, integer=True), default=limits.MAX_STEPS,
                    help=f"step limit (default {limits.MAX_STEPS:,}): the run stops there with its partial result")
    ps.add_argument("--out", metavar="FILE.csv")
    ps.add_argument("--plot", metavar="FILE.png")
    ps.add_argument("--json", action="store_true", help="print metrics as one JSON object")
    ps.set_defaults(func=cmd_simulate)

    pw = sub.add_parser("sweep", help="run a grid of variants in parallel (local processes or Dask)")
    _add_params_flags(pw)
    pw.add_argument("--vary", action="append", metavar="KEY=V1,V2,...",
                    help="a parameter key, or voltage/force/reset/duration/frequency/duty/theta0 (repeatable: grid)")
    _add_protocol_flags(pw)
    pw.add_argument("--workers", type=_number(1, 1024, integer=True), help="local processes (default: all cores)")
    pw.add_argument("--scheduler", metavar="ADDRESS", help="run on a dask.distributed scheduler")
    pw.add_argument("--out", metavar="FILE.csv", help="one row per variant: varied values, metrics, status")
    pw.add_argument("--quiet", action="store_true", help="no progress bar")
    pw.set_defaults(func=cmd_sweep)

    if plugins:
        _plugins(sub, command)
    return ap


def _plugins(sub, command=None) -> None:
    """Commands of the packages built on this one (fmu build; reduce, compare, design,
    hold; diagnose), registered under the entry-point group 'dfa.commands', each named as
    typed: only `command`'s is imported when it is one (diagnose imports SciPy's
    optimizers: 1 s), else all (help, a typo)."""
    from importlib.metadata import entry_points
    eps = list(entry_points(group="dfa.commands"))
    for ep in [ep for ep in eps if ep.name == command] or eps:
        ep.load()(sub)


def main(argv=None):
    from . import interrupt
    # Ctrl-C stops a compiled run within a step, and the pools at once (interrupt.py)
    with interrupt.armed():
        return _main(sys.argv[1:] if argv is None else list(argv), interrupt)


def _main(argv, interrupt):
    from .numerics.solver import SolverError
    from .waveforms import WaveformError
    try:
        # the plugins' commands (reduce, compare, design, diagnose) import SciPy and
        # python-control: 0.35 s of a warm `dfa simulate`, which needs none of them
        ap = build_parser(plugins=not (argv and argv[0] in BUILTIN), command=argv[0] if argv else None)
        args = ap.parse_args(argv)
        if not getattr(args, "command", None):
            ap.print_help()
            raise CLIError("command: required, one of params, simulate, sweep, fmu, reduce, compare, design, hold, "
                           "diagnose "
                           "(dfa COMMAND --help for more)")
        if getattr(args, "dt", None) == 0:
            args.dt = None
        with warnings.catch_warnings():
            warnings.simplefilter("always", PhysicsWarning)
            warnings.showwarning = lambda m, c, *a, **k: print(f"dfa: warning: {m}", file=sys.stderr)
            rc = args.func(args)
        return rc or 0
    except (CLIError, parameters.ParameterError, WaveformError, SolverError, OutputError, ValueError) as exc:
        print(f"dfa: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:            # a file that vanished or a full disk after the checks
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"dfa: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except MemoryError:
        print("dfa: error: out of memory (see the limits in docs/reliability.md)", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("dfa: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:          # a bug: one line for users, the traceback on request
        if interrupt.received():      # Ctrl-C turned into another exception (a C extension's import)
            print("dfa: interrupted", file=sys.stderr)
            return 130
        if os.environ.get("DFA_DEBUG"):
            raise
        print(f"dfa: internal error: {type(exc).__name__}: {exc} (a bug: please report it; DFA_DEBUG=1 shows "
              f"the traceback)", file=sys.stderr)
        return EXIT_SOFTWARE


if __name__ == "__main__":
    # `python -m dfa_model.cli`: run the package module's main, not this __main__ copy of it,
    # so that the plugins' CLIError (raised from dfa_model.cli) is the one main catches
    from dfa_model.cli import main as _main
    sys.exit(_main())
