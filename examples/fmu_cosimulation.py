"""Co-simulation through FMUs: the actuator (dfa fmu build), a drive-electronics FMU
(polarity inversion with slew-rate and current limits) and a mass-spring load FMU, run
together by fmpy at 1 ms communication steps. Two drives: the paper's charge reset
(3 s bipolar at 30 Hz) followed by a DC hold, and a continuous 30 Hz inversion.

    python examples/fmu_cosimulation.py [OUTDIR]

Writes fmu_cosimulation.png and fmu_cosimulation.csv. Copy `cosimulate` in
fmu/cosim.py for your own wiring.
"""
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fmu import build_companion_fmu, build_fmu  # noqa: E402
from fmu.cosim import cosimulate  # noqa: E402

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)
actuator = build_fmu(None, out / "DFAActuator.fmu")          # Table 1 preset
drive = build_companion_fmu("drive", out / "DriveElectronics.fmu")
load = build_companion_fmu("load", out / "MassSpringLoad.fmu")

runs = {}
for mode in ("reset_dc", "inversion"):
    wall = time.perf_counter()
    runs[mode] = cosimulate(actuator, drive, load, 23.0, drive_start={"mode": mode, "amplitude": 6000.0})
    print(f"{mode}: 23 s simulated in {time.perf_counter() - wall:.2f} s")

fig, ax = plt.subplots(3, 1, figsize=(8, 9))
kernel = np.ones(200) / 200          # 0.2 s mean: six inversion periods
for mode, label, color in (("inversion", "30 Hz polarity inversion", "C1"),
                           ("reset_dc", "charge reset (3 s, 30 Hz) + DC", "C0")):
    r = runs[mode]
    ax[0].plot(r["t"], r["stroke"] * 1e3, lw=0.3, alpha=0.25, color=color)
    ax[0].plot(r["t"][199:], np.convolve(r["stroke"], kernel, "valid") * 1e3, lw=1.5, color=color,
               label=label + " (0.2 s mean)")
ax[0].set(xlabel="t (s)", ylabel="stroke (mm)",
          title="Actuator stroke through the FMUs (6 kV, 0.51 kg on 2 kN/m; light: instantaneous)")
ax[0].legend()
r = runs["reset_dc"]
win = (r["t"] >= 2.9) & (r["t"] <= 3.1)
ax[1].plot(r["t"][win], r["voltage"][win] / 1e3, label="drive voltage (kV)")
ax[1].plot(r["t"][win], r["supply_current"][win] * 1e3, label="drive current (mA)")
ax[1].set(xlabel="t (s)", title="Drive at the end of the reset: slew-rate and current limits")
ax[1].legend()
ax[2].plot(r["t"], r["force"], lw=0.6, label="load force on the actuator")
ax[2].set(xlabel="t (s)", ylabel="force (N)")
ax[2].legend()
fig.tight_layout()
fig.savefig(out / "fmu_cosimulation.png", dpi=130)
cols = ["t", "voltage", "supply_current", "force", "stroke"]
np.savetxt(out / "fmu_cosimulation.csv",
           np.column_stack([runs["reset_dc"][c] for c in cols] + [runs["inversion"]["stroke"]]),
           delimiter=",", header=",".join(cols[:-1] + ["stroke_reset_dc", "stroke_inversion"]), comments="")
print(f"wrote {out / 'fmu_cosimulation.png'} and {out / 'fmu_cosimulation.csv'}")
