"""Fig. 4: (a) waveforms; stroke after a voltage step for (b) loads, (c) tau_f/tau_l,
(d) initial angles; (e) unzipping speed against theta_0 for rho_l = 2, 2.5, 3e12."""
import numpy as np
from _common import plt, save

from dfa_model import Bipolar, DC, Protocol, Unipolar, preset, simulate
from dfa_model.sweep import grid, run

p = preset("vshape-table1")
t = np.linspace(0, 20, 4001)
fig, ax = plt.subplots(2, 3, figsize=(15, 8))
a = ax[0, 0]
for wf, lab in ((DC(6000), "DC"), (Bipolar(6000, 1.0), "bipolar 1 Hz"), (Bipolar(6000, 30.0), "bipolar 30 Hz"),
                (Unipolar(6000, 0.5, 0.5), "unipolar 0.5 Hz, 50 %")):
    r = simulate(p, Protocol.single(wf, 20), load=5, t_eval=t)
    a.plot(r.t, r.x * 1e3, lw=0.8, label=lab)
a.set_title("(a) waveforms, 6 kV, 5 N"), a.set_ylabel("stroke (mm)")
a = ax[0, 1]
for F in (3, 5, 7, 9):
    r = simulate(p, Protocol.dc(6000, 20), load=F, t_eval=t)
    a.plot(r.t, r.x * 1e3, label=f"{F} N, {r.unzipping_speed * 1e6:.1f} um/s")
a.set_title("(b) loads, 6 kV DC")
a = ax[0, 2]
base = p.rho_l * p.eps_r_l / p.eps_r_f
for ratio in (1, 3, 10, 100, 1000):
    r = simulate(p.replace(rho_f=ratio * base), Protocol.dc(6000, 20), load=5, t_eval=t)
    a.plot(r.t, r.x * 1e3, label=f"tau_f/tau_l = {ratio}")
a.set_title("(c) materials, rho_l = 2e12 ohm m")
a = ax[1, 0]
for th in (15, 20, 25, 30, 35, 40):
    r = simulate(p.with_theta0(th), Protocol.dc(6000, 20), load=5, t_eval=t)
    a.plot(r.t, r.x * 1e3, label=f"{th} deg")
a.set_title("(d) initial angle, 6 kV, 5 N"), a.set_ylabel("stroke (mm)")
for a in ax.flat[:4]:
    a.set_xlabel("time (s)"), a.legend(fontsize=7), a.grid(alpha=0.3)
a = ax[1, 1]
angles = [10, 15, 20, 25, 30, 35, 40, 42]
rows = run(grid(p, dict(voltage=6000, force=5, duration=20), rho_l=[2e12, 2.5e12, 3e12], theta0=angles))
for i, rho in enumerate([2e12, 2.5e12, 3e12]):
    uz = [r["unzipping_speed"] * 1e6 for r in rows if r["rho_l"] == rho and r["status"] == "ok"]
    a.plot(angles, uz, "o-", color="C3", alpha=[0.4, 1, 0.4][i], label=f"rho_l = {rho:.2g}")
a.set_title("(e) DC, 20 s"), a.set_xlabel("theta_0 (deg)"), a.set_ylabel("unzipping speed (um/s)")
a.legend(fontsize=7), a.grid(alpha=0.3)
ax[1, 2].axis("off")
save(fig, "fig4_dynamics.png")
