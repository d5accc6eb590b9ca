"""Where the fitted model and the recordings disagree, and how: statistics on residuals.

Each recording is cut into windows: the charge reset, the first second of the hold (the
fast drop after the reset), then the rest of the hold in thirds. In each window, with
sigma the sensor noise estimated from the data (fit.noise_level) and r the residual
(measured - model, offset removed):

- excess: (sum r^2 / sigma^2 - n) / sqrt(2 n), the chi-square excess in standard
  deviations (white noise: about N(0, 1));
- runs: the Wald-Wolfowitz runs test on the signs of r, in standard deviations (white
  noise: N(0, 1); a systematic mismatch gives long runs, a large negative value);
- effect: the RMS of the repetition-averaged residual against the repetitions' scatter
  about it (/ sqrt(R)): about 1 when the misfit is noise or repetition-to-repetition
  difference, large when every repetition misses the same way (_effect).

A window is systematic when excess > Z_SYSTEMATIC and runs < -Z_SYSTEMATIC (both beyond
what noise gives with probability ~1e-7) and its effect exceeds EFFECT_MIN. Its signature
names the pattern: dips at the reset's inversions (the residual averaged over the switch
instants), a fast drop after the reset, an unzipping speed that changes over the hold
(a residual trend), a zipping transient of the wrong shape (the first 50 ms), an offset.
A condition-level summary regresses the mean residual of each window type on voltage and
load (a static-stroke offset growing with voltage or load).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Z_SYSTEMATIC = 5.0
EFFECT_MIN = 2.0


@dataclass
class Window:
    recording: str
    name: str
    t_start: float
    t_end: float
    n: int
    excess: float
    runs: float
    effect: float
    mean: float          # mean residual (m)
    rms: float           # RMS residual (m)
    systematic: bool
    signature: str

    def to_dict(self) -> dict:
        return {"recording": self.recording, "t_start": self.t_start, "t_end": self.t_end,
                "signature": self.signature, "window": self.name, "rms_error": self.rms, "mean_error": self.mean,
                "excess_sd": self.excess, "runs_sd": self.runs, "effect": self.effect}


def runs_z(r: np.ndarray) -> float:
    """Wald-Wolfowitz runs test on the signs of r (z score; negative: too few runs)."""
    s = r[r != 0] > 0
    n1, n2 = int(s.sum()), int((~s).sum())
    n = n1 + n2
    if n1 == 0 or n2 == 0:
        return -math.inf if n > 10 else 0.0
    runs = 1 + int(np.count_nonzero(s[1:] != s[:-1]))
    mu = 2.0 * n1 * n2 / n + 1.0
    var = (mu - 1.0) * (mu - 2.0) / (n - 1.0)
    return (runs - mu) / math.sqrt(var) if var > 0 else 0.0


def windows_of(rec) -> list:
    """(name, t0, t1) of a recording's windows (module docstring)."""
    out = []
    te = rec.reset_end
    if te > 0.05:
        out.append(("reset", 0.0, te))
    early = min(te + 1.0, rec.duration)
    out.append(("after reset", te, early))
    if rec.duration - early > 0.3:
        edges = np.linspace(early, rec.duration, 4)
        for i, nm in enumerate(("hold, first third", "hold, second third", "hold, last third")):
            out.append((nm, float(edges[i]), float(edges[i + 1])))
    return out


def _signature(name, rec, t, r, sigma) -> str:
    if name == "reset":
        # the residual averaged over the reset's inversion instants (10 ms after each)
        sw = _switch_times(rec)
        if len(sw) >= 4:
            lags = np.arange(0, max(int(round(0.01 / rec.dt)), 1) + 1)
            idx = np.searchsorted(t, sw)
            idx = idx[idx + lags[-1] < len(t)]
            if idx.size >= 4:
                ep = np.array([np.mean(r[idx + L]) for L in lags])
                se = sigma / math.sqrt(idx.size)
                if np.min(ep) - np.mean(r) < -5 * se:
                    return "dips at every inversion of the reset (the measured stroke drops more at each switch)"
                if np.max(ep) - np.mean(r) > 5 * se:
                    return "dips at every inversion of the reset (the model's stroke drops more at each switch)"
        head = t < t[0] + 0.05
        if head.any() and np.sqrt(np.mean(r[head] ** 2)) > 3 * np.sqrt(np.mean(r ** 2)):
            return "a zipping transient of the wrong shape (first 50 ms)"
        return f"static stroke offset: the measurement is {abs(np.mean(r)) * 1e6:.3g} um " \
               f"{'above' if np.mean(r) > 0 else 'below'} the model during the reset"
    if name == "after reset":
        third = t < t[0] + 0.2
        # (a window of 0.2 s or less has no rest to compare with: under polarity inversion the
        # "after reset" window is the drive's first switches, and numpy warned of an empty mean)
        if third.any() and not third.all() and abs(np.mean(r[third])) > 2 * abs(np.mean(r[~third])):
            return "a fast drop right after the charge reset" + (" that the model misses (measured lower)"
                                                               if np.mean(r[third]) < 0 else " (measured higher)")
    # a trend in the hold: the unzipping speed differs
    A = np.column_stack([np.ones_like(t), t - t.mean()])
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    slope = coef[1]
    fitted = A @ coef
    if np.sum(fitted ** 2) > 0.5 * np.sum(r ** 2) and abs(slope) > 0:
        return (f"unzipping speed off by {slope * 1e6:+.3g} um/s over this window (measured - model: "
                f"{'faster zipping/slower unzipping' if slope > 0 else 'faster unzipping'})")
    return f"offset of {np.mean(r) * 1e6:+.3g} um with structure (curvature) over the window"


