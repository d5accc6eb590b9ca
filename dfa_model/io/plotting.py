"""Plots of results (matplotlib, Agg backend: works without a display).

`plot_result` draws voltage, stroke, forces and current on readable axes: a square wave
too fast to draw is a labelled band, each stage is named, and the force and current axes
are scaled to what the run spends its time at, the short peaks (zipping from rest) noted
as off scale instead of flattening everything else."""
from __future__ import annotations

import numpy as np

# a square wave with more periods than this in its stage is drawn as a band
MAX_DRAWN_PERIODS = 40
# the force and current axes cover this share of the run's time (time-weighted quantiles)
BULK = (0.002, 0.998)


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def describe_waveform(wf) -> str:
    from ..waveforms import DC, Bipolar, Sampled, Unipolar
    if isinstance(wf, DC):
        return f"DC {wf.V / 1e3:g} kV"
    if isinstance(wf, Bipolar):
        return f"bipolar ±{abs(wf.V) / 1e3:g} kV, {wf.frequency:g} Hz, duty {wf.duty:g}"
    if isinstance(wf, Unipolar):
        return f"unipolar {wf.V / 1e3:g} kV, {wf.frequency:g} Hz, duty {wf.duty:g}"
    if isinstance(wf, Sampled):
        return f"sampled signal, up to {wf.amplitude / 1e3:.3g} kV"
    return type(wf).__name__


def describe_load(load) -> str:
    from ..waveforms import Sampled
    F = load.F
    text = f"load {F:g} N" if not (callable(F) or isinstance(F, Sampled)) else "time-varying load"
    return text + (f" + spring {load.k_load:g} N/m" if load.k_load else "")


def default_title(res, source=None) -> str:
    p = res.params
    head = f"{source}: " if source else ""
    stages = " + ".join(f"{s.label or 'stage'} {s.duration:g} s" for s in res.protocol.stages)
    rho = f"{p.rho_l:.3g}".replace("e+", "e")
    held = periodic_hold(res)
    last = (f"unzipping speed {res.unzipping_speed * 1e6:.4g} µm/s" if held is None else
            f"ripple {res.ripple() * 1e6:.4g} µm" + (f", drift rate {held[1] * 1e6:.4g} µm/s"
                                                     if np.isfinite(held[1]) else ""))
    return (f"{head}{p.layout}, N = {p.N}, ρ_l = {rho} Ω m; {res.protocol.amplitude / 1e3:g} kV, "
            f"{describe_load(res.load)}; {stages}\n"
            f"static stroke {res.static_stroke * 1e3:.4g} mm, {last}")


def periodic_hold(res):
    """(per-period rows (start, mean, min, max) over the last stage, its drift rate in m/s
    (positive when lost; NaN under two periods after the first)) when the last stage is a
    square wave holding at least one whole period, else None. There the DC hold's
    unzipping chord (Sec. 3.1) is no measure: under unipolar pulses it joins a pulse's
    peak to the stroke at rest in the last pause."""
    T = res.period
    t0, t1 = res.protocol.boundaries[-2], res.protocol.boundaries[-1]
    if T is None or not T <= min(t1, res.trace.t1) - t0:
        return None
    from ..metrics import cycles, drift_rate
    t1 = min(t1, res.trace.t1)
    return cycles(res.trace, T, t0, t1), drift_rate(res.trace, T, t0, t1)


def _settled(res):
    """Samples after the zipping transient from rest (the stroke first within 90 % of
    its peak): its force and current peaks would set the scale of everything else."""
    x = res.x
    if len(x) < 3 or np.max(x) <= 0:
        return np.ones(len(x), bool)
    k = int(np.argmax(x >= 0.9 * np.max(x)))
    keep = np.arange(len(x)) >= k
    return keep if keep.sum() >= 2 else np.ones(len(x), bool)


