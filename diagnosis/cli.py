"""dfa diagnose DATASET --out DIR (registered under the entry-point group 'dfa.commands')."""
from __future__ import annotations

import contextlib
import shutil
import sys
import time
from pathlib import Path


def register(sub) -> None:
    from dfa_model import cli as base
    pd = sub.add_parser("diagnose", help="fit recordings, locate the mismatch, name and model the missing physics")
    pd.add_argument("dataset", metavar="DATASET", help="a folder with actuator.toml and one CSV per test (or HDF5/TDMS "
                    "files described by a dataset.toml)")
    pd.add_argument("--out", metavar="DIR", required=True, help="where report.json, report.md and the plots go")
    pd.add_argument("--workers", type=base._number(1, 1024, integer=True), help="local processes (default: all cores)")
    pd.add_argument("--scheduler", metavar="ADDRESS", help="run the full model on a dask.distributed scheduler")
    pd.add_argument("--quiet", action="store_true", help="no progress lines")
    pd.set_defaults(func=cmd_diagnose)


def cmd_diagnose(args) -> int:
    from dfa_model.io.recordings import read_dataset
    ds = read_dataset(args.dataset)          # a bad dataset fails before anything is created
    out = Path(args.out)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--out: cannot create folder '{args.out}': {exc.strerror}") from None
    try:
        return _diagnose(args, ds, out)
    except BaseException:
        # Ctrl-C or a failure: a folder this run created goes again; in one that was there,
        # report.json (written last, removed first) tells a complete report
        if created:
            shutil.rmtree(out, ignore_errors=True)
        raise


def _diagnose(args, ds, out) -> int:
    from dfa_model.io.fileio import check_writable
    from dfa_model.interrupt import owned_pool

    from .diagnose import diagnose
    from .fit import local_executor
    from .report import write
    check_writable("--out", out / "report.json")
    t0 = time.perf_counter()
    say = None if args.quiet else (lambda s: print(f"[{time.perf_counter() - t0:6.1f} s] {s}", file=sys.stderr,
                                                   flush=True))
    client = None
    if args.scheduler:
        # the CLI's own connection: one line naming --scheduler if it is not reached in time
        from dfa_model.cli import _dask_executor
        client = _dask_executor(args.scheduler)
        executor = client.get_executor()
    else:
        executor = local_executor(args.workers)
    try:
        with owned_pool(executor) if not args.scheduler else contextlib.nullcontext():
            D = diagnose(ds, executor=executor, progress=say)
    finally:
        if client is not None:
            client.close()
    report = write(D, args.out)
    print(f"{report['conclusion']}; baseline held-out RMSE "
          f"{_um(D.baseline.heldout_rmse)}, improved {_um(D.final.heldout_rmse) if D.improved else '-'}; "
          f"wrote {args.out}/report.json, report.md, {report['improved_params']} (the improved model: "
          f"dfa simulate --params {args.out}/{report['improved_params']}) and protocols/")
    return 0


def _um(x):
    return "-" if x is None else f"{x * 1e6:.3g} um"
