"""Fig. 2: convergence in N (Table 1, 6 kV, 5 N, theta_0 = 25 deg) of (a) the static
force and (c) the unzipping speed after a 6 kV step (20 s, peak to end), for our schemes
and the paper's (midpoint Eq. 9, pseudo-transient Eq. 15, integrated exactly). (b), not
in the paper, shows why (a) is taken over the stroke range: the midpoint force is a
staircase in x, so a single stroke samples one step of it. Prints the README tables."""
import numpy as np
from _common import QUICK, plt, save, style

from dfa_model import Protocol, preset, simulate
from dfa_model.physics.statics import equilibrium_stroke, force_eq10, static_force

style()
p = preset("vshape-table1")
V, F = 6000.0, 5.0
x_star = equilibrium_stroke(p, V, F)                  # the static stroke at 6 kV, 5 N (0.8711 mm)
N_static = [11, 41, 161] if QUICK else [11, 21, 41, 81, 161, 321, 641, 1500]
N_ours = [11, 41] if QUICK else [11, 21, 41, 81, 161, 321, 641, 1500]
N_paper = [101, 201] if QUICK else [101, 201, 401, 801, 1500, 3001]
x = np.linspace(0.05e-3, 3e-3, 300 if QUICK else 3000)   # the working range (front up to ~31 of 40 mm)

# (a) static force against the exact one (continuum integral of Eq. 8: our scheme, any N)
exact = static_force(p, x, V)
f_star = float(static_force(p, x_star, V))
err = {N: static_force(p.replace(N=N, scheme="paper"), x, V) / exact - 1 for N in N_static}
err_star = {N: float(static_force(p.replace(N=N, scheme="paper"), x_star, V)) / f_star - 1 for N in N_static}
err10 = force_eq10(p, x, V) / exact - 1
print(f"static force at the equilibrium x = {x_star * 1e3:.4f} mm, 6 kV: exact {f_star:.4f} N, "
      f"Eq. (10) {float(force_eq10(p, x_star, V)):.4f} N")
print("| N | paper midpoint Eq. (9) at x | mean / max |error| over x = 0.05-3 mm |")
print("|---|---|---|")
for N in N_static:
    print(f"| {N} | {f_star * (1 + err_star[N]):.4f} ({err_star[N] * 100:+.1f} %) | "
          f"{np.mean(np.abs(err[N])) * 100:.1f} / {np.max(np.abs(err[N])) * 100:.1f} % |")

# (c) unzipping speed after a 6 kV step, 20 s, from the stroke peak (Sec. 3.1)
proto = Protocol.dc(V, 20)
speed = {s: [simulate(p.replace(N=N, scheme=s), proto, load=F).unzipping_speed * 1e6 for N in N_ours]
         for s in ("continuum", "continuum-p0")}
paper_runs = [simulate(p.replace(N=N, scheme="paper"), proto, load=F) for N in N_paper]
speed["paper"] = [r.unzipping_speed * 1e6 for r in paper_runs]
print("| N | " + " | ".join(map(str, N_ours)) + " |")
for s in ("continuum", "continuum-p0"):
    print(f"| {s} (um/s) | " + " | ".join(f"{u:.3f}" for u in speed[s]) + " |")
print("| paper scheme N | " + " | ".join(map(str, N_paper)) + " |")
print("| peak stroke (mm) | " + " | ".join(f"{r.peak_stroke * 1e3:.3f}" for r in paper_runs) + " |")
print("| unzipping speed (um/s) | " + " | ".join(f"{u:.2f}" for u in speed["paper"]) + " |")

fig, ax = plt.subplots(1, 3, figsize=(15.5, 4.6), gridspec_kw=dict(width_ratios=[1, 0.9, 1.1]))
a = ax[0]
Ns = np.array(N_static)
a.loglog(Ns, [np.max(np.abs(err[N])) * 100 for N in N_static], "o-", color="C0",
         label="paper, midpoint Eq. (9): max over x")
