"""Diagnose a synthetic dataset with two concealed effects, the way a user diagnoses a rig.

A "truth" actuator (Table 1, rho_l 2e12) has a 1 Mohm resistance between the source and
the device and a small, fast relaxation of its liquid (chi_p = 0.01, tau_p = 1 s): each
alone changes the paper's headline metric, the average unzipping speed, by less than the
scatter between repetitions. It is measured like a rig: 1 um laser noise, 0.5 um
resolution, a zero offset per recording, 5 % rho_l scatter between repetitions, the
paper's routine (3 s reset at 30 Hz, 20 s hold) at three loads and two voltages. The
nominal actuator.toml the diagnosis sees has rho_l = 3e12 and neither effect (N = 41 to
keep the example to a few minutes). Writes figures/diagnosis/: the dataset, report.json,
report.md and the plots.

    python examples/diagnose_synthetic.py
"""
import os

from _common import OUT

import diagnosis
from dfa_model import preset
from dfa_model.io.recordings import read_dataset
from dfa_model.io.synthetic import Measurement, generate_dataset

TRUTH = {"R_s": 1e6, "chi_p": 0.01, "tau_p": 1.0}


def main():
    root = os.path.join(OUT, "diagnosis")
    nominal = preset("vshape-table1").replace(N=41, rho_l=3e12)
    truth = nominal.replace(rho_l=2e12, **TRUTH)
    generate_dataset(os.path.join(root, "data"), truth, nominal,
                     conditions=[(6000, 3), (6000, 5), (6000, 7), (8000, 5), (8000, 7)], repetitions=3,
                     measurement=Measurement(noise=1e-6, rho_spread=0.05), seed=7)
    ds = read_dataset(os.path.join(root, "data"))
    D = diagnosis.diagnose(ds, progress=lambda s: print(" ", s, flush=True))
    report = diagnosis.write_report(D, root)
    print(report["conclusion"])
    for m in report["missing_physics"]:
        print(f"  {m['name']}: " + ", ".join(f"{k} = {v['value']:.4g} +- {v['stderr']:.2g}"
                                            for k, v in m["parameters"].items()))
    print("  truth:", ", ".join(f"{k} = {v:g}" for k, v in TRUTH.items()))
    hidden = [h["concealed"] for h in report["headline"]]
    print(f"  headline metric: the baseline's error within the repetitions' spread in {sum(hidden)} of "
          f"{len(hidden)} conditions")
    b, i = report["fit"]["baseline"], report["fit"]["improved"]
    print(f"held-out RMSE: baseline {b['heldout_rmse'] * 1e6:.2f} um" +
          (f", improved {i['heldout_rmse'] * 1e6:.2f} um" if i else ""))
    print("wrote", os.path.join(root, "report.md"))


if __name__ == "__main__":
    main()
