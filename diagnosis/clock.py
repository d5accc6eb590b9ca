"""The drive's timing, fitted from the stroke. A recording's drive is read off its voltage
record (recordings._interpret), to a fraction of a sample where a regular reset's many
switches lie on one grid - but a reset of a few switches is read switch by switch, each
within its sample, its generator runs on its own clock, not the data-acquisition
system's (0.1 % apart is common), which a few switches do not show, and the hold starts
when the generator's timer says. The zipping each switch starts moves at ~1 m/s: on the
lab rig's unipolar drive (2 Hz, 1 s reset: 3 switches and the hold's) the switches were
read up to 0.5 ms off, the model at the truth's own parameters missed a clean recording
by 5.3 um RMS (216 um at a switch), and the rounds named inertia on a null dataset.

Each such recording gets up to three timing nuisances (recordings.retimed): the reset's
`shift`, its `clock` and the hold's start `hold_shift`, fitted on the baseline by a few
Levenberg-Marquardt steps on the full model's runs (a difference step in each, every
recording in one batch per nuisance) with priors from how each was read (nuisances()),
the sensor zero and the recording's (linearized) time shift profiled as in every fit
(fit.align). A recording's timing is changed only when that pays for itself on the BIC
scale (its chi-square falls by more than ln n per nuisance): otherwise it stays as
read."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from dfa_model.io.recordings import CLOCK_MIN_SWITCHES, RecordingError, retimed

from .fit import DECIMATE, SIGMA_REP, Problem, Runner

CLOCK_PRIOR = 1e-3     # prior SD of a drive's clock rate error (relative)
STEPS = {"shift": 5e-5, "clock": 1e-4, "hold_shift": 5e-5}   # difference steps (s, relative, s)
ITERATIONS = 4
LM_START = 0.01        # the Levenberg-Marquardt damping's start (relative to the curvature)


def nuisances(rec) -> dict:
    """The timing nuisances of a recording and their prior SDs. Only a drive whose switches
    were read one by one (a reset of too few switches for a grid) has any: the reset's
    shift and the hold's start (each read from one crossing: uniform within its sample, SD
    dt / sqrt(12)) and, with CLOCK_MIN_SWITCHES reset switches or more, its clock
    (CLOCK_PRIOR). A reset on a regular grid has its timing pinned by its many switches
    (a 30 Hz reset of 1 s: 0.04 ms and 1e-4), and its hold's start, freed, took up part of
    a series resistance's charging delay on the baseline this is fitted on (the proof's
    R_s 1e6 came out as 8.2e5, and with a branch beside it the held-out error doubled):
    left as read. A single switch's timing is the recording's time shift (fit.align)."""
    n = 0 if rec.switches is None else len(rec.switches)
    if n < 2 or rec.gridded:
        return {}
    sd = rec.dt / math.sqrt(12.0)
    out = {"shift": sd}
    if n - 1 >= CLOCK_MIN_SWITCHES:
        out["clock"] = CLOCK_PRIOR
    out["hold_shift"] = sd
    return out


def _residuals(recs, zs, keys, p, deltas, runner, sigma) -> list:
    """Each recording's whitened residuals (decimated samples) on the model p with its
    resistivity factor, its drive retimed by its nuisances' values; None where it cannot run."""
    moved, ok = [], []
    for r, z, k in zip(recs, zs, keys):
        try:
            moved.append(retimed(r, **dict(zip(k, z))))
            ok.append(True)
        except RecordingError:
            moved.append(r)
            ok.append(False)
    prob = Problem(moved, runner, sigma, SIGMA_REP, DECIMATE, False)
    xs = prob.runs(p, deltas)
    res = prob.residuals(xs, deltas)
    return [res[prob.offs[j]:prob.offs[j + 1]] if good and not isinstance(x, str) else None
            for j, (x, good) in enumerate(zip(xs, ok))]


