"""Randomized trial of the diagnosis: datasets with a hidden effect (or none) drawn at
random - which catalog entry, its magnitude, the conditions (three loads or three
voltages), the sensor noise and the repetitions' resistivity spread - diagnosed without
being told the truth. Reports the recovery rate (the named entry is the hidden one; on a
null dataset, nothing named) and the false-alarm rate (missing physics named on a null
dataset), overall and per effect, with the wall time.

    python benchmarks/bench_diagnosis_trial.py [--n 36] [--seed 1] [--workers 2] [--out trial.jsonl]

Each dataset is the test size (N = 21, 3 conditions x 3 repetitions) with the protocol
drawn too: the paper's (3 s reset at 30 Hz + 20 s hold) or a short one (1 s + 10 s), as in
diagnosis.proofs. Datasets run in parallel, each diagnosis in its own process with its
model runs in that process. Results are appended to --out as JSON lines, and a rerun with
the same --out skips what is done.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

EFFECTS = ("null", "stiffness", "inertia", "field_dependent_resistivity", "polarization_branch",
           "series_resistance")
# magnitude ranges (log-uniform): from about the size that is concealed in the headline
# metric at 1 um noise (tests/test_diagnosis.py) up to 4x that
RANGES = {"stiffness": ("k", 15.0, 60.0), "inertia": ("m", 0.02, 0.1), "polarization_branch": ("chi_p", 0.01, 0.04),
          "series_resistance": ("R_s", 5e5, 2e6), "field_dependent_resistivity": ("m_rho", 4e4, 1.6e5)}
# the lab rig's (no rest stretch, fitted sensor zeros, truth at 4x N) revealed sizes per drive:
# the smallest size at which the baseline's held-out RMSE doubles over what it leaves on the
# same recordings without the entry (bench_revealed_sizes.py, 2026-11-28, 3 draws a size,
# docs/guide/diagnosis.md "What the lab rig's recordings reveal"). None: not revealed up to
# the ladder's top (a spring to 15 kN/m, a branch to chi_p 0.04): such an entry leaves no
# trace a diagnosis could name in these recordings, so the trial does not draw it there.
# --sizes revealed draws each entry at 1-4x its size on the trial's rig and drive
REVEALED_LAB = {
    "reset_hold": {"stiffness": None, "inertia": 0.02, "polarization_branch": 0.01, "series_resistance": 1.25e5,
                   "field_dependent_resistivity": 8e4},
    "inversion": {"stiffness": None, "inertia": 0.02, "polarization_branch": None, "series_resistance": 2.5e5,
                  "field_dependent_resistivity": 1.6e5},
    "unipolar": {"stiffness": 30.0, "inertia": 0.01, "polarization_branch": 0.02, "series_resistance": 2e6,
                 "field_dependent_resistivity": 8e4},
}


# the converged truth's rig (lab_fine: the lab's channels, the truth at 31x N) measured the
# same way (bench_revealed_sizes.py --rig lab_fine, 2026-11-29, 3 draws a size; docs/guide/
# diagnosis.md "... the converged truth's own revealed sizes"). The branch's is in
# BRANCH_TAU_FINE, at each time constant measured, which moves it 16x, in
# opposite ways under reset + hold (0.16 at 0.1 s, 0.01 at 3 s) and inversion (0.04 at
# 0.1 s, not revealed at 3 s). The trial drew chi_p 1-4x one size for tau_p 0.1-3 s, and
# fresh lab_fine draws missed two branches at tau_p 0.11 and 0.16 s below their own size
REVEALED_FINE = {
    "reset_hold": {"stiffness": None, "inertia": 0.02, "series_resistance": 1.25e5,
                   "field_dependent_resistivity": 8e4},
    "inversion": {"stiffness": None, "inertia": 0.02, "series_resistance": 2.5e5,
                  "field_dependent_resistivity": 1.6e5},
    "unipolar": {"stiffness": 30.0, "inertia": 0.01, "series_resistance": 1e6,
                 "field_dependent_resistivity": 8e4},
}
BRANCH_TAU_FINE = {   # drive: ((tau_p, revealed chi_p or None), ...) by rising tau_p
    "reset_hold": ((0.1, 0.16), (0.3, 0.04), (1.0, 0.02), (3.0, 0.01)),
    "inversion": ((0.1, 0.04), (0.3, 0.04), (1.0, 0.16), (3.0, None)),
    "unipolar": ((0.1, 0.01), (0.3, 0.02), (1.0, 0.01), (3.0, 0.01)),
}
REVEALED = {"lab": REVEALED_LAB, "lab_fine": REVEALED_FINE}
BRANCH_TAU = {"lab_fine": BRANCH_TAU_FINE}
TAU_P_RANGE = (0.1, 3.0)   # the branch's time constants drawn (log-uniform), s


def branch_sizes(rig: str, drive: str):
    """((tau_p, revealed chi_p), ...) of the rig and drive where measured at several time
    constants, the taus where the branch is not revealed left out; None: not measured so."""
    table = BRANCH_TAU.get(rig, {}).get(drive)
    return None if table is None else tuple((t, v) for t, v in table if v is not None)


def branch_size_at(taus, tau_p: float) -> float:
    """The revealed chi_p at tau_p: log-log between the measured time constants, the
    nearest one's beyond them."""
    t, v = np.log([x for x, _ in taus]), np.log([y for _, y in taus])
    return float(np.exp(np.interp(math.log(tau_p), t, v)))


