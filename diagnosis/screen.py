"""Screening a candidate before its full fit: a score (Lagrange-multiplier) test, and
what it predicts on the held-out conditions.

At the current fit the residual vector r (whitened samples and priors) and its Jacobian
J over the fitted unknowns are known (FitResult.lsq). A candidate adds parameters at a
neutral value where it changes nothing. Its probes - a small step in each coordinate from
there, or the straight line to each stated start value for an entry whose neutral point
cannot move (catalog.Entry.starts) - change the residuals by d_1..d_m (one batch of runs
each, with every recording's resistivity factor held). Projected off the span of J
(what the current unknowns can already do), they give the chi-square reduction a
Gauss-Newton step in the current unknowns and along the probes would make:

    LM = |r|^2 - min_a |r + D a|^2,   D = P [d_1 .. d_m],  P = I - J J^+

with a >= 0 for the probes that leave a bound (a one-sided score test: a stiffness that
would help only if negative is no evidence for one; without it the round's true model
still showed LM ~ 100 along the spline's drops and the branch's strength). The predicted
BIC change is n ln(1 - LM / chi2_data) + k ln n (k the candidate's parameters), as
FitResult.bic counts it.

The same step predicts the held-out error: the probes are run on the held-out recordings
too, the step's change of the current globals is carried there by their derivatives
(one batch per global, once a round), and each held-out recording's nuisance is refitted
(linearly) as the held-out evaluation does. A model's imperfection leaves structured
residuals that almost any parameter chips at (a few tens on the BIC scale); the held-out
prediction tells those from physics before a full fit is spent on them.

For a model linear in its parameters these are exactly what a full fit reaches; for ours
they are its first step. The current model's residuals are recomputed with the
probes' runs (same tolerance, SCREEN_RTOL): a probe's difference from them holds the
difference of two runs' integration errors, which is smooth in the parameters at 1e-5
(1e-6 gave the same LM to a few units on the true model and on a model one effect short,
at twice the runs' cost).

diagnose.shortlist says which candidates these predictions send to a full fit. A correct
model leaves LM ~ chi2 with k degrees of freedom, far under k ln n: no full fit at all.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import lsq_linear

from .fit import FD_STEP, Problem, Runner
from .model import apply, start

PROBE_LINEAR = 0.1   # probe step of a linear coordinate, in its scale (FreeParameter.scale)
PROBE_LOG = 0.05     # of a log coordinate (5 %)
SCREEN_RTOL = 1e-5


def probes(entry, p, ctx) -> list:
    """(Parameters, one_sided) at which to run the candidate `entry` on top of p (its
    neutral point, entry.prepare(current, ctx)): per start value, the start itself, and
    for the empty start (the neutral point) a step in each of the entry's coordinates that
    has a finite value there. one_sided: the probe leaves a bound (a stiffness, a mass,
    a branch's strength from 0; a start from the neutral point): only positive multiples
    of it are the candidate's."""
    spec = entry.spec(p, ctx)
    out = []
    for st in (entry.starts(p, ctx) if entry.starts else [{}]):
        if st:
            out.append((p.replace(**st), True))
            continue
        for i, f in enumerate(spec):
            try:
                z = start(p, [f])
            except (ValueError, OverflowError):     # log of 0: no neutral value to step from
                continue
            if not np.all(np.isfinite(z)):
                continue
            step = PROBE_LOG if f.log else PROBE_LINEAR
            lo, hi = f.z_bounds()
            zp = z[0] + step if z[0] + step <= hi else z[0] - step
            out.append((apply(p, [f], [zp]), bool(z[0] <= lo or z[0] >= hi)))
    return out


class Screen:
    """The score test against the current fit `current` (a FitResult) of one round: its
    runs at SCREEN_RTOL are made once, then `score(probes)` for each candidate."""

    def __init__(self, dataset, current, executor=None):
        lsq = current.lsq
        recs = {r.name: r for r in dataset.recordings}
        runner = Runner(executor)
        self.current, self.lsq, self.runner = current, lsq, runner
        self.prob = Problem([recs[nm] for nm in current.train], runner, current.sigma, lsq["sigma_rep"],
                            lsq["decimate"], lsq["pin"])
        self.held = None
        # held out: residuals, and their derivatives in the current globals (FD_STEP in z)
        # and in each recording's factor (read off the level's, see fit._solve)
        hp = hd = ht = None
        steps = []
        # the drives' timing as the current fit has it (a nuisance of every fit: fit._solve)
        self.tz = lsq.get("tz") if self.prob.T else None
        if current.heldout:
            held = [recs[nm] for nm in current.heldout]
            hp = Problem(held, runner, current.sigma, lsq["sigma_rep"], lsq["decimate"], False)
            hd = np.log([current.rho_factors[r.name] for r in held])
            ht = hp.flat_timing(current.timing)
            z = np.asarray(current.z, float)
            for i in range(len(current.spec)):
                zp = z.copy()
                zp[i] += FD_STEP
                steps.append((hp, apply(current.base, current.spec, zp), hd, ht))
        # every run of the set-up in one batch (the workers' load evens out over it)
        res = self._many([(self.prob, current.params, lsq["deltas"], self.tz)]
                         + ([(hp, current.params, hd, ht)] if hp else []) + steps)
        self.r0 = res[0]
        if hp is not None and self.r0 is not None and res[1] is not None:
            rh = res[1]
            G = np.array([np.zeros_like(rh) if r is None else (r - rh) / FD_STEP for r in res[2:]]).T
            G = G.reshape(len(rh), len(current.spec))
            Jh = np.zeros((len(rh), len(hp.recs)))
            level = G[:, 0] if current.spec and current.spec[0].is_level else None
            for j in range(len(hp.recs)):
                sl = slice(hp.offs[j], hp.offs[j + 1])
                if level is not None:
                    Jh[sl, j] = level[sl]
                Jh[hp.n + j, j] = 1.0 / lsq["sigma_rep"]
            self.held = {"prob": hp, "deltas": hd, "tz": ht, "r": rh, "G": G, "J": Jh}

    def _many(self, requests) -> list:
        """Residuals of each (Problem, Parameters, deltas, timing) request (None where a
        run failed), every run in one batch."""
        jobs, spans = [], []
        for prob, p, deltas, tz in requests:
            js = prob.jobs(p, deltas, SCREEN_RTOL, tz)
            spans.append((len(jobs), len(jobs) + len(js)))
            jobs += js
        xs = self.runner(jobs)
        out = []
        for (prob, p, deltas, tz), (a, b) in zip(requests, spans):
            part = xs[a:b]
            out.append(None if any(isinstance(x, str) for x in part) else prob.residuals(part, deltas, tz))
        return out

    @property
    def runs(self) -> int:
        return self.runner.runs

    def score(self, params_list) -> dict:
        """For probes ((Parameters, one_sided): the current model plus the candidate off its
        neutral point, see probes()): {'chi2_reduction': LM, 'heldout_ratio': predicted
        held-out RMSE over the current one (None without held-out conditions), 'runs':
        model runs, 'failed': probes that did not run}."""
        before = self.runs
        D, Dh, lo, failed = [], [], [], 0
        if self.r0 is None:
            failed = len(params_list)
            params_list = []
        requests = []
        for q, _ in params_list:
            requests.append((self.prob, q, self.lsq["deltas"], self.tz))
            if self.held is not None:
                requests.append((self.held["prob"], q, self.held["deltas"], self.held["tz"]))
        res = self._many(requests) if requests else []
        per = 2 if self.held is not None else 1
        for i, (q, one_sided) in enumerate(params_list):
            r, rh = res[per * i], (res[per * i + 1] if per == 2 else None)
            if r is None or (per == 2 and rh is None):
                failed += 1
                continue
            D.append(r - self.r0)
            if rh is not None:
                Dh.append(rh - self.held["r"])
            lo.append(0.0 if one_sided else -np.inf)
        out = {"chi2_reduction": 0.0, "heldout_ratio": None if self.held is None else 1.0, "runs": 0,
               "failed": failed}
        if D:
            D = np.array(D).T
            J, r0 = self.lsq["J"], self.r0
            # project the probes off what the current unknowns already span
            coef, *_ = np.linalg.lstsq(J, D, rcond=None)
            PD = D - J @ coef
            # the best combination of the probes, one-sided ones only forwards (a score test
            # at a boundary: a stiffness that would help only if negative is no evidence)
            a = lsq_linear(PD, -r0, bounds=(np.array(lo), np.full(len(lo), np.inf))).x
            out["chi2_reduction"] = max(float(r0 @ r0 - np.sum((r0 + PD @ a) ** 2)), 0.0)
            if self.held is not None and len(Dh) == D.shape[1]:
                out["heldout_ratio"] = self._heldout_ratio(np.array(Dh).T, a, -(coef @ a))
        out["runs"] = self.runs - before
        return out

    def _heldout_ratio(self, Dh, a, b):
        """Held-out RMSE after the step (a along the probes, b in the current unknowns:
        its first entries the globals), each recording's nuisance refitted, over before."""
        H = self.held
        k = len(self.current.spec)
        new = H["r"] + Dh @ a + H["G"] @ b[:k]
        n = H["prob"].n

        def refit(r):
            c, *_ = np.linalg.lstsq(H["J"], -r, rcond=None)
            return float(np.sqrt(np.mean((r + H["J"] @ c)[:n] ** 2)))

        before = refit(H["r"])
        return refit(new) / before if before > 0 else 1.0


def predicted_delta_bic(current, chi2_reduction: float, k: int) -> float:
    """The BIC change (FitResult.bic's definition) of a reduction of the data's chi-square
    by chi2_reduction with k more parameters."""
    chi2 = current.rss / current.sigma ** 2
    frac = max(1.0 - chi2_reduction / chi2, 1e-12) if chi2 > 0 else 1.0
    return current.n * math.log(frac) + k * math.log(current.n)
