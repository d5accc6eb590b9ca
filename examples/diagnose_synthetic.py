"""Diagnose a synthetic dataset with a hidden stiffness, the way a user diagnoses a rig.

A "truth" actuator (Table 1 with an elastic restoring force k = 300 N/m, rho_l 2e12)
is measured like a rig: 2 um laser noise, 0.5 um resolution, a zero offset per
recording, 3 % rho_l scatter between repetitions. The nominal actuator.toml the
diagnosis sees has rho_l = 3e12 and no stiffness. Writes figures/diagnosis/: the
dataset, report.json, report.md and the plots.

    python examples/diagnose_synthetic.py
"""
import os

from _common import OUT

import diagnosis
from dfa_model import preset
from dfa_model.recordings import read_dataset
from dfa_model.synthetic import generate_dataset


def main():
    root = os.path.join(OUT, "diagnosis")
    nominal = preset("vshape-table1").replace(rho_l=3e12)
    truth = preset("vshape-table1").replace(k=300.0)
    generate_dataset(os.path.join(root, "data"), truth, nominal,
                     conditions=[(6000, 3), (6000, 5), (6000, 7), (8000, 5), (8000, 7)], repetitions=3, seed=7)
    ds = read_dataset(os.path.join(root, "data"))
    D = diagnosis.diagnose(ds, progress=lambda s: print(" ", s, flush=True))
    report = diagnosis.write_report(D, root)
    print(report["conclusion"])
    for m in report["missing_physics"]:
        print(f"  {m['name']}: " + ", ".join(f"{k} = {v['value']:.4g} +- {v['stderr']:.2g}"
                                            for k, v in m["parameters"].items()), "(truth: k = 300)")
    b, i = report["fit"]["baseline"], report["fit"]["improved"]
    print(f"held-out RMSE: baseline {b['heldout_rmse'] * 1e6:.2f} um" +
          (f", improved {i['heldout_rmse'] * 1e6:.2f} um" if i else ""))
    print("wrote", os.path.join(root, "report.md"))


if __name__ == "__main__":
    main()
