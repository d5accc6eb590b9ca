"""`dfa reduce`, `dfa compare`, `dfa design`, `dfa hold`: the surrogates' subcommands.

They plug into the `dfa` command through the entry-point group `dfa.commands`
(pyproject.toml), so dfa_model never imports this package.
"""
from __future__ import annotations

import contextlib
import json
import sys


from dfa_model import cli as base
from dfa_model.cli import json_safe
from dfa_model.io.fileio import check_writable


def register(sub) -> None:
    """All four commands of this package (the entry points name each: pyproject.toml)."""
    from .design_cli import add_design_parser
    from .hold_cli import add_hold_parser
    register_reduce(sub)
    register_compare(sub)
    add_design_parser(sub)
    add_hold_parser(sub)


def register_reduce(sub) -> None:
    pr = sub.add_parser("reduce", help="fit a low-order surrogate to the full model; write it to a file")
    base._add_params_flags(pr)
    pr.add_argument("--family", choices=["lattice", "charge", "lumped"], default=None,
                    help="lattice (default; charge for scheme = 'continuum-p0'): a material point at every node of "
                         "the full model, the most faithful, 9-15x faster than it; charge: 19 states of reduced "
                         "charge dynamics, 20-26x faster, less faithful held out; lumped: the equivalent circuit")
    pr.add_argument("--out", metavar="MODEL.json", required=True)
    pr.add_argument("--workers", type=base._number(1, 1024, integer=True), help="local processes (default: all cores)")
    pr.add_argument("--scheduler", metavar="ADDRESS", help="run the full model on a dask.distributed scheduler")
    pr.add_argument("--quiet", action="store_true", help="no progress bar")
    pr.set_defaults(func=cmd_reduce)


def register_compare(sub) -> None:
    pc = sub.add_parser("compare", help="run the full model and a surrogate on one protocol; errors and speed-up")
    pc.add_argument("model", metavar="MODEL", help="a surrogate file written by dfa reduce")
    base._add_protocol_flags(pc, protocol_file=True)
    pc.add_argument("--plot", metavar="FILE.png", help="both strokes, the error below")
    pc.add_argument("--json", action="store_true", help="print the comparison as one JSON object")
    pc.add_argument("--inversions", choices=("average", "step"), default="average",
                    help="the surrogate's fast full-duty inversions: cycle-averaged but for their last periods "
                         "(default; where the period is under 1 %% of every electrical time constant) or every "
                         "inversion stepped")
    pc.set_defaults(func=cmd_compare)


def cmd_reduce(args) -> int:
    from . import fitting
    p = base._params(args)
    check_writable("--out", args.out, ("json",))
    executor = base._dask_executor(args.scheduler) if args.scheduler else None
    own = None
    if executor is None and args.workers:
        from dfa_model.interrupt import local_pool
        executor = own = local_pool(args.workers)
    # an executor left open ends the process with a traceback; on Ctrl-C it is stopped at once
    from dfa_model.interrupt import owned_pool
    with owned_pool(own) if own is not None else contextlib.nullcontext():
        s = fitting.fit(p, family=args.family, executor=executor, progress=not args.quiet)
    s.save(args.out)
    rows = s.info.get("heldout", [])
    names = s.state_names
    shown = ", ".join(names) if len(names) <= 12 else ", ".join(names[:3]) + ", ..., " + ", ".join(names[-2:])
    print(f"{s.family} surrogate, {s.n_states} states ({shown}); held-out conditions:", file=sys.stderr)
    um = lambda x: f"{x * 1e6:.1f}"   # noqa: E731
    for r in rows:
        head = f"  {r['condition']:42s} RMS error {r['relative_rms_error'] * 100:6.2f} % of range, "
        if r.get("ripple_full") is not None:
            # a periodic drive: the hold's mean slope is the drift, near zero, so its relative
            # error says nothing; ripple and drift are what a drive is judged on
            print(head + f"ripple {um(r['ripple_reduced'])} um (full {um(r['ripple_full'])}), drift "
                  f"{um(r['drift_reduced'])} um (full {um(r['drift_full'])})", file=sys.stderr)
        else:
            se = r["speed_error"]
            print(head + f"unzipping speed error {'-' if se is None else f'{se * 100:.2f} %'}", file=sys.stderr)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


def cmd_compare(args) -> int:
    from .compare import KEYS, compare, plot
    from .files import load
    s = load(args.model)
    proto = base._protocol(args)
    if args.plot:
        check_writable("--plot", args.plot, base.PLOT_FORMATS)
    from .design_cli import surrogate_errors
    with surrogate_errors(args.model):
        row = compare(s, proto, base._load(args, proto), repeats=5, inversions=args.inversions)
    if args.plot:
        plot(row, args.plot)
    out = {k: json_safe(row[k]) for k in KEYS}
    out["averaged_windows"] = [list(w) for w in row["reduced"].averaged_windows]
    if args.json:
        print(json.dumps(out))
        return 0

    def mm(v, unit=1e3, fmt=".4f"):
        return "-" if v is None else format(v * unit, fmt)
    print(f"stroke RMS error   {mm(out['stroke_rms_error'], 1e6, '.2f')} um = "
          f"{mm(out['relative_rms_error'], 100, '.2f')} % of the stroke range ({mm(out['stroke_range'])} mm)")
    print(f"unzipping speed    full {mm(out['unzipping_speed_full'], 1e6)} um/s, reduced "
          f"{mm(out['unzipping_speed_reduced'], 1e6)} um/s")
    print(f"ripple             full {mm(out['ripple_full'])} mm, reduced {mm(out['ripple_reduced'])} mm")
    print(f"drift              full {mm(out['drift_full'])} mm, reduced {mm(out['drift_reduced'])} mm (stroke lost "
          f"against the uncharged static stroke)")
    print(f"wall time          full {out['wall_time_full'] * 1e3:.2f} ms, reduced "
          f"{out['wall_time_reduced'] * 1e3:.3f} ms: {out['speedup']:.0f}x ({out['states']} states)")
    for t0, t1 in out["averaged_windows"]:
        print(f"cycle-averaged     {t0:g}-{t1:g} s (the surrogate's stroke there is the period mean; "
              f"--inversions step steps every inversion)")
    return 0
