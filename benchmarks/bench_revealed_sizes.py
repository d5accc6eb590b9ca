"""The size at which each catalog entry shows in a rig's recordings under a drive: the
trial's sizes (bench_diagnosis_trial.py) are drawn at 1-4x it.

For each entry, a ladder of sizes; at each, a few datasets drawn as the trial draws its
cases (conditions, protocol, sensor noise), the truth carrying the entry at that size,
measured on the rig under the drive, and fitted by the baseline alone
(diagnosis.diagnose(..., candidates=[])). Size 0 is the same draw without the entry: the
error the model leaves on those recordings anyway (at least one sensor noise; above it
under unipolar pulses, where the voltage monitor's gain error shows). An entry is
revealed at a size when the baseline's held-out RMSE is at least REVEALED = 2 times that
floor in the median draw: the verdict rule's own line (the model within 2 noises is
"within the noise"), lifted where the model's floor is higher. The revealed size is the
smallest such size on the ladder; an entry with none up to the ladder's top is not in
these recordings at any size tried, and no diagnosis can name it from them.

    python benchmarks/bench_revealed_sizes.py --rig lab --drive reset_hold [--draws 3] [--out sizes.jsonl]
        [--tau-p 0.1,0.3,1,3]   (the branch's ladder at each of these time constants)

Prints one row per entry and size (each draw's held-out RMSE in noises and whether the
headline metric conceals it) and the revealed size. A rerun with the same --out skips
what is done.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import bench_diagnosis_trial as trial  # noqa: E402

REVEALED = 2.0        # the baseline's held-out RMSE over its floor (the same draw without the entry, >= 1 noise)
TAU_P = 1.0           # the branch's time constant on its ladder (the trial draws 0.1-3 s)
LADDERS = {"stiffness": (0.0, 3.75, 7.5, 15.0, 30.0, 60.0, 240.0, 960.0, 3840.0, 15360.0),
           "inertia": (0.0, 0.00125, 0.0025, 0.005, 0.01, 0.02, 0.04, 0.08),
           "polarization_branch": (0.0, 0.0025, 0.005, 0.01, 0.02, 0.04, 0.08, 0.16),
           "series_resistance": (0.0, 3.125e4, 6.25e4, 1.25e5, 2.5e5, 5e5, 1e6, 2e6),
           "field_dependent_resistivity": (0.0, 1e4, 2e4, 4e4, 8e4, 1.6e5)}
SEED = 777001         # the draws of conditions, protocol and noise (not a trial's seed)


def truth_keys(entry: str, value: float, tau_p: float = TAU_P) -> dict:
    """The truth's parameter changes for `entry` at size `value` (as the trial's draw:
    bench_diagnosis_trial.truth_at, an Eq. (21) law, the branch at tau_p); size 0: none."""
    return {} if value == 0.0 else trial.truth_at(entry, value, tau_p)


def _taus_of(entry: str, value: float, taus: list) -> list:
    """The time constants `entry` is run at, at size `value`: the branch at each of `taus`,
    but its size 0 (the same draw without it, every tau's floor) once, at TAU_P."""
    return list(taus) if entry == "polarization_branch" and value != 0.0 else [TAU_P]


def run_one(job: tuple) -> dict:
    rig_name, drive, entry, value, d, N, tau_p = job
    import warnings
    warnings.simplefilter("ignore")
    import diagnosis
    from dfa_model.io.recordings import read_dataset
    from diagnosis.fit import InProcess
    # conditions, protocol and noise as the trial draws them for this entry
    case = {**trial.draw(trial.EFFECTS.index(entry) + len(trial.EFFECTS) * d, SEED),
            "truth": truth_keys(entry, value, tau_p), "rig": rig_name, "drive": drive, "N": N}
    wall = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        trial.generate(case, Path(tmp) / "data")
        D = diagnosis.diagnose(read_dataset(Path(tmp) / "data"), executor=InProcess(), candidates=[])
        report = diagnosis.report.to_json(D)
    hl = [h["concealed"] for h in report["headline"] if h["concealed"] is not None]
    ho = report["fit"]["baseline"]["heldout_rmse"]
    return {"rig": rig_name, "drive": drive, "entry": entry, "value": value, "draw": d, "N": N, "tau_p": tau_p,
            "heldout_noises": None if ho is None else ho / case["noise"],
            "concealed": all(hl) if hl else None, "noise": case["noise"], "wall_time": time.perf_counter() - wall}


def revealed_size(rows: list, entry: str):
    """The smallest ladder size at which the baseline's held-out RMSE is at least REVEALED
    times what it is on the same draw's recordings without the entry (at least one noise),
    in the median draw. None: no size on the ladder."""
    def h(v):
        return {r["draw"]: r["heldout_noises"] for r in rows
                if r["entry"] == entry and r["value"] == v and r["heldout_noises"] is not None}
    floor = h(0.0)
    for v in LADDERS[entry]:
        if v == 0.0:
            continue
        ratios = [x / max(1.0, floor[d]) for d, x in h(v).items() if d in floor]
        if ratios and float(np.median(ratios)) >= REVEALED:
            return v
    return None


def summarize(rows: list, entries) -> str:
    lines = [f"{'entry':28s} {'size':>10s}  held-out RMSE / noise per draw   headline conceals"]
    for e in entries:
        for v in LADDERS[e]:
            rs = sorted((r for r in rows if r["entry"] == e and r["value"] == v), key=lambda r: r["draw"])
            if rs:
                h = " ".join(f"{r['heldout_noises']:.2f}" for r in rs)
                c = " ".join({True: "yes", False: "no", None: "-"}[r["concealed"]] for r in rs)
                lines.append(f"{e:28s} {v:10.4g}  {h:30s}  {c}")
        rv = revealed_size(rows, e)
        top = LADDERS[e][-1]
        lines.append(f"{e:28s} revealed at {rv:.4g}" if rv is not None else f"{e:28s} not revealed up to {top:.4g}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", choices=["ideal", "lab", "lab_fine"], default="lab")
    ap.add_argument("--drive", choices=["reset_hold", "inversion", "unipolar"], default="reset_hold")
    ap.add_argument("--entries", default=",".join(LADDERS), help="comma-separated catalog entries")
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--N", type=int, default=21)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="revealed_sizes.jsonl")
    ap.add_argument("--tau-p", default=str(TAU_P),
                    help=f"the branch's time constant(s), s, comma-separated (default {TAU_P:g}; the trial draws "
                         "0.1-3)")
    a = ap.parse_args(argv)
    try:
        taus = [float(x) for x in a.tau_p.split(",") if x]
    except ValueError:
        ap.error(f"--tau-p: got {a.tau_p!r}, expected comma-separated time constants in s")
    if not taus or not all(1e-3 <= x <= 1e3 for x in taus):
        ap.error(f"--tau-p: got {a.tau_p!r}, expected time constants within 1e-3-1e3 s")
    entries = [e for e in a.entries.split(",") if e]
    bad = [e for e in entries if e not in LADDERS]
    if bad:
        ap.error(f"--entries: unknown {', '.join(bad)}; expected some of {', '.join(LADDERS)}")
    out = Path(a.out)
    rows = [json.loads(line) for line in out.read_text().splitlines()] if out.exists() else []
    rows = [r for r in rows if r["rig"] == a.rig and r["drive"] == a.drive and r["N"] == a.N]
    for r in rows:                  # rows from before --tau-p: the branch at TAU_P
        r.setdefault("tau_p", TAU_P)
    done = {(r["entry"], r["value"], r["draw"], r["tau_p"]) for r in rows}
    jobs = [(a.rig, a.drive, e, v, d, a.N, t) for e in entries for v in LADDERS[e] for t in _taus_of(e, v, taus)
            for d in range(a.draws) if (e, v, d, t) not in done]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex, out.open("a") as fh:
        for k, r in enumerate(ex.map(run_one, jobs), 1):
            rows.append(r)
            fh.write(json.dumps(r) + "\n")
            fh.flush()
            print(f"[{k}/{len(jobs)}, {time.perf_counter() - t0:.0f} s] {r['entry']} {r['value']:.4g} draw {r['draw']}: "
                  f"held out {r['heldout_noises']:.2f} noises", file=sys.stderr, flush=True)
    others = [e for e in entries if e != "polarization_branch"]
    if others:
        print(summarize(rows, others))
    if "polarization_branch" in entries:
        for t in taus:
            print(f"polarization_branch at tau_p = {t:g} s")
            print(summarize([r for r in rows if r["entry"] == "polarization_branch"
                             and (r["tau_p"] == t or r["value"] == 0.0)], ["polarization_branch"]))


if __name__ == "__main__":
    main()
