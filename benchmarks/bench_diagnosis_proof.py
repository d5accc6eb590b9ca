"""The proof on concealed effects as a table: every design of diagnosis.proofs (each
catalog entry, two at once, a null, a wrong nominal t_lz) generated, diagnosed without
the truth, and compared with it: what was named, the recovered parameters, the held-out
RMSE before and after, whether the effect was concealed in the headline metric, and the
wall time of each diagnosis.

    python benchmarks/bench_diagnosis_proof.py [--N 41] [--seeds 21 22] [--only stiffness ...] [--keep DIR]
                                               [--rig ideal|lab] [--drive reset_hold|inversion|unipolar]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import numpy as np  # noqa: E402

from dfa_model.physics.dielectrics import from_parameters  # noqa: E402
from diagnosis.proofs import CASES, DRIVES, E6, RIGS, run  # noqa: E402


def describe(name, D, report, truth) -> dict:
    case = CASES[name]
    named = [m["name"] + (f" ({m['form']})" if m.get("form") else "") for m in report["missing_physics"]]
    corr = [k for k, v in report["corrected_parameters"].items() if v["corrected"] and k != "rho_l"]
    right = sorted(m["name"] for m in report["missing_physics"]) == sorted(case.expected) and \
        all(k in corr for k in case.corrected)
    fitted = {k: v for m in report["missing_physics"] for k, v in m["parameters"].items()}
    fitted.update({k: {"value": v["fitted"], "stderr": v["stderr"]} for k, v in report["corrected_parameters"].items()
                   if k in case.corrected})
    rec = ", ".join(f"{k} = {fitted[k]['value']:.4g} +- {fitted[k]['stderr']:.2g} (truth {t:g})"
                    for k, (t, _) in {**case.tolerances, **case.corrected}.items() if k in fitted)
    if name == "field_dependent_resistivity" and report["missing_physics"]:
        # the law against the truth's over the fields the recordings probe (as the test)
        E = np.linspace(0.8 * 5 / 6 * E6, 7 / 6 * E6, 9)
        dev = np.max(np.abs(from_parameters(D.final.params).rho(E) / from_parameters(truth).rho(E) - 1))
        rec = f"law within {dev:.1%} of the truth over {E[0] / 1e6:.0f}-{E[-1] / 1e6:.0f} MV/m"
        if "m_rho" in fitted:
            rec += (f"; m_rho = {fitted['m_rho']['value']:.3g} +- {fitted['m_rho']['stderr']:.2g} "
                    f"(truth {truth.m_rho:g})")
    b, i = report["fit"]["baseline"], report["fit"]["improved"]
    return {"name": name, "named": ", ".join(named) or "nothing", "right": right, "recovered": rec or "-",
            "heldout": f"{b['heldout_rmse'] * 1e6:.2f} -> {i['heldout_rmse'] * 1e6:.2f}" if i else
            f"{b['heldout_rmse'] * 1e6:.2f}", "noise": b["noise_rms"] * 1e6,
            "concealed": f"{sum(h['concealed'] for h in report['headline'])}/{len(report['headline'])}",
            "wall": D.wall_time}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", type=int, default=41)
    ap.add_argument("--seeds", type=int, nargs="+", default=[21])
    ap.add_argument("--only", nargs="+", choices=list(CASES))
    ap.add_argument("--keep", help="keep the datasets and reports here")
    ap.add_argument("--rig", choices=list(RIGS), default="ideal",
                    help="ideal: the truth at the fit's N, clean channels; lab: the truth at 4x N, lab channels, "
                         "no rest stretch (diagnosis.proofs.RIGS)")
    ap.add_argument("--drive", choices=list(DRIVES), default="reset_hold")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    root = a.keep or tempfile.mkdtemp(prefix="proof_")
    m = RIGS[a.rig]
    print(f"N = {a.N}; rig {a.rig} (truth at N = {m['truth_N'] * a.N}, {m['pretrigger']:g} s rest before the drive, "
          f"{m['measurement']}), drive {a.drive}; 3 conditions x 3 repetitions; work in {root}")
    print("| design | seed | named | recovered | held-out RMSE (um) | noise (um) | concealed | diagnosis (s) |")
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for seed in a.seeds:
        for name in a.only or list(CASES):
            t0 = time.perf_counter()
            D, report, truth = run(name, os.path.join(root, f"{name}_{seed}"), N=a.N, seed=seed, rig=a.rig,
                                   drive=a.drive)
            r = describe(name, D, report, truth)
            rows.append(r)
            print(f"| {name} | {seed} | {r['named']}{'' if r['right'] else ' (WRONG)'} | {r['recovered']} | "
                  f"{r['heldout']} | {r['noise']:.2f} | {r['concealed']} | {time.perf_counter() - t0:.0f} |", flush=True)
    print(f"right: {sum(r['right'] for r in rows)}/{len(rows)}")


if __name__ == "__main__":
    main()