def ranges(rig: str = "ideal", drive: str = "reset_hold", sizes: str = "ideal") -> dict:
    """entry -> (key, low, high) drawn log-uniformly on this rig and drive. sizes 'ideal':
    RANGES everywhere (1-4x what the ideal rig's reset + hold conceals); 'revealed': on the
    lab rigs 1-4x REVEALED[rig][drive], the entries it does not reveal left out. Where the
    branch was measured at several time constants (BRANCH_TAU) its entry is (key, low, high,
    taus): tau_p is drawn where it is revealed, and chi_p at 1-4x its size there (draw)."""
    if sizes == "ideal" or rig == "ideal":
        return dict(RANGES)
    out = {e: (RANGES[e][0], v, 4.0 * v) for e, v in REVEALED[rig][drive].items() if v is not None}
    taus = branch_sizes(rig, drive)
    if taus:          # its range at 1 s, each draw's moved to its own tau_p (draw)
        v = branch_size_at(taus, 1.0)
        out["polarization_branch"] = (RANGES["polarization_branch"][0], v, 4.0 * v, taus)
    return {e: out[e] for e in RANGES if e in out}


def truth_at(effect: str, value: float, tau_p: float | None = None) -> dict:
    """The truth's changes for `effect` at size `value` (RANGES' key), besides rho_l = 2e12:
    the field law as Eq. (21), rho_l = 2e12 at the zipped field of 6 kV falling with the
    field at slope -value; the branch with time constant tau_p."""
    if effect == "field_dependent_resistivity":
        return {"law": "linear", "m_rho": -value, "q_rho": 2e12 + value * 5.5e7}
    if effect == "polarization_branch":
        return {"chi_p": value, "tau_p": tau_p}
    return {RANGES[effect][0]: value}


