"""Fig. 2: convergence in N of (a) the static force and (b) the unzipping speed, for
our scheme and the paper's (midpoint Eq. 9). Prints the README table."""
import numpy as np
from _common import plt, save

from dfa_model import Protocol, preset, simulate
from dfa_model.statics import force_eq10, static_force

p = preset("vshape-table1")
x = 0.865e-3                                # the static stroke at 6 kV, 5 N
Ns = [11, 21, 41, 81, 161, 321, 641, 1500]
exact = float(static_force(p.replace(N=1001), x, 6000))
mid = [float(static_force(p.replace(N=N, scheme="paper"), x, 6000)) for N in Ns]
ours = [float(static_force(p.replace(N=N), x, 6000)) for N in Ns]
eq10 = float(force_eq10(p, x, 6000))

Nd = [11, 21, 41, 81, 161, 321, 641]
uz = {s: [simulate(p.replace(N=N, scheme=s), Protocol.dc(6000, 20), load=5).unzipping_speed for N in Nd]
      for s in ("continuum", "continuum-p0")}
print("| N | " + " | ".join(map(str, Nd)) + " |")
for s, v in uz.items():
    print(f"| {s} (um/s) | " + " | ".join(f"{u * 1e6:.3f}" for u in v) + " |")

fig, ax = plt.subplots(1, 2, figsize=(11, 4))
ax[0].semilogx(Ns, mid, "o-", label="paper: midpoint Eq. (9)")
ax[0].semilogx(Ns, ours, "s-", label="ours: exact element integrals")
ax[0].axhline(eq10, color="k", ls="--", lw=1, label="Eq. (10)")
ax[0].axhline(exact, color="C2", ls=":", lw=1, label="continuum Eq. (8)")
ax[0].set_xlabel("N"), ax[0].set_ylabel("static force at x = 0.865 mm (N)"), ax[0].legend(fontsize=8)
ax[0].set_title("(a) static force, 6 kV")
for s, v in uz.items():
    ax[1].semilogx(Nd, np.array(v) * 1e6, "o-", label=s)
ax[1].set_xlabel("N"), ax[1].set_ylabel("unzipping speed (um/s)"), ax[1].legend(fontsize=8)
ax[1].set_title("(b) 6 kV step, 5 N, 25 deg, 20 s")
for a in ax:
    a.grid(alpha=0.3)
save(fig, "fig2_convergence.png")