a.loglog(Ns, [np.mean(np.abs(err[N])) * 100 for N in N_static], "s-", color="C0", mfc="white",
         label="paper, midpoint Eq. (9): mean over x")
a.loglog(Ns, [max(abs(err_star[N]), 1e-3) * 100 for N in N_static], "x", color="k", ms=7,
         label=f"paper, midpoint: at x = {x_star * 1e3:.3f} mm only")
a.axhline(np.mean(np.abs(err10)) * 100, color="C1", ls="--", lw=1.2,
          label=f"Eq. (10), the paper's benchmark: mean {np.mean(np.abs(err10)) * 100:.1f} %")
a.text(0.03, 0.03, "ours (both continuum schemes): exact for any N\n(the element integrals of Eq. (8) in closed form)",
       transform=a.transAxes, fontsize=7.5, color="C2")
a.set_ylim(0.5, 3e5)
a.set_xlabel("N (discretization points)")
a.set_ylabel("|static force error| vs exact Eq. (8), x = 0.05-3 mm (%)")
a.set_title("(a) static force, 6 kV, over the stroke range")
a.legend(loc="upper right", fontsize=7)

a = ax[1]
xw = np.linspace(x_star - 0.06e-3, x_star + 0.06e-3, 1500 if not QUICK else 200)
a.plot(xw * 1e3, static_force(p, xw, V), color="C2", lw=2, label="exact (ours, any N)")
a.plot(xw * 1e3, force_eq10(p, xw, V), color="C1", ls="--", lw=1.2, label="Eq. (10)")
for N, c in ((161, "C0"), (1500 if not QUICK else 41, "C4")):
    a.plot(xw * 1e3, static_force(p.replace(N=N, scheme="paper"), xw, V), color=c, lw=0.9,
           label=f"paper midpoint Eq. (9), N = {N}")
a.axvline(x_star * 1e3, color="k", ls=":", lw=1)
a.text(x_star * 1e3, 0.02, " equilibrium\n 6 kV, 5 N", transform=a.get_xaxis_transform(), fontsize=7)
a.set_xlabel("stroke x (mm)")
a.set_ylabel("static force (N)")
a.set_title("(b) not in the paper: the midpoint force jumps at every element")
a.set_ylim(0, 17)
a.legend(loc="upper center", fontsize=7, ncol=2)

a = ax[2]
a.semilogx(N_ours, speed["continuum"], "o-", color="C2", label="ours: continuum (default)")
a.semilogx(N_ours, speed["continuum-p0"], "s--", color="C2", mfc="white", label="ours: continuum-p0")
a.semilogx(N_paper, speed["paper"], "^-", color="C0", label="paper scheme, Eqs. (9) + (15), exact (Filippov)")
for N, u in zip(N_paper, speed["paper"]):
    if u >= 0.1:
        a.annotate(f"{u:.1f}", (N, u), xytext=(-6, 2), textcoords="offset points", ha="right", fontsize=7.5,
                   color="C0")
a.annotate(f"{speed['continuum'][-1]:.2f}", (N_ours[-1], speed["continuum"][-1]), xytext=(-4, 6),
           textcoords="offset points", ha="center", fontsize=7.5, color="C2")
stuck = [N for N, u in zip(N_paper, speed["paper"]) if u < 0.1]
if stuck:
    a.text(12, 4, f"paper scheme: the stroke sticks at a force\njump (Filippov), < 0.1 µm/s for N = {stuck[0]}-{stuck[-1]}",
           fontsize=7.5, color="C0")
a.set_ylim(-1, 27)
a.set_xlabel("N (discretization points)")
a.set_ylabel("unzipping speed, peak to 20 s (µm/s)")
a.set_title("(c) 6 kV step, 5 N, θ0 = 25°, 20 s window")
a.legend(loc="center left", fontsize=7)
save(fig, "fig2_convergence.png")
