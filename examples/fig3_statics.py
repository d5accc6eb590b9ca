"""Fig. 3: static force maps of the V-shaped actuator (Table 1), no interface charge:
(a) force-stroke at 5-10 kV, theta_0 = 25 deg; (b) at 6 kV for theta_0 = 20-45 deg;
(c) force against the zipping angle at 5-10 kV, the same curve for every theta_0.
Solid: the exact force (the continuum integral of Eq. 8, our scheme); dashed: Eq. (10),
which the paper plots. Eq. (10) keeps only the zipped region's capacitance: ~2.5 % high
over the working range, and it does not vanish when the front reaches the electrode end
(x_e), where the exact force does."""
import numpy as np
from _common import QUICK, plt, save, style
from matplotlib.lines import Line2D

from dfa_model import preset
from dfa_model.physics.kinematics import VShaped
from dfa_model.physics.statics import force_eq10, static_force

style()
p = preset("vshape-table1")
n = 40 if QUICK else 160
volts = [5e3, 7e3, 10e3] if QUICK else [5e3, 6e3, 7e3, 8e3, 9e3, 10e3]
angles = [20, 30, 45] if QUICK else [20, 25, 30, 35, 40, 45]
style_legend = [Line2D([], [], color="k", lw=1.3, label="exact, Eq. (8) (ours)"),
                Line2D([], [], color="k", lw=1, ls="--", label="Eq. (10) (the paper's Fig. 3)")]

fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
a = ax[0]
x = np.linspace(0, 4e-3, n)
for i, V in enumerate(volts):
    a.plot(x * 1e3, static_force(p, x, V), color=f"C{i}", lw=1.3, label=f"{V / 1e3:g} kV")
    a.plot(x * 1e3, force_eq10(p, x, V), color=f"C{i}", ls="--", lw=1)
a.set_xlabel("stroke x (mm)")
a.set_ylabel("zipping force (N)")
a.set_title("(a) θ0 = 25°, 5-10 kV")
leg = a.legend(loc="upper right", title="voltage")
a.add_artist(leg)
a.legend(handles=style_legend, loc="center right", fontsize=7.5)

a = ax[1]
for i, th in enumerate(angles):
    q = p.with_theta0(th)
    x_e = VShaped(q).x_e
    xx = np.linspace(0, min(x_e, 5e-3), n)
    a.plot(xx * 1e3, static_force(q, xx, 6000), color=f"C{i}", lw=1.3, label=f"{th}°")
    a.plot(xx * 1e3, force_eq10(q, xx, 6000), color=f"C{i}", ls="--", lw=1)
    if x_e < 5e-3:        # the front reaches the electrode end inside the plotted range
        a.plot(x_e * 1e3, 0, "o", color=f"C{i}", ms=5)
        a.annotate(f"x_e = {x_e * 1e3:.1f} mm", (x_e * 1e3, 0), xytext=(8, 30) if x_e < 3e-3 else (-8, 70),
                   textcoords="offset points", ha="left" if x_e < 3e-3 else "right", fontsize=7, color=f"C{i}",
                   arrowprops=dict(arrowstyle="-", color=f"C{i}", lw=0.6))
a.text(0.97, 0.30, "dots: the front reaches the electrode\nend (x_e); the exact force falls to 0,\n"
       "Eq. (10) does not", transform=a.transAxes, ha="right", va="bottom", fontsize=7.5)
a.set_xlim(0, 5)
a.set_ylim(0, None)
a.set_xlabel("stroke x (mm)")
a.set_ylabel("zipping force (N)")
a.set_title("(b) 6 kV, θ0 = 20-45°")
leg = a.legend(loc="upper right", title="θ0")
a.add_artist(leg)
a.legend(handles=style_legend, loc="upper right", fontsize=7.5, bbox_to_anchor=(1.0, 0.56))

a = ax[2]
dashes = {20: "-", 30: "--", 40: ":"}
for i, V in enumerate(volts):
    for th, ls in dashes.items():
        q = p.with_theta0(th)
        k = VShaped(q)
        xx = np.linspace(0, k.x_e * 0.999, n)
        ang = np.degrees(k.angle(xx))
        keep = ang <= 92
        a.plot(ang[keep], static_force(q, xx[keep], V), color=f"C{i}", ls=ls, lw=1.1,
               label=f"{V / 1e3:g} kV" if th == 20 else None)
a.annotate("θ0 = 20°: front at the electrode\nend at θ = 79°, force falls to 0", (79, 0.3), xytext=(62, 12),
           fontsize=7, ha="center", arrowprops=dict(arrowstyle="-", color="0.4", lw=0.6))
a.set_xlim(18, 90)
a.set_ylim(0, None)
a.set_xlabel("zipping angle θ (°)")
a.set_ylabel("zipping force, exact (N)")
a.set_title("(c) 5-10 kV: one curve for every θ0")
leg = a.legend(loc="upper right", title="voltage")
a.add_artist(leg)
a.legend(handles=[Line2D([], [], color="k", ls=ls, lw=1.1, label=f"θ0 = {th}°") for th, ls in dashes.items()],
         loc="center right", fontsize=7.5, title="curves from", bbox_to_anchor=(1.0, 0.45))
save(fig, "fig3_statics.png")