def draw(i: int, seed: int, laws_outside: bool = False, rng_of: dict | None = None) -> dict:
    """Case i of the trial. laws_outside: a field law's truth is drawn among Eq. (21) and
    two forms the catalog does not contain (an exponential and a power law in the field,
    dfa_model.io.synthetic), with the same relative slope at the zipped field of 6 kV.
    rng_of: the ranges (ranges(); default RANGES); the effects drawn are the null and the
    entries it has, in turn."""
    rng_of = RANGES if rng_of is None else rng_of
    rng = np.random.default_rng([seed, i])
    effects = [e for e in EFFECTS if e == "null" or e in rng_of]
    effect = effects[i % len(effects)]            # balanced: every effect and the null alike
    by_voltage = bool(rng.integers(2)) or effect == "field_dependent_resistivity"
    if by_voltage:
        V = sorted(rng.choice([5000.0, 6000.0, 7000.0, 8000.0], 3, replace=False))
        conditions = [(float(v), 5.0) for v in V]
    else:
        F = sorted(rng.choice([2.0, 3.0, 4.0, 5.0, 6.0, 7.0], 3, replace=False))
        conditions = [(6000.0, float(f)) for f in F]
    reset, hold = (3.0, 20.0) if rng.integers(2) else (1.0, 10.0)
    truth = {}
    if effect != "null":
        lo, hi = rng_of[effect][1:3]
        value = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
        tau_p = None
        if effect == "polarization_branch":
            taus = rng_of[effect][3] if len(rng_of[effect]) > 3 else None
            # where the branch's size depends on tau_p: tau_p drawn between the time constants
            # where it is revealed, chi_p the same 1-4x of its size there (one draw each, as before)
            t_lo, t_hi = (max(TAU_P_RANGE[0], taus[0][0]), min(TAU_P_RANGE[1], taus[-1][0])) if taus else TAU_P_RANGE
            tau_p = float(math.exp(rng.uniform(math.log(t_lo), math.log(t_hi))))
            if taus:
                value *= branch_size_at(taus, tau_p) / lo
        truth = truth_at(effect, value, tau_p)
        if effect == "field_dependent_resistivity":
            form = ("eq21", "exp", "power")[int(rng.integers(3))] if laws_outside else "eq21"
            if form != "eq21":
                # the same relative slope d ln rho / d ln E at 5.5e7 V/m as the Eq. (21) draw
                truth = {"outside": form, "s": value * 5.5e7 / 2e12}
    return {"i": i, "effect": effect, "truth": truth, "conditions": conditions, "reset": reset, "hold": hold,
            "noise": float(rng.uniform(1e-6, 3e-6)), "rho_spread": float(rng.uniform(0.02, 0.05)),
            "seed": int(rng.integers(1 << 30))}


def generate(case: dict, folder: Path) -> None:
    """Case `case`'s recordings (draw, with its "rig", "drive" and "N") into folder: the
    truth measured on the rig (diagnosis.proofs.RIGS; the drawn noise, and on the ideal
    rig the drawn repetition spread) under the drive (DRIVES)."""
    from dfa_model import preset
    from dfa_model.io.synthetic import Measurement, generate_dataset
    from diagnosis.proofs import DRIVES, RIGS
    rig = RIGS[case.get("rig", "ideal")]
    kind, hz = DRIVES[case.get("drive", "reset_hold")]
    N = case.get("N", 21)
    nominal = preset("vshape-table1").replace(N=N, rho_l=3e12)
    law, keys = None, dict(case["truth"])
    if "outside" in keys:          # a law the parameter file cannot express (draw)
        from dfa_model.io.synthetic import ExponentialResistivity, PowerResistivity
        form, s = keys.pop("outside"), keys.pop("s")
        # the exponential's floor (1e6 ohm m, 1e-6 of the reference) only keeps it positive
        # in the law's check up to 1e10 V/m: at the revealed sizes' steepest (s = 8.8) it
        # underflowed to 0 there; at the probed fields it moves rho_l by 5e-7 of itself
        law = ExponentialResistivity(2e12 * math.exp(s), 5.5e7 / s, 1e6) if form == "exp" else \
            PowerResistivity(2e12, 5.5e7, s, 1e6)
    truth = nominal.replace(**{"rho_l": 2e12, **keys})
    meas = {**rig["measurement"], "noise": case["noise"], "rho_spread": case["rho_spread"]} \
        if case.get("rig", "ideal") == "ideal" else {**rig["measurement"], "noise": case["noise"]}
    generate_dataset(folder, truth.replace(N=rig["truth_N"] * N), nominal, case["conditions"], repetitions=3,
                     reset=case["reset"], hold=case["hold"], measurement=Measurement(**meas), seed=case["seed"],
                     pretrigger=rig["pretrigger"], drive=kind, law=law,
                     **({} if kind == "reset_hold" else {"reset_frequency": hz}))


