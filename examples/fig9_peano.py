"""Fig. 9, Peano-HASEL (Fig. 10a pouch, 7 kV, 3 s charge reset + 20 s DC, the routine of
Sec. 4.2): unzipping speed against (a) the load at 7 ml and (b) the liquid volume at 1 N,
over the paper's rho_l band (2, 2.5, 3e12 ohm m; 2.5e12 bold). (c), not in the paper,
explains (a): the static force map with each load's equilibrium.

(a) is not monotonic in the load, unlike the V-shape's Fig. 4b: below about 1.5 N the
equilibrium sits on the flank where the force falls to zero as the front reaches the
electrode end (1 N: front 0.16 mm from the end of the 17 mm electrode; 0.5 N: 0.04 mm).
There the force is stiff in the stroke (|dF/dx| 5-26 kN/m against 2 kN/m at 1.5-2 N), so
the charge's slow loss of force moves the stroke little. A finer grid (N = 1281, crosses)
gives the same curve: it is the model's physics, not its resolution.
"""
import numpy as np
from _common import QUICK, RHO_BAND, plt, rho_band, save, style

from dfa_model import preset
from dfa_model.physics.kinematics import make
from dfa_model.physics.statics import equilibrium_stroke, static_force
from dfa_model.sweep import grid, run_case

style()
p = preset("peano-fig10")
V = 7000.0
settings = dict(voltage=V, force=1.0, reset=3, duration=20)
if QUICK:
    forces, volumes, check_forces = [0.5, 1.0, 2.0], [6e-6, 7e-6, 8e-6], [1.0]
else:
    # the steep flank (0.2-1.5 N) finely, then coarser
    forces = list(np.round(np.r_[np.arange(0.2, 1.5, 0.05), np.arange(1.5, 3.01, 0.25)], 3))
    volumes = list(np.round(np.arange(5e-6, 9.01e-6, 0.25e-6), 10))
    check_forces = [0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0]
N_CHECK = 1281


def speeds(rows, key, values):
    out = {}
    for rho in RHO_BAND:
        got = {r[key]: r for r in rows if r["rho_l"] == rho}
        for v in values:
            if got[v]["status"] != "ok":
                print("failed:", got[v]["label"], got[v]["error"])
        out[rho] = np.array([got[v]["unzipping_speed"] * 1e6 if got[v]["status"] == "ok" else np.nan
                             for v in values])
    return out


# the runs take milliseconds: in this process, through the sweep's own case runner
r_force = [run_case(c) for c in grid(p, settings, rho_l=list(RHO_BAND), force=forces)]
r_vol = [run_case(c) for c in grid(p, settings, rho_l=list(RHO_BAND), volume=volumes)]
r_check = [run_case(c) for c in grid(p.replace(N=N_CHECK), settings, rho_l=[2.5e12], force=check_forces)]
uz_force, uz_vol = speeds(r_force, "force", forces), speeds(r_vol, "volume", volumes)

fig, ax = plt.subplots(1, 3, figsize=(15, 4.8))
a = ax[0]
rho_band(a, forces, uz_force, "C3", 2.5e12)
a.plot(check_forces, [r["unzipping_speed"] * 1e6 for r in r_check], "kx", ms=7, mew=1.5,
       label=rf"N = {N_CHECK} (resolution check), $\rho_l$ = 2.5e12")
a.set_xlabel("load F (N)")
a.set_ylabel("unzipping speed (µm/s)")
a.set_title(f"(a) 7 ml, 7 kV, reset 3 s + 20 s DC (N = {p.N})")
a.set_xlim(0, 3.1)
a.axvspan(0, 1.0, color="0.85", alpha=0.5, lw=0, zorder=0)
a.text(0.5, 0.6, "F ≤ 1 N: the front sits\nwithin 0.16 mm of the\nelectrode end, on the\nsteep flank of (c)",
       transform=a.get_xaxis_transform(), ha="center", va="center", fontsize=7.5)
a.legend(loc="lower right", fontsize=7)

a = ax[1]
vol_ml = np.array(volumes) * 1e6
rho_band(a, vol_ml, uz_vol, "C3", 2.5e12)
a.set_xlabel(r"liquid volume $\Omega_f$ (ml)")
a.set_ylabel("unzipping speed (µm/s)")
a.set_title("(b) 1 N, 7 kV, reset 3 s + 20 s DC")
a.legend(loc="upper left", fontsize=7)
gap6 = (p.l_e - float(make(p.replace(volume=6e-6)).lz(equilibrium_stroke(p.replace(volume=6e-6), V, 1.0, warn=False))))
a.text(0.2, 0.5, f"≤ 6 ml: the front sits within\n{gap6 * 1e3:.2f} mm of the electrode end,\nas at low loads in (a)",
       transform=a.transAxes, ha="center", fontsize=7.5)
# the volume sets the pouch's initial half-angle theta_0 (Appendix A), as theta_0 does for the V-shape
th0 = np.degrees([make(p.replace(volume=v)).angle(0.0) for v in volumes])
top = a.secondary_xaxis("top", functions=(lambda v: np.interp(v, vol_ml, th0), lambda t: np.interp(t, th0, vol_ml)))
top.set_xlabel("initial half-angle θ0 (°)")

a = ax[2]
k = make(p)
x = np.linspace(0, k.x_e, 400)
a.plot(x * 1e3, static_force(p, x, V), color="k", lw=1.5)
h = 1e-7
for F in [0.5, 1.0, 1.5, 2.0, 3.0]:
    xs = equilibrium_stroke(p, V, F, warn=False)
    gap = (p.l_e - float(k.lz(xs))) * 1e3
    stiff = -float(static_force(p, min(xs + h, k.x_e), V) - static_force(p, xs - h, V)) / (min(xs + h, k.x_e) - xs + h)
    a.plot(xs * 1e3, F, "o", color="C3", ms=5)
    a.annotate(f"{F:g} N: {gap:.2f} mm, {stiff / 1e3:.1f} kN/m", (xs * 1e3, F), xytext=(-7, -4),
               textcoords="offset points", ha="right", va="top", fontsize=7)
a.axvline(k.x_e * 1e3, color="0.5", ls=":", lw=1)
a.text(k.x_e * 1e3 - 0.01, 5.9, "x_e: front at the electrode end", rotation=90, ha="right", va="top",
       fontsize=7, color="0.3")
a.text(0.92, 0.97, "load: front to electrode end, |dF/dx|\n\n"
       "Near x_e the force falls to 0: a small loss of\nforce (the interface charge relaxing) moves\n"
       "a stiff equilibrium little. Speed ~ force loss\nrate / |dF/dx|.", transform=a.transAxes, ha="right",
       va="top", fontsize=7, multialignment="left", bbox=dict(fc="white", ec="0.7", alpha=0.9))
a.set_ylim(0, 6)
a.set_xlim(0, k.x_e * 1e3 * 1.02)
a.set_xlabel("stroke x (mm)")
a.set_ylabel("static zipping force at 7 kV, no interface charge (N)")
a.set_title("(c) not in the paper: equilibria of (a) on the force map")
a.text(0.03, 0.03, f"blocking force {float(static_force(p, 0.0, V)):.0f} N (off scale)", transform=a.transAxes,
       fontsize=7)
save(fig, "fig9_peano.png")