def _chi2(r, z, priors) -> float:
    return math.inf if r is None else float(r @ r) + float(np.sum((z / priors) ** 2))


def calibrate(dataset, f, executor=None, say=None):
    """(dataset with each recording's fitted timing applied, record) on the fit f (a
    FitResult: its parameters and each recording's resistivity factor). record: None when
    no recording has a switch, else {recording: {shift, clock, hold_shift (None where not
    fitted; s, relative, s), stderr: {...}, chi2_reduction, applied}}."""
    say = say or (lambda s: None)
    idx = [j for j, r in enumerate(dataset.recordings) if nuisances(r)]
    if not idx:
        return dataset, None
    recs = [dataset.recordings[j] for j in idx]
    say(f"the drives' timing: {len(recs)} recordings")
    runner = Runner(executor)
    deltas = [math.log(f.rho_factors.get(r.name, 1.0)) for r in recs]
    priors = [nuisances(r) for r in recs]
    keys = [list(p) for p in priors]
    pri = [np.array(list(p.values())) for p in priors]
    z = [np.zeros(len(ks)) for ks in keys]
    r0 = _residuals(recs, z, keys, f.params, deltas, runner, f.sigma)
    first = [_chi2(r, zj, pj) for r, zj, pj in zip(r0, z, pri)]
    H = [np.diag(1.0 / pj ** 2) for pj in pri]
    lam = [LM_START] * len(recs)
    for _ in range(ITERATIONS):
        cols = {}
        for name, h in STEPS.items():   # one batch per nuisance: every recording's step in it at once
            if not any(name in ks for ks in keys):
                continue
            zi = [zj + h * np.array([k == name for k in ks]) for zj, ks in zip(z, keys)]
            cols[name] = _residuals(recs, zi, keys, f.params, deltas, runner, f.sigma)
        trial = []
        for j, (zj, pj, ks, rj) in enumerate(zip(z, pri, keys, r0)):
            G = [cols[k][j] for k in ks]
            if rj is None or any(g is None for g in G):
                trial.append(zj)
                continue
            J = np.column_stack([(g - rj) / STEPS[k] for g, k in zip(G, ks)])
            JJ = J.T @ J
            H[j] = JJ + np.diag(1.0 / pj ** 2)
            # Levenberg-Marquardt: a switch moved by a fraction of a millisecond moves the
            # zipping by tens of um, far from linear (a full step sent a clock to 5e-3)
            step = -np.linalg.solve(H[j] + lam[j] * np.diag(np.diag(JJ)), J.T @ rj + zj / pj ** 2)
            trial.append(np.clip(zj + step, -5 * pj, 5 * pj))
        rt = _residuals(recs, trial, keys, f.params, deltas, runner, f.sigma)
        for j, pj in enumerate(pri):
            if _chi2(rt[j], trial[j], pj) < _chi2(r0[j], z[j], pj):
                z[j], r0[j], lam[j] = trial[j], rt[j], lam[j] / 3
            else:
                lam[j] *= 10
    out, record = list(dataset.recordings), {}
    for j, r, zj, pj, ks, rj, c0, Hj in zip(idx, recs, z, pri, keys, r0, first, H):
        fall = c0 - _chi2(rj, zj, pj)
        applied = bool(math.isfinite(fall) and fall > len(zj) * math.log(len(rj)))
        se = dict(zip(ks, np.sqrt(np.diag(np.linalg.inv(Hj))).tolist()))
        values = dict(zip(ks, zj.tolist()))
        record[r.name] = {**{k: values.get(k) for k in STEPS}, "stderr": {k: se.get(k) for k in STEPS},
                          "chi2_reduction": float(fall) if math.isfinite(fall) else None, "applied": applied}
        if applied:
            out[j] = retimed(r, **values)
    done = [k for k, v in record.items() if v["applied"]]
    if done:
        say(f"the drives' timing refitted in {len(done)} of {len(record)} recordings")
    return replace(dataset, recordings=out), record
