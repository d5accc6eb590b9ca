"""Fig. 4 (Table 1 V-shape, 6 kV, 5 N, rho_l = 2e12 ohm m as in Sec. 3; voltage applied at
t = 0 to an uncharged actuator at rest, no charge reset): (a) stroke under four waveforms
(DC, bipolar 1 Hz and 30 Hz, unipolar 0.5 Hz 50 %), each in its own panel so that the
inversion ripple can be read; stroke after a voltage step for (b) loads, (c) tau_f/tau_l,
(d) initial angles; (e) unzipping speed against theta_0 over the rho_l band."""
import numpy as np
from _common import QUICK, RHO_BAND, plt, rho_band, save, style

from dfa_model import Bipolar, DC, Protocol, Unipolar, preset, simulate
from dfa_model.physics.statics import equilibrium_stroke
from dfa_model.sweep import grid, run_case

style()
p = preset("vshape-table1")                 # rho_l = 2e12 ohm m, the value of Sec. 3
V, F, T = 6000.0, 5.0, 20.0
t = np.linspace(0, T, 1001 if QUICK else 4001)
step = Protocol.dc(V, T)
fig = plt.figure(figsize=(17, 8.6))
outer = fig.add_gridspec(2, 4, wspace=0.3, hspace=0.36, left=0.045, right=0.99, top=0.9, bottom=0.065)


def um(v):
    return f"{v * 1e6:.3g} µm"


