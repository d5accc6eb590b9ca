"""Peano-HASEL study like Fig. 9: unzipping speed (3 s reset + 20 s DC at 7 kV)
against (a) the load (7 ml) and (b) the liquid volume (1 N), rho_l = 2, 2.5, 3e12."""
from _common import plt, save

from dfa_model import preset
from dfa_model.sweep import grid, run

p = preset("peano-fig10")
rhos = [2e12, 2.5e12, 3e12]
forces = [0.25, 0.5, 1.0, 1.5, 2.0, 3.0]
volumes = [5e-6, 6e-6, 7e-6, 8e-6, 9e-6]
settings = dict(voltage=7000, force=1.0, reset=3, duration=20)
r_force = run(grid(p, settings, rho_l=rhos, force=forces))
r_vol = run(grid(p, settings, rho_l=rhos, volume=volumes))
fig, ax = plt.subplots(1, 2, figsize=(11, 4))
for i, rho in enumerate(rhos):
    kw = dict(color="C0", alpha=[0.4, 1, 0.4][i], label=f"rho_l = {rho:.2g}")
    ax[0].plot(forces, [r["unzipping_speed"] * 1e6 for r in r_force if r["rho_l"] == rho], "o-", **kw)
    ax[1].plot([v * 1e6 for v in volumes], [r["unzipping_speed"] * 1e6 for r in r_vol if r["rho_l"] == rho], "o-", **kw)
for r in r_force + r_vol:
    if r["status"] != "ok":
        print("failed:", r["label"], r["error"])
ax[0].set_xlabel("load (N)"), ax[0].set_title("(a) 7 ml, 7 kV")
ax[1].set_xlabel("liquid volume (ml)"), ax[1].set_title("(b) 1 N, 7 kV")
for a in ax:
    a.set_ylabel("unzipping speed (um/s)"), a.grid(alpha=0.3), a.legend(fontsize=8)
save(fig, "fig9_peano.png")
