"""Convergence in N of the Peano-HASEL unzipping speed (Fig. 10a pouch: 7 kV, 3 s reset +
20 s DC), over the conditions of Fig. 9, against N = 2561. Prints the README table and
draws the error against N; the preset's default N is chosen from it as the V-shaped one
was from Fig. 2b (0.3 % from the converged speed at the baseline, 1 N, 7 ml)."""
import numpy as np
from _common import QUICK, plt, save, style

from dfa_model import Protocol, preset, simulate
from dfa_model.physics.kinematics import make

style()
p = preset("peano-fig10")
Ns = [41, 81, 161, 321] if QUICK else [41, 81, 161, 321, 401, 641, 1281]
N_REF = 641 if QUICK else 2561
# (label, volume m^3, load N): the loads and volumes of Fig. 9, 1 N / 7 ml the baseline
CASES = ([("0.5 N", 7e-6, 0.5), ("1 N, 7 ml", 7e-6, 1.0), ("2 N", 7e-6, 2.0)] if QUICK else
         [("0.5 N", 7e-6, 0.5), ("0.75 N", 7e-6, 0.75), ("1 N, 7 ml", 7e-6, 1.0), ("1.5 N", 7e-6, 1.5),
          ("2 N", 7e-6, 2.0), ("3 N", 7e-6, 3.0), ("6 ml", 6e-6, 1.0), ("9 ml", 9e-6, 1.0)])
proto = Protocol.reset_then_hold(7000, hold=20)


def run(q, F):
    return simulate(q, proto, load=F)


rows = []
for label, vol, F in CASES:
    q = p.replace(volume=vol)
    ref = run(q.replace(N=N_REF), F)
    t_hold = proto.stage_span("hold")[0]
    gap = (q.l_e - float(np.interp(t_hold, ref.t, ref.lz))) * 1e3      # front to electrode end, mm
    speeds = [run(q.replace(N=N), F).unzipping_speed for N in Ns]
    rows.append((label, gap, ref.unzipping_speed, speeds))

print(f"Peano-HASEL (Fig. 10a, 7 kV, reset 3 s + 20 s DC): unzipping speed error vs N = {N_REF}")
print("| condition | front to l_e end | speed (um/s, N = %d) | " % N_REF + " | ".join(f"N = {N}" for N in Ns) + " |")
print("|---|---|---|" + "---|" * len(Ns))
for label, gap, ref, speeds in rows:
    print(f"| {label} | {gap:.3f} mm | {ref * 1e6:.3f} | "
          + " | ".join(f"{(s / ref - 1) * 100:+.2f} %" for s in speeds) + " |")

fig, ax = plt.subplots(figsize=(6.4, 4.2))
for i, (label, gap, ref, speeds) in enumerate(rows):
    err = np.abs(np.array(speeds) / ref - 1) * 100
    base = label.startswith("1 N")
    ax.loglog(Ns, np.maximum(err, 3e-3), "o-", color=f"C{i}", lw=2.2 if base else 1, ms=4,
              label=f"{label} (front {gap:.2f} mm from the end, {ref * 1e6:.1f} µm/s)")
ax.axhline(0.3, color="k", ls=":", lw=1)
ax.text(Ns[0], 0.33, "0.3 % (the V-shaped default's criterion)", fontsize=7.5, va="bottom")
if not QUICK:
    ax.axvline(p.N, color="0.4", ls="--", lw=1)
    ax.text(p.N * 1.05, 4e-3, f"default N = {p.N}", va="bottom", fontsize=7.5, color="0.3")
ax.set_ylim(3e-3, 30)
ax.set_xlabel("N (discretization points)")
ax.set_ylabel(f"|unzipping speed error| vs N = {N_REF} (%)")
ax.set_title("Peano-HASEL (Fig. 10a pouch), 7 kV, 3 s reset + 20 s DC: convergence in N")
ax.legend(fontsize=6.8, loc="lower left")
save(fig, "peano_convergence.png")