def _bulk_limits(t, ys, margin=0.08, min_span=0.05):
    """y-limits holding every series in ys over the share BULK of the time of t, at
    least min_span of its magnitude wide (a force that balances its load to 1 mN is a
    flat line, not noise blown up)."""
    w = np.diff(t, append=t[-1]) if len(t) > 1 else np.ones(1)
    lo, hi = np.inf, -np.inf
    for y in ys:
        order = np.argsort(y)
        cw = np.cumsum(w[order])
        if cw[-1] <= 0:
            a, b = y.min(), y.max()
        else:
            a = y[order][min(np.searchsorted(cw, BULK[0] * cw[-1]), len(y) - 1)]
            b = y[order][min(np.searchsorted(cw, BULK[1] * cw[-1]), len(y) - 1)]
        lo, hi = min(lo, a), max(hi, b)
    span = max(hi - lo, min_span * max(abs(hi), abs(lo)), 1e-30)
    mid = (lo + hi) / 2
    return mid - (0.5 + margin) * span, mid + (0.5 + margin) * span


def _eng(v, unit):
    """3 digits with an SI prefix: 4.39e-3 A -> '4.39 mA'."""
    for prefix, f in (("", 1.0), ("m", 1e-3), ("µ", 1e-6), ("n", 1e-9)):
        if abs(v) >= f:
            return f"{v / f:.3g} {prefix}{unit}"
    return f"{v / 1e-12:.3g} p{unit}"


def _note_off_scale(ax, t, y, lim, unit, scale=1.0):
    """Say where a series (y in units of scale * unit) leaves the axis: extreme and time."""
    notes = [f"{_eng(y[k] * scale, unit)} at t = {t[k]:.3g} s"
             for k, bad in ((np.argmax(y), y.max() > lim[1]), (np.argmin(y), y.min() < lim[0])) if bad]
    if notes:
        ax.set_title("off scale: " + ", ".join(notes), loc="right", fontsize=7, color="0.3", pad=2)


def _current_unit(scale):
    for unit, f in (("mA", 1e-3), ("µA", 1e-6), ("nA", 1e-9)):
        if scale >= f:
            return unit, f
    return "pA", 1e-12


def _voltage(ax, res):
    """The protocol's voltage, exactly (its own breakpoints, not the samples); a square wave
    with too many periods to draw is a band between its levels, named."""
    from ..waveforms import Bipolar, Unipolar
    b = res.protocol.boundaries
    for i, stage in enumerate(res.protocol.stages):
        t0, t1 = b[i], b[i + 1]
        wf = stage.waveform
        if isinstance(wf, (Bipolar, Unipolar)) and wf.frequency * stage.duration > MAX_DRAWN_PERIODS:
            lo = -abs(wf.V) if isinstance(wf, Bipolar) else min(0.0, wf.V)
            hi = abs(wf.V) if isinstance(wf, Bipolar) else max(0.0, wf.V)
            ax.fill_between([t0, t1], lo / 1e3, hi / 1e3, color="C3", alpha=0.3, lw=0)
            ax.text((t0 + t1) / 2, (lo + hi) / 2e3, f"{wf.frequency:g} Hz\nsquare wave\n(band: too\nfast to draw)",
                    ha="center", va="center", fontsize=7)
        else:
            pw = wf.piecewise(stage.duration).shifted(t0)
            tt = np.repeat(pw.t, 2)[1:-1]
            vv = np.repeat(pw.v0, 2) + np.repeat(pw.slope, 2) * (tt - np.repeat(pw.t[:-1], 2))
            ax.plot(tt, vv / 1e3, color="C3", lw=0.9)
    ax.set_ylabel("voltage (kV)")
    amp = res.protocol.amplitude / 1e3
    ax.set_ylim(-1.35 * amp if np.min(res.V) < 0 else -0.1 * amp, 1.6 * amp if amp > 0 else 1)


