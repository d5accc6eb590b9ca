"""Fig. 3: static force maps of the V-shaped actuator (exact integral, solid; Eq. (10),
dashed): (a) force-stroke at 5-10 kV, theta_0 = 25 deg; (b) at 6 kV for theta_0 = 20-45
deg; (c) force against the zipping angle, the same for every theta_0."""
import numpy as np
from _common import plt, save

from dfa_model import preset
from dfa_model.kinematics import VShaped
from dfa_model.statics import force_eq10, static_force

p = preset("vshape-table1")
fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
volts = [5e3, 6e3, 7e3, 8e3, 9e3, 10e3]
x = np.linspace(0, 4e-3, 120)
for i, V in enumerate(volts):
    ax[0].plot(x * 1e3, static_force(p, x, V), color=f"C{i}", label=f"{V / 1e3:g} kV")
    ax[0].plot(x * 1e3, force_eq10(p, x, V), color=f"C{i}", ls="--", lw=0.8)
ax[0].set_xlabel("stroke x (mm)"), ax[0].set_ylabel("force (N)"), ax[0].set_title("(a) theta_0 = 25 deg")
for i, th in enumerate([20, 25, 30, 35, 40, 45]):
    q = p.with_theta0(th)
    xx = np.linspace(0, VShaped(q).x_e, 120)
    ax[1].plot(xx * 1e3, static_force(q, xx, 6000), color=f"C{i}", label=f"{th} deg")
ax[1].set_xlabel("stroke x (mm)"), ax[1].set_title("(b) 6 kV"), ax[1].set_xlim(0, 5)
for i, V in enumerate(volts):
    for j, th in enumerate([20, 30, 40]):
        q = p.with_theta0(th)
        k = VShaped(q)
        xx = np.linspace(0, k.x_e * 0.98, 80)
        ang = np.degrees(k.angle(xx))
        ax[2].plot(ang, static_force(q, xx, V), color=f"C{i}", ls=["-", "--", ":"][j], lw=1,
                   label=f"{V / 1e3:g} kV" if j == 0 else None)
ax[2].set_xlabel("zipping angle theta (deg)"), ax[2].set_title("(c) lines: theta_0 = 20 / 30 / 40 deg")
ax[2].set_xlim(20, 120)
for a in ax:
    a.set_ylim(0, None), a.grid(alpha=0.3), a.legend(fontsize=7)
save(fig, "fig3_statics.png")