# ---------------------------------------------------------------- (a) waveforms
# the bipolar runs at rtol 1e-6: the 30 Hz ripple (0.15 um) is below the default's
# resolution (about rtol x stroke = 0.1 um, README 'Reliability')
sub = [fig.add_subplot(outer[i // 2, i % 2]) for i in range(4)]
zoom = (10.0, 10.1)                          # the 30 Hz inset: three periods
t_fine = np.sort(np.concatenate([t, np.linspace(*zoom, 2001)]))
runs = {}
for key, wf, q in (("dc", DC(V), p), ("bip1", Bipolar(V, 1.0), p.replace(rtol=1e-6)),
                   ("uni", Unipolar(V, 0.5, 0.5), p), ("bip30", Bipolar(V, 30.0), p.replace(rtol=1e-6))):
    runs[key] = simulate(q, Protocol.single(wf, T), load=F, t_eval=t_fine if key == "bip30" else t)
a = sub[0]
r = runs["dc"]
a.plot(r.t, r.x * 1e3, color="C0")
a.set_title(f"(a) DC 6 kV: unzips at {r.unzipping_speed * 1e6:.1f} µm/s")
a = sub[2]
r = runs["uni"]
a.plot(r.t, r.x * 1e3, color="C3", lw=0.8)
peaks = [r.x[(r.t >= k) & (r.t < k + 1)].max() for k in range(0, int(T), 2)]
a.set_title(f"(a) unipolar 0.5 Hz, 50 %: peak {peaks[0] * 1e3:.2f} → {peaks[-1] * 1e3:.2f} mm")
for a in (sub[0], sub[2]):
    a.set_ylim(0, 0.95)
ylim_bip = (0.845, 0.878)
for a, key, f in ((sub[1], "bip1", 1.0), (sub[3], "bip30", 30.0)):
    r = runs[key]
    a.plot(r.t, r.x * 1e3, color="C1" if f == 1 else "C2", lw=0.7)
    a.set_ylim(*ylim_bip)
    a.set_title(f"(a) bipolar {f:g} Hz: ripple {um(r.ripple(1 / f))} peak to peak")
    a.text(0.02, 0.03, "zips from 0 at t = 0 (below the axis)", transform=a.transAxes, fontsize=7, color="0.3")
ins = sub[3].inset_axes([0.5, 0.2, 0.47, 0.36])
r = runs["bip30"]
w = (r.t >= zoom[0]) & (r.t <= zoom[1])
ins.plot((r.t[w] - zoom[0]) * 1e3, (r.x[w] - r.x[w].mean()) * 1e6, color="C2", lw=0.9)
ins.set_xlabel(f"t − {zoom[0]:g} s (ms)", fontsize=7, labelpad=1)
ins.set_ylabel("x − mean (µm)", fontsize=7, labelpad=1)
ins.tick_params(labelsize=6.5)
ins.set_title("zoom: 3 periods; the stroke dips\nat every inversion (60 per s)", fontsize=7, pad=2)
for a in sub:
    a.set_xlabel("time (s)")
    a.set_ylabel("stroke x (mm)")
sub[1].text(0.5, 0.3, "same stroke scale in both bipolar panels:\nthe ripple shrinks as the inversion\n"
            "frequency rises (1 Hz → 30 Hz)", transform=sub[1].transAxes, fontsize=7.5, ha="center", va="center")

# ---------------------------------------------------------------- (b) loads
a = fig.add_subplot(outer[0, 2])
for i, load in enumerate((3, 5, 7, 9)):
    r = simulate(p, step, load=load, t_eval=t)
    a.plot(r.t, r.x * 1e3, color=f"C{i}", label=f"{load} N: {r.unzipping_speed * 1e6:.1f} µm/s")
    t0, _ = r.hold_window()
    at_zero = r.t[(r.t > t0) & (r.x <= 1e-9)]
    if at_zero.size:             # the stroke stops at 0 before the window ends: the speed is biased low
        tz = at_zero[0]
        a.lines[-1].set_label(a.lines[-1].get_label() + " *")
        a.plot(tz, 0, "x", color=f"C{i}", ms=8, mew=2)
        a.text(0.02, 0.97, f"* {load} N reaches x = 0 at {tz:.1f} s (×): its speed over the\n"
               f"20 s window is biased low; {r.peak_stroke / (tz - t0) * 1e6:.1f} µm/s until then",
               transform=a.transAxes, va="top", fontsize=7, color=f"C{i}")
a.set_title("(b) 6 kV step, loads 3-9 N (speed: peak to 20 s)")
a.set_ylim(0, 2.0)
a.legend(loc="upper right", bbox_to_anchor=(1, 0.86))

# ---------------------------------------------------------------- (c) materials
a = fig.add_subplot(outer[0, 3])
base = p.rho_l * p.eps_r_l / p.eps_r_f           # rho_f giving tau_f = tau_l
for i, ratio in enumerate((1, 3, 10, 100, 1000)):
    r = simulate(p.replace(rho_f=ratio * base), step, load=F, t_eval=t)
    a.plot(r.t, r.x * 1e3, color=f"C{i}", label=rf"$\tau_f/\tau_l$ = {ratio}")
a.set_title(r"(c) 6 kV step, 5 N, $\rho_l$ = 2×10¹² Ω m, $\rho_f$ varied")
a.legend(loc="lower right")
a.set_ylim(0, 0.95)

# ---------------------------------------------------------------- (d) initial angle
a = fig.add_subplot(outer[1, 2])
for i, th in enumerate((15, 20, 25, 30, 35, 40)):
    r = simulate(p.with_theta0(th), step, load=F, t_eval=t)
    a.plot(r.t, r.x * 1e3, color=f"C{i}", label=f"θ0 = {th}°")
a.set_title("(d) 6 kV step, 5 N, initial angles θ0")
a.legend(loc="upper right", ncol=3, fontsize=7)
a.set_ylim(0, 1.14)
for a in fig.axes[-3:]:
    a.set_xlabel("time (s)")
    a.set_ylabel("stroke x (mm)")

# ---------------------------------------------------------------- (e) speed against theta_0
a = fig.add_subplot(outer[1, 3])
angles = [10, 20, 30, 40] if QUICK else list(np.arange(10, 43.5, 2.5))
rows = [run_case(c) for c in grid(p, dict(voltage=V, force=F, duration=T), rho_l=list(RHO_BAND), theta0=angles)]
uz = {rho: np.array([r["unzipping_speed"] * 1e6 if r["status"] == "ok" else np.nan
                     for r in rows if r["rho_l"] == rho]) for rho in RHO_BAND}
rho_band(a, angles, uz, "C3", 2e12)
# past the peak the stroke reaches 0 inside the window: the speed is the static stroke / 20 s
falling = [th for th in angles if th >= angles[int(np.nanargmax(uz[2e12]))]]
bound = [equilibrium_stroke(p.with_theta0(th), V, F, warn=False) / T * 1e6 for th in falling]
a.plot(falling, bound, color="0.2", ls=(0, (4, 2)), lw=1.2, label="static stroke / 20 s")
if len(falling) > 2:
    a.annotate("falling branch: the stroke\nreaches 0 within 20 s, so\nspeed = static stroke / 20 s\n"
               "(Sec. 3.5, cf. Fig. 3b)", (falling[2], bound[2]), xytext=(0.99, 0.97),
               textcoords="axes fraction", ha="right", va="top", fontsize=7,
               arrowprops=dict(arrowstyle="->", color="0.3", lw=0.7))
no_zip = [th for th in angles if equilibrium_stroke(p.with_theta0(th), V, F, warn=False) == 0]
if no_zip:
    a.annotate(f"θ0 ≥ {no_zip[0]:g}°: blocking force\n< 5 N, no zipping", (no_zip[0], 0), xytext=(-40, 3),
               textcoords="offset points", ha="right", fontsize=7)
a.set_xlabel("initial angle θ0 (°)")
a.set_ylabel("unzipping speed, peak to 20 s (µm/s)")
a.set_title(r"(e) 6 kV step, 5 N, 20 s window; $\rho_l$ band")
a.legend(loc="upper left", fontsize=7)
a.set_ylim(0, 50)
fig.suptitle("Fig. 4: V-shaped actuator (Table 1, N = %d), 6 kV applied at t = 0 to an uncharged actuator at rest; "
             r"$\rho_l$ = 2×10¹² Ω m (Sec. 3) unless stated" % p.N, fontsize=10.5)
save(fig, "fig4_dynamics.png", tight=False)