def plot_result(res, path=None, title=None, source=None):
    """Voltage, stroke, forces and current against time. `source` (e.g. 'preset
    vshape-table1') heads the default title, which names the parameters, protocol and
    load."""
    plt = _plt()
    fig, ax = plt.subplots(4, 1, figsize=(8.5, 10), sharex=True,
                           gridspec_kw=dict(height_ratios=[0.8, 1.2, 1, 1]))
    t = res.t
    _voltage(ax[0], res)
    ax[1].plot(t, res.x * 1e3, lw=1.2, color="C0", label="stroke")
    held = periodic_hold(res)
    if held is None:
        t0, t1 = res.hold_window()
        ax[1].plot([t0, t1], [res.trace(t0) * 1e3, res.trace(t1) * 1e3], color="k", ls=":", lw=1,
                   label=f"unzipping speed {res.unzipping_speed * 1e6:.4g} µm/s (Sec. 3.1)")
    else:                   # a square wave held: each period's mean stroke, and the rate it is lost at
        c, rate = held
        ax[1].plot(c[:, 0] + 0.5 * res.period, c[:, 1] * 1e3, color="k", ls=":", lw=1,
                   marker="." if len(c) <= MAX_DRAWN_PERIODS else None, ms=3,
                   label="per-period mean stroke" + (f", drift rate {rate * 1e6:.4g} µm/s" if np.isfinite(rate)
                                                     else ""))
    ax[1].set_ylabel("stroke x (mm)")
    ax[1].set_ylim(0, max(float(np.max(res.x)) * 1e3 * 1.25, 1e-6))
    ax[1].legend(loc="upper right", fontsize=7.5)

    ax[2].plot(t, res.Fe, lw=0.9, color="C2", label="zipping (electrostatic) force")
    ax[2].plot(t, res.F, lw=1.0, color="k", ls="--", label="load")
    ok = _settled(res)
    lim = _bulk_limits(t[ok], [res.Fe[ok], res.F[ok]], min_span=0.2)
    ax[2].set_ylim(*lim)
    _note_off_scale(ax[2], t, res.Fe, lim, "N")
    ax[2].set_ylabel("force (N)")
    ax[2].legend(loc="lower left", fontsize=7.5, bbox_to_anchor=(0.05, 0.0))
    if res.params.m == 0:
        ax[2].set_title("no inertia (m = 0): zipping force = load + b dx/dt", loc="left", fontsize=7, color="0.3",
                        pad=2)

    lim = _bulk_limits(t[ok], [res.I[ok]])
    unit, f = _current_unit(max(abs(lim[0]), abs(lim[1])))
    ax[3].plot(t, res.I / f, lw=0.8, color="C4")
    ax[3].set_ylim(lim[0] / f, lim[1] / f)
    _note_off_scale(ax[3], t, res.I / f, (lim[0] / f, lim[1] / f), "A", f)
    ax[3].set_ylabel(f"device current ({unit})")
    from ..waveforms import DC
    dc = sum(st.duration for st in res.protocol.stages if isinstance(st.waveform, DC))
    if dc > 0.5 * res.protocol.duration and np.ptp(res.lz[ok]) > 2 * res.params.l_e / (res.params.N - 1):
        # under DC the front moves slowly across the material points, each leaving a scallop
        ax[3].set_title(f"scallops: the front passing material points (N = {res.params.N})",
                        loc="left", fontsize=7, color="0.3", pad=2)
    ax[3].set_xlabel("time (s)")

    # each stage shaded (alternately) and named at the top
    b = res.protocol.boundaries
    for i, stage in enumerate(res.protocol.stages):
        if i % 2 == 0 and len(res.protocol.stages) > 1:
            for a in ax:
                a.axvspan(b[i], b[i + 1], color="0.92", zorder=0, lw=0)
        n = len(res.protocol.stages)
        x, ha = ((b[i], "left") if i == 0 and n > 1 else (b[i + 1], "right") if i == n - 1 and n > 1
                 else ((b[i] + b[i + 1]) / 2, "center"))
        ax[0].text(x, 1.02, f"{stage.label or 'stage'} ({stage.duration:g} s): {describe_waveform(stage.waveform)}",
                   transform=ax[0].get_xaxis_transform(), ha=ha, va="bottom", fontsize=7.5)
    for a in ax:
        a.grid(alpha=0.3)
    fig.suptitle(title or default_title(res, source), fontsize=9)
    fig.tight_layout()
    if path is not None:
        from .fileio import write_atomic
        try:
            write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120))
        finally:
            plt.close(fig)
        return None
    return fig
