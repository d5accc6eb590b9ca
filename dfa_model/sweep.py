"""Many runs through any concurrent.futures-style executor (local processes by
default, or a Dask cluster via `client.get_executor()`).

    from dfa_model.sweep import grid, run
    cases = grid(preset("vshape-table1"), dict(voltage=6000, force=5, reset=3, duration=20),
                 rho_l=[2e12, 2.5e12, 3e12], force=[3, 5, 7])
    rows = run(cases)                          # ProcessPoolExecutor, progress bar
    from dask.distributed import Client
    rows = run(cases, executor=Client(cluster).get_executor())

A failing case does not stop the others: its row has status 'error' and the message.
"""
from __future__ import annotations

import csv
import itertools
import time
import traceback
import warnings
from concurrent.futures import as_completed
from contextlib import nullcontext
from dataclasses import dataclass, field

from .io.fileio import write_atomic
from .interrupt import local_pool, owned_pool
from .io.parameters import SPEC, Parameters, coerce
from .waveforms import build_protocol

SETTINGS = ("voltage", "force", "waveform", "frequency", "duty", "reset", "reset_frequency", "duration", "theta0")
METRICS = ("static_stroke", "final_stroke", "unzipping_speed", "wall_time")


@dataclass
class Case:
    """One run: parameters plus protocol settings (the CLI's simulate flags)."""

    label: str
    params: Parameters
    settings: dict
    varied: dict = field(default_factory=dict)


def grid(base: Parameters, settings: dict, **axes) -> list[Case]:
    """Cartesian product of `axes`: parameter keys (rho_l, N, a, ...), protocol settings
    (voltage, force, reset, duration, frequency, ...) or theta0 (deg, v-shaped: sets a).
    Invalid values do not raise here: the case runs and reports the error."""
    names = list(axes)
    for n in names:
        if n not in SPEC and n not in SETTINGS:
            raise ValueError(f"{n}: cannot be varied; use a parameter key ({', '.join(SPEC)}) or one of "
                             f"{', '.join(SETTINGS)}")
        if len(axes[n]) == 0:
            raise ValueError(f"{n}: no values to vary over")
    _check_applicable(base, axes)
    cases = []
    for values in itertools.product(*(axes[n] for n in names)):
        varied = dict(zip(names, values))
        label = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}" for k, v in varied.items())
        cases.append(Case(label or "base", base, {**settings, **{k: v for k, v in varied.items() if k in SETTINGS}},
                          varied))
    return cases


def _check_applicable(base: Parameters, axes: dict) -> None:
    """An axis that no case can use (theta0 of a peano-hasel pouch, m_rho without the
    linear law in any case) is a setup error, reported once before anything runs."""
    from types import SimpleNamespace

    from .io.parameters import applies, not_applicable
    if "theta0" in axes and base.layout != "v-shaped":
        raise ValueError("theta0: applies only to layout 'v-shaped' (a peano-hasel pouch's angle follows from "
                         "its volume); vary volume instead")
    combos = [SimpleNamespace(layout=base.layout, scheme=s, law=w)
              for s in axes.get("scheme", [base.scheme]) for w in axes.get("law", [base.law])]
    for key in axes:
        if key in SPEC and not any(applies(c, key) for c in combos):
            raise ValueError(not_applicable(combos[0], key))


def run_case(case: Case) -> dict:
    """Run one case; never raises (errors are reported in the row)."""
    row = {"label": case.label, **case.varied}
    t0 = time.perf_counter()
    try:
        p = case.params
        changes = {k: v for k, v in case.varied.items() if k in SPEC}
        if changes:
            p = p.replace(**changes)
        s = dict(case.settings)
        if s.get("theta0") is not None:
            p = p.with_theta0(float(s["theta0"]))
        proto = build_protocol(s.get("voltage"), s.get("duration"), s.get("waveform", "dc"), s.get("frequency"),
                               s.get("duty"), s.get("reset", 0.0), s.get("reset_frequency"))
        from .numerics.solver import simulate
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = simulate(p, proto, load=float(s.get("force", 0.0)))
        row.update(res.summary())
        row["status"] = "ok"
        row["warnings"] = "; ".join(sorted({str(w.message) for w in caught}))
    except Exception as exc:  # report, keep the sweep going
        row["status"] = "error"
        row["error"] = f"{type(exc).__name__}: {exc}"
        row["traceback"] = traceback.format_exc(limit=3)
    row["elapsed"] = time.perf_counter() - t0
    return row


def run(cases, executor=None, max_workers=None, progress=True, fn=run_case, desc="sweep") -> list[dict]:
    """Run cases through `executor` (default: local processes). Rows come back in case
    order. With `progress`, a tqdm bar on stderr. `fn` (a picklable module-level
    function of one case returning a dict, never raising) replaces run_case: the
    surrogate fitting uses it to bring back whole stroke records."""
    own = executor is None
    if own:
        executor = local_pool(max_workers)
    # an executor of our own ends with the call; on Ctrl-C (or an error) at once (stop_pool)
    with owned_pool(executor) if own else nullcontext():
        futures = {executor.submit(fn, c): i for i, c in enumerate(cases)}
        rows = [None] * len(cases)
        it, bar = as_completed(futures), None
        try:
            if progress:
                from tqdm import tqdm
                it = bar = tqdm(it, total=len(futures), desc=desc, unit="run")
            for fut in it:
                i = futures[fut]
                try:
                    rows[i] = fut.result()
                except Exception as exc:   # the worker itself died (e.g. killed): say which case
                    rows[i] = {"label": getattr(cases[i], "label", str(i)), **getattr(cases[i], "varied", {}),
                               "status": "error",
                               "error": f"worker failed: {type(exc).__name__}: {exc}"}
        except BaseException:
            for fut in futures:        # a caller's executor (Dask): drop what has not started
                fut.cancel()
            if bar is not None:        # end the bar's line: "dfa: interrupted" had been printed onto it
                bar.close()
            raise
        return rows


def write_csv(rows, path) -> None:
    keys = []
    for r in rows:
        for k in r:
            if k not in keys and k != "traceback":
                keys.append(k)
    def write(tmp):
        with open(tmp, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
            w.writeheader()
            for r in rows:
                w.writerow(r)
    write_atomic(path, write)


def parse_vary(items) -> dict:
    """CLI `--vary KEY=V1,V2,...` into axes."""
    axes = {}
    for item in items or ():
        if "=" not in item:
            raise ValueError(f"--vary: expected KEY=V1,V2,..., got {item!r}")
        key, vals = item.split("=", 1)
        key = key.strip()
        if key in axes:
            raise ValueError(f"--vary: {key} given twice; give all its values in one --vary {key}=V1,V2,...")
        if key in SETTINGS:
            if key == "waveform":
                axes[key] = [v.strip() for v in vals.split(",")]
            else:
                try:
                    axes[key] = [float(v) for v in vals.split(",")]
                except ValueError:
                    raise ValueError(f"{key}: --vary values must be numbers, got {vals!r}") from None
        else:
            axes[key] = [coerce(key, v.strip())[1] for v in vals.split(",")]
    return axes