def run_one(case: dict) -> dict:
    import warnings
    warnings.simplefilter("ignore")
    import diagnosis
    from dfa_model.io.recordings import read_dataset
    from diagnosis.fit import InProcess
    wall = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        generate(case, Path(tmp) / "data")
        D = diagnosis.diagnose(read_dataset(Path(tmp) / "data"), executor=InProcess())
        report = diagnosis.report.to_json(D)
    named = [m["name"] for m in report["missing_physics"]]
    expected = [] if case["effect"] == "null" else [case["effect"]]
    return {**case, "named": named, "right": named[:1] == expected,
            "concealed": all(h["concealed"] for h in report["headline"] if h["concealed"] is not None),
            "heldout_baseline": report["fit"]["baseline"]["heldout_rmse"],
            "heldout_improved": (report["fit"]["improved"] or {}).get("heldout_rmse"),
            "unexplained": (report["unexplained"] or {}).get("measure"),     # None, 'held-out' or 'training'
            # the held-out error with the held-out monitors' common gain fitted as well (None: not asked)
            "heldout_common_gain": (report.get("heldout_common_gain") or {}).get("rmse"),
            "conclusion": report["conclusion"],
            # kept entries the training conditions' common monitor gains stand in for (gain_account)
            "not_separable": (report.get("gain_account") or {}).get("entries", [])
            if (report.get("gain_account") or {}).get("separable") is False else [],
            "parameters": {k: v for m in report["missing_physics"] for k, v in m["parameters"].items()},
            "corrected": [k for k, v in report["corrected_parameters"].items() if v["corrected"] and k != "rho_l"],
            # the discretization checks' records: why an entry stood or was dropped, at which N
            "resolution": report["resolution"], "resolution_first": report["resolution_first"],
            # the resolution check again at a finer N (before and after it: diagnose._again)
            "diagnosed_again": report.get("diagnosed_again"),
            # (kept entry, its rival that explains the data as well, whether a condition tells them apart)
            "alternatives": [(a["entry"], a["rival"], bool((a["separate_at"] or {}).get("tells")))
                             for a in report.get("alternatives") or []],
            "wall_time": time.perf_counter() - wall}