def _switch_times(rec):
    t_rst = rec.reset_end
    wf = rec.protocol.stages[0].waveform if rec.protocol.stages[0].label == "reset" else None
    if wf is None:
        return np.array([])
    ts = np.asarray(wf.times)
    return ts[(ts > 0) & (ts < t_rst)]


def _mask(t, t0, t1, name):
    """The window's samples: [t0, t1), the last one closed at the recording's end."""
    return (t >= t0) & (t < t1) if name != "hold, last third" else (t >= t0)


def _effect(fit, reps, t0, t1, name, sigma) -> float:
    """RMS of the repetition-averaged residual over the window against what the
    repetitions' scatter about it leaves in such an average (scatter / sqrt(R)): about 1
    when the residuals are noise or repetition-to-repetition differences, large when all
    repetitions miss the same way. One repetition: its RMS against the noise."""
    rs = [fit.residual(o)[_mask(o.t, t0, t1, name)] for o in reps]
    L = min(len(x) for x in rs)
    A = np.array([x[:L] for x in rs])
    if len(rs) < 2:
        return float(np.sqrt(np.mean(A[0] ** 2))) / sigma
    mean = A.mean(axis=0)
    scatter = float(np.sqrt(np.mean((A - mean) ** 2) * len(rs) / (len(rs) - 1)))
    return float(np.sqrt(np.mean(mean ** 2))) / (max(scatter, sigma * 1e-3) / math.sqrt(len(rs)))


def locate(dataset, fit) -> list:
    """Windows of every recording with their statistics (module docstring), in file order."""
    sigma = fit.sigma
    conds = dataset.conditions()
    out = []
    for rec in dataset.recordings:
        res = fit.residual(rec)
        reps = conds[rec.condition()]
        for name, t0, t1 in windows_of(rec):
            m = _mask(rec.t, t0, t1, name)
            n = int(m.sum())
            if n < 20:
                continue
            r = res[m]
            excess = (float(r @ r) / sigma ** 2 - n) / math.sqrt(2.0 * n)
            rz = runs_z(r)
            effect = _effect(fit, reps, t0, t1, name, sigma)
            systematic = excess > Z_SYSTEMATIC and rz < -Z_SYSTEMATIC and effect > EFFECT_MIN
            sig = _signature(name, rec, rec.t[m], r, sigma) if systematic else "noise-like"
            out.append(Window(rec.name, name, float(t0), float(t1), n, float(excess), float(rz), effect,
                              float(np.mean(r)), float(np.sqrt(np.mean(r * r))), bool(systematic), sig))
    return out


def condition_trends(dataset, windows) -> list:
    """Mean residual of each window type regressed on voltage and load across conditions:
    sentences for the slopes that stand out against their standard errors (|t| > 3)."""
    recs = {r.name: r for r in dataset.recordings}
    out = []
    for name in sorted({w.name for w in windows}):
        ws = [w for w in windows if w.name == name]
        if len(ws) < 4:
            continue
        V = np.array([recs[w.recording].hold_voltage for w in ws])
        F = np.array([recs[w.recording].force_mean for w in ws])
        y = np.array([w.mean for w in ws])
        for label, xv in (("voltage", V), ("load", F)):
            if np.ptp(xv) == 0:
                continue
            A = np.column_stack([np.ones_like(xv), xv - xv.mean()])
            coef, *_ = np.linalg.lstsq(A, y, rcond=None)
            dof = len(y) - 2
            if dof < 1:
                continue
            s2 = float(np.sum((y - A @ coef) ** 2)) / dof
            se = math.sqrt(s2 / float(np.sum((xv - xv.mean()) ** 2))) if s2 > 0 else 0.0
            tval = coef[1] / se if se > 0 else math.inf
            if abs(tval) > 3 and np.ptp(A @ coef) > 1e-6:
                unit = "kV" if label == "voltage" else "N"
                k = coef[1] * (1e3 if label == "voltage" else 1.0)
                out.append(f"{name}: the mismatch grows with {label} ({k * 1e6:+.3g} um per {unit}, t = {tval:.1f})")
    return out