def summarize(rows: list) -> str:
    lines = []
    nulls = [r for r in rows if r["effect"] == "null"]
    effects = [r for r in rows if r["effect"] != "null"]
    right = sum(r["right"] for r in rows)
    fa = sum(bool(r["named"]) for r in nulls)
    lines.append(f"datasets: {len(rows)} ({len(nulls)} null); right: {right}/{len(rows)} = "
                 f"{100 * right / max(len(rows), 1):.0f} % (goal >= 90 %); false alarms on nulls: {fa}/{len(nulls)} = "
                 f"{100 * fa / max(len(nulls), 1):.0f} % (goal <= 10 %)")
    if effects:
        rc = sum(r["right"] for r in effects)
        lines.append(f"hidden effects recovered: {rc}/{len(effects)}; of them concealed in the headline metric: "
                     f"{sum(r['concealed'] for r in effects)}")
    lines.append(f"{'effect':30s} {'n':>3s} {'right':>6s}  named instead")
    for e in EFFECTS:
        rs = [r for r in rows if r["effect"] == e]
        if not rs:
            continue
        wrong = [",".join(r["named"]) or "nothing" for r in rs if not r["right"]]
        lines.append(f"{e:30s} {len(rs):3d} {sum(r['right'] for r in rs):6d}  {'; '.join(wrong)}")
    ns = [r for r in rows if r.get("not_separable")]
    if ns:
        fa_ns = sum(bool(r["named"]) and r["effect"] == "null" for r in ns)
        lines.append(f"named but not separable from the monitors' calibration (gain_account): {len(ns)} ("
                     + ", ".join(f"{r['effect']}: {'+'.join(r['not_separable'])}" for r in ns)
                     + f"); false alarms on nulls without them: {fa - fa_ns}/{len(nulls)}, right among the "
                     f"effects flagged so: {sum(r['right'] for r in ns if r['effect'] != 'null')}")
    alt = [r for r in rows if r.get("alternatives")]
    if alt:
        lines.append(f"kept entries reported with an alternative the data cannot tell apart: {len(alt)} ("
                     + ", ".join(f"{r['effect']}: " + "; ".join(f"{a} or {b}" + (" (a condition tells)" if t else "")
                                                               for a, b, t in r["alternatives"]) for r in alt)
                     + f"); wrong answers with the truth among the alternatives: "
                     f"{sum(not r['right'] and any(b == r['effect'] for _, b, _ in r['alternatives']) for r in alt)}")
    un = [r for r in rows if r.get("unexplained")]
    if un:
        lines.append(f"verdicts of unexplained mismatch: {len(un)} ("
                     + ", ".join(f"{r['effect']}: {r['unexplained']}" for r in un) + ")")
    cal = [r for r in rows if r.get("heldout_common_gain") is not None]
    if cal:
        lines.append(f"held-out errors told again with the held-out monitors' common gain: {len(cal)} ("
                     + ", ".join(f"{r['effect']}: {(r['heldout_improved'] or r['heldout_baseline']) * 1e6:.2f} -> "
                                 f"{r['heldout_common_gain'] * 1e6:.2f} um, noise {r['noise'] * 1e6:.2f}"
                                 for r in cal) + ")")
    wt = [r["wall_time"] for r in rows]
    lines.append(f"wall time per dataset: median {np.median(wt):.0f} s, max {max(wt):.0f} s")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=36)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="trial.jsonl")
    ap.add_argument("--N", type=int, default=21, help="the fit's N (the nominal actuator's)")
    ap.add_argument("--rig", choices=["ideal", "lab", "lab_fine"], default="ideal",
                    help="diagnosis.proofs.RIGS: ideal (truth at the fit's N), lab (truth at 4x N, lab channels, "
                         "no rest stretch; the drawn noise replaces the rig's 2 um) or lab_fine (lab, the truth at 31x "
                         "N: converged)")
    ap.add_argument("--drive", choices=["reset_hold", "inversion", "unipolar"], default="reset_hold")
    ap.add_argument("--sizes", choices=["ideal", "revealed"], default="ideal",
                    help="ideal: every entry at 1-4x what the ideal rig's reset + hold conceals (RANGES); revealed: "
                         "on the lab rigs at 1-4x what their recordings under the drive reveal (REVEALED), the "
                         "entries they do not reveal left out")
    ap.add_argument("--laws-outside", action="store_true",
                    help="draw field laws among Eq. (21), an exponential and a power law (the last two outside the "
                         "catalog's forms)")
    a = ap.parse_args(argv)
    out = Path(a.out)
    done = {}
    if out.exists():
        for line in out.read_text().splitlines():
            r = json.loads(line)
            done[r["i"]] = r
    rng_of = ranges(a.rig, a.drive, a.sizes)
    left_out = [e for e in EFFECTS if e != "null" and e not in rng_of]
    if left_out:
        print(f"not drawn: {', '.join(left_out)} (not revealed by the {a.rig} rig's recordings under {a.drive}; "
              "REVEALED)", file=sys.stderr)
    cases = [{**draw(i, a.seed, a.laws_outside, rng_of), "N": a.N, "rig": a.rig, "drive": a.drive, "sizes": a.sizes}
             for i in range(a.n) if i not in done]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex, out.open("a") as fh:
        futs = {ex.submit(run_one, c): c for c in cases}
        for k, fut in enumerate(as_completed(futs), 1):
            r = fut.result()
            done[r["i"]] = r
            fh.write(json.dumps(r) + "\n")
            fh.flush()
            form = f" ({r['truth']['outside']} law)" if "outside" in r["truth"] else ""
            ho = f"held out {r['heldout_baseline'] * 1e6:.2f} -> {(r['heldout_improved'] or r['heldout_baseline']) * 1e6:.2f}" \
                f" um, noise {r['noise'] * 1e6:.2f}"
            print(f"[{k}/{len(cases)}, {time.perf_counter() - t0:.0f} s] {r['effect']}{form}: named "
                  f"{r['named'] or 'nothing'} ({'right' if r['right'] else 'WRONG'}); {ho}; {r['wall_time']:.0f} s",
                  file=sys.stderr, flush=True)
    print(summarize([done[i] for i in sorted(done) if i < a.n]))
    print(f"sizes ({a.sizes}, {a.rig} rig, {a.drive}): "
          + "; ".join(f"{e} {r[0]} {r[1]:.3g}-{r[2]:.3g}" + (" at tau_p 1 s, scaled by tau_p" if len(r) > 3 else "")
                      for e, r in rng_of.items())
          + (f"; not drawn: {', '.join(left_out)}" if left_out else ""))


if __name__ == "__main__":
    main()
