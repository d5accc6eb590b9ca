"""Least-squares fit of the full model to recordings, jointly, with nuisance parameters.

Unknowns:
- the spec's global parameters (diagnosis.model.FreeParameter: rho_l always, plus any
  nominal value being corrected or a catalog entry's);
- per training recording, its liquid resistivity factor exp(delta_i) (repetitions of one
  device differ by a few percent: dfa_model.io.synthetic.scaled_resistivity), with the prior
  delta_i ~ N(0, sigma_rep) - so repetition scatter is never taken for missing physics;
- per recording, the sensor's zero offset: read where the model's actuator rests on its
  stop (a pre-trigger stretch at 0 V, the first sample, a complete unzip), with a prior
  (sensor_offset) - not the mean residual, which would swallow a static-stroke mismatch;
- per recording, its timing between the drive and the sensor (align): a fraction of a
  millisecond, which the zipping transient right after the first switch shows;
- per recording with switches, its drive's timing, and its voltage monitor's gain as it
  differs from its condition's other repetitions (diagnosis/timing.py).

Cost: sum over training samples of (residual / sigma)^2 + sum delta_i^2 / sigma_rep^2, sigma
the sensor noise estimated from the data (noise_level). Every `decimate`-th sample enters
the fit (the noise is white at 1 kHz; the stroke is smooth on that scale), and every one
of each switch's transient (fit_samples); errors are
reported on all samples. Solver: scipy.optimize.least_squares (trust region, bounds), its
Jacobian by forward differences with the problem's sparsity (a recording's residuals
depend on the globals and its own delta only), each evaluation one batch of full-model
runs through an executor (local processes by default: dfa_model.sweep's convention).

Held out: whole conditions (all repetitions of a load or a voltage, choose_holdout), run
with the fitted globals; only their nuisance is fitted - each recording's offset and
resistivity factor, with the same prior - so the held-out error measures the physics,
not the repetition scatter.

Uncertainty: the Gauss-Newton covariance at the optimum, inflated by the residuals'
variance over the noise's (when the model misses, > 1) and by their lag-1 correlation
(1 + r) / (1 - r) (correlated residuals carry fewer independent samples).
"""
from __future__ import annotations

import math
import os
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix
from threadpoolctl import threadpool_limits

from dfa_model.interrupt import local_pool
from dfa_model.io.parameters import Parameters
from dfa_model.io.recordings import RecordingError, retimed
from dfa_model.io.synthetic import scaled_resistivity

from .model import apply, start
from .timing import BOUND as TIMING_BOUND
from .timing import GAIN_PRIOR, GAIN_STEP
from .timing import STEPS as TIMING_STEPS
from .timing import gains as timing_gains
from .timing import nuisances as timing_nuisances

SIGMA_REP = 0.05     # prior SD of log(rho_l) between repetitions
DELTA_BOUND = 0.5    # |delta_i| at most (a factor 1.65)
DECIMATE = 5
# every sample this long after each switch of the drive (and one before) enters the fit too:
# a release under load is over in ~2 ms (870 -> 5 um on the lab rig at 6 kV, 5 N), so one
# sample in DECIMATE saw it at most once, and a unipolar train's off-switches did not time
# its drive - the line through its switches (timing.py) pinned by the on-switches' zipping
# and the priors missed the releases by 0.1-0.2 ms: 100 um spikes, a null's held out 1.91
# um against 1.04 um noise with an exact voltage monitor
SWITCH_SAMPLES = 6e-3
OFFSET_PRIOR = 20e-6 # prior SD of a sensor's zero offset (m)
# a zero at most this many prior SDs from 0: beyond, it is a stroke mismatch, not a zero. A
# lab recording without a rest stretch fits its zero over the whole run, and a baseline
# whose rho_l ran to where the actuator does not zip at all had each zero take up the
# stroke (+770 um), leaving 154 um: from there no screen saw a polarization branch
ZERO_MAX = 5.0
TIME_PRIOR = 0.2e-3  # prior SD of a recording's timing between the drive and the sensor (s)
NUISANCES = 3       # unknowns per recording: its resistivity factor, sensor zero and timing (align)
# the search's step tolerance (scipy's xtol: relative to the norm of the fitted
# coordinates, which ln rho_l ~ 28 dominates: 1e-5 stops at steps of ~3e-4 in z, a
# hundredth of a typical standard error; 1e-6 spent 2-3 more runs of every recording
# shrinking a trust region the model's integration roughness would not let it cross)
XTOL = 1e-5
PIN = 30.0           # weight of the zero-sum pin on the factors, against one factor's prior
DENSE_MAX = 4_000_000  # Jacobian entries up to which it is dense (32 MB)
# the integrator's tolerance in fits: the model's output moves in small jumps as its
# adaptive steps change with the parameters, and at the default 1e-4 those jumps put
# ~65 (chi-square units) of noise on the cost of 3 recordings along a 1e-3 change of
# rho_l - the search stalled in it (no step lowered the cost, the trust region shrank
# to nothing) and candidates' BIC differences scattered by tens. At 1e-5: ~1, for
# twice the steps
FIT_RTOL = 1e-5
FD_STEP = 0.02       # finite-difference step in the fitted coordinates (log: 2 %)
VERBOSE = int(os.environ.get("DFA_FIT_VERBOSE", "0"))
FAILED = 1e3         # residual (in noise units) of a sample whose run failed: the step is rejected


class FitError(ValueError):
    pass


def noise_level(rec) -> float:
    """Sensor noise (m, RMS) from the recording itself: the robust spread (MAD) of first
    differences over the second half of the hold, where the stroke moves by far less
    than the noise per sample; / sqrt(2) (a difference holds two samples' noise)."""
    t0 = rec.reset_end + 0.5 * (rec.duration - rec.reset_end)
    x = rec.stroke[rec.t >= t0]
    d = np.diff(x)
    if d.size < 10:
        d = np.diff(rec.stroke)
    mad = float(np.median(np.abs(d - np.median(d))))
    sd = mad / 0.6745 / math.sqrt(2.0)
    if sd == 0.0:   # quantized to steps coarser than the noise: the quantum's own spread
        q = np.min(np.abs(d[d != 0])) if np.any(d != 0) else 1e-9
        sd = q / math.sqrt(12.0)
    return sd


def sensor_offset(stroke, x_model, sigma, prior=OFFSET_PRIOR) -> float:
    """The sensor's zero offset (m): the mean reading where the model's actuator is at rest
    on its stop (x = 0: the first sample, and after a complete unzip), shrunk towards 0 by
    its prior N(0, prior). Not the mean over the run: that would also absorb a static-stroke
    mismatch, the very thing the diagnosis must see."""
    rest = x_model <= 0.0
    n = int(np.count_nonzero(rest))
    off = float(np.sum(stroke[rest] - x_model[rest])) / (n + (sigma / prior) ** 2) if n else 0.0
    return min(max(off, -ZERO_MAX * prior), ZERO_MAX * prior)


def sample_times(t: np.ndarray):
    """A recording's sample times as a job carries them: (t0, dt, n) when evenly spaced
    (a data-acquisition clock; within 1e-9 of a sample period), else the array itself.
    150 recordings of 23 s at 1 kHz are 27 MB of times: a Dask scheduler warned of a
    21.6 MiB graph at every batch of runs."""
    t = np.asarray(t, float)
    if t.size >= 3:
        dt = (t[-1] - t[0]) / (t.size - 1)
        if dt > 0 and np.max(np.abs(t - (t[0] + dt * np.arange(t.size)))) <= 1e-9 * dt:
            return (float(t[0]), float(dt), int(t.size))
    return t


def _times(spec) -> np.ndarray:
    if isinstance(spec, tuple):
        t0, dt, n = spec
        return t0 + dt * np.arange(n)
    return spec


def _run(job):
    """One recording on the full model (module-level: runs in worker processes): its
    stroke and stroke rate at the samples (rows), from the solver's dense record."""
    params, protocol, load, t = job
    if isinstance(protocol, str):      # a drive the timing could not be applied to (Problem.jobs)
        return protocol
    t = _times(t)
    from dfa_model import simulate
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = simulate(params, protocol, load=load, warn=False)
        tr = res.trace
        h = 2e-5
        return np.vstack([tr(t), (tr(t + h) - tr(t - h)) / (2 * h)])
    except Exception as exc:   # a parameter set the model cannot run: the caller rejects the step
        return f"{type(exc).__name__}: {exc}"


REST_MIN = 20       # samples at rest on the stop that read the sensor's zero; fewer: it is fitted


def align(stroke, run, sigma) -> tuple:
    """The model's stroke as the sensor saw it: (model at the samples with the sensor's
    zero added, that zero (sensor_offset), the recording's time shift tau (s)).

    The drive's switches are read off a 1 kHz voltage record: the first one, from rest,
    to a few hundredths of a millisecond (a regular reset's grid, recordings.py), and the
    zipping right after it moves at ~1 m/s, so that error alone misplaced those samples
    by up to 90 um. Each recording's timing is a nuisance like its zero: the model shifted
    by tau, linearized (x(t - tau) = x - tau dx/dt: tau is a fraction of the transient's
    milliseconds), with the prior N(0, TIME_PRIOR), profiled in closed form."""
    x, xd = run[0], run[1]
    if np.count_nonzero(x <= 0.0) < REST_MIN:
        # no rest stretch (a recording that starts with the drive): nothing reads the zero,
        # so it is fitted with the timing over the whole recording (prior N(0, OFFSET_PRIOR)).
        # It then also takes up a constant stroke mismatch: the report says so.
        e = stroke - x
        lo, lt = (sigma / OFFSET_PRIOR) ** 2, (sigma / TIME_PRIOR) ** 2
        a11, a12, a22 = e.size + lo, -float(np.sum(xd)), float(xd @ xd) + lt
        b1, b2 = float(np.sum(e)), -float(xd @ e)
        det = a11 * a22 - a12 * a12
        off, tau = (b1 * a22 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det
        cap = ZERO_MAX * OFFSET_PRIOR
        if abs(off) > cap:          # not a zero: held at the cap, the timing profiled again
            off = math.copysign(cap, off)
            tau = (b2 - a12 * off) / a22
        return x - tau * xd + off, off, tau
    off = sensor_offset(stroke, x, sigma)
    e0 = stroke - x - off
    tau = -float(e0 @ xd) / (float(xd @ xd) + (sigma / TIME_PRIOR) ** 2)
    return x - tau * xd + off, off, tau


class Runner:
    """Batches of recordings through an executor (None: in this process)."""

    def __init__(self, executor=None):
        self.executor = executor
        self.runs = 0

    def __call__(self, jobs):
        self.runs += len(jobs)
        if self.executor is None:
            return [_run(j) for j in jobs]
        size = max(1, len(jobs) // TASKS)
        if size == 1:
            return list(self.executor.map(_run, jobs))
        chunks = [jobs[i:i + size] for i in range(0, len(jobs), size)]
        return [x for part in self.executor.map(_run_all, chunks) for x in part]


TASKS = 16    # a batch of more runs than this goes to the executor in about this many tasks: 150 recordings
#               as 150 tasks of 30 ms kept a Dask scheduler and its client at 40 % of a core each


def _run_all(jobs):
    return [_run(j) for j in jobs]


def one_blas_thread():
    """Limit BLAS (OpenBLAS, MKL) to one thread in this process. The fit's vector
    operations (scipy's trust-region steps: norms and products over ~1e4 residuals) take
    2 us on one thread, but 0.2-3.5 ms when OpenBLAS spreads them over threads that spin
    for cores the model runs already hold: a 1000x slowdown, most of a diagnosis's wall
    time on a loaded 2-core machine."""
    threadpool_limits(1)


class InProcess:
    """An executor that runs the model in the calling process (a small diagnosis, or one
    already running one per core, needs no worker processes)."""

    @staticmethod
    def map(fn, jobs):
        return map(fn, jobs)

    def shutdown(self, *a, **k):
        pass


def local_executor(workers=None):
    """Local worker processes (one BLAS thread each, Ctrl-C left to the parent: stop it
    with dfa_model.interrupt.stop_pool, or owned_pool)."""
    return local_pool(workers, initializer=one_blas_thread)


@dataclass
class FitResult:
    spec: list
    base: Parameters                  # the parameters the spec was applied to
    params: Parameters                # fitted
    values: dict                      # key -> fitted value
    stderr: dict                      # key -> standard error (its units)
    sigma: float                      # sensor noise used (m)
    train: list                       # recording names
    heldout: list
    rho_factors: dict                 # recording -> exp(delta) (held out: its nuisance fit)
    offsets: dict                     # recording -> sensor offset (m)
    time_shifts: dict                 # recording -> its timing between drive and sensor (s, align)
    simulated: dict                   # recording -> model stroke at every sample (offset added)
    train_rmse: float
    heldout_rmse: float | None
    rss: float                        # sum of squared training residuals over fitted samples (m^2)
    n: int                            # fitted samples
    k: int                            # fitted unknowns (globals + NUISANCES per training recording)
    cost: float
    wall_time: float
    runs: int
    notes: list = field(default_factory=list)
    cov_z: np.ndarray | None = None   # covariance of the spec's globals in their fitted coordinates
    z: np.ndarray | None = None       # the spec's globals in their fitted coordinates
    lsq: dict | None = field(default=None, repr=False)   # the search's end: Jacobian, residuals, factors (screen.py)
    timing: dict = field(default_factory=dict)   # recording -> its drive's fitted timing {key: value} (timing.py;
    #                                              recordings with switches: timing.nuisances)
    converged: bool = True            # the search met its tolerances (not stopped by max_nfev)

    @property
    def bic(self) -> float:
        return self.n * math.log(self.rss / self.n) + self.k * math.log(self.n)

    @property
    def aic(self) -> float:
        return self.n * math.log(self.rss / self.n) + 2 * self.k

    def residual(self, rec) -> np.ndarray:
        """Measured minus model (offset removed) at every sample of `rec` (m)."""
        return rec.stroke - self.simulated[rec.name]

    def parameters_dict(self) -> dict:
        return {f.key: {"value": self.values[f.key], "stderr": self.stderr[f.key]} for f in self.spec}

    def model_values(self, keys) -> dict:
        """{key: {value, stderr}} for model keys (Parameters attributes) at the fit, their
        errors carried from the fitted coordinates' covariance (delta method): what a
        law fitted in coordinates of its own (model.Coordinate) is in its own keys."""
        v0 = np.array([float(getattr(self.params, k)) for k in keys])
        J = np.zeros((len(keys), len(self.spec)))
        for i in range(len(self.spec)):
            zp = np.array(self.z, float)
            zp[i] += 1e-6
            q = apply(self.base, self.spec, zp)
            J[:, i] = (np.array([float(getattr(q, k)) for k in keys]) - v0) / 1e-6
        var = np.einsum("ij,jk,ik->i", J, self.cov_z, J) if self.cov_z is not None else np.zeros(len(keys))
        return {k: {"value": float(v), "stderr": float(math.sqrt(max(s2, 0.0)))} for k, v, s2 in zip(keys, v0, var)}


def choose_holdout(dataset) -> list:
    """Conditions to hold out: all recordings at one load (the middle of three or more
    loads, else the largest of two), or, with one load, at one voltage (likewise); none
    with a single condition."""
    conds = list(dataset.conditions())
    loads = sorted({F for _, F in conds})
    volts = sorted({V for V, _ in conds})
    if len(loads) >= 2:
        F = loads[len(loads) // 2] if len(loads) >= 3 else loads[-1]
        return [c for c in conds if c[1] == F]
    if len(volts) >= 2:
        V = volts[len(volts) // 2] if len(volts) >= 3 else volts[-1]
        return [c for c in conds if c[0] == V]
    return []


class Problem:
    """Whitened residuals of training recordings against runs of the model: per recording
    every `decimate`-th sample of (measured - model - sensor offset) / sigma, then one
    prior row per recording's log resistivity factor (delta / sigma_rep), with a common
    level in the fit the zero-sum pin of the factors, and one prior row per timing
    nuisance (timing.py: value / prior SD). The timing nuisances, `tz`, are one flat array
    in recording order (keys[j] of recording j; None: every one as read). The monitors'
    gains (timing.gains) are in it as contrasts: a condition's n - 1 coordinates under the
    key "gain" of its recordings but the first, each recording's own gain the contrasts'
    combination (timing())."""

    def __init__(self, recs, runner, sigma, sigma_rep, decimate, pin, common_gain=False):
        self.recs, self.runner, self.sigma, self.sigma_rep = recs, runner, sigma, sigma_rep
        self.idx = [fit_samples(r, decimate) for r in recs]
        self.times = [sample_times(r.t) for r in recs]
        self.offs = np.concatenate([[0], np.cumsum([len(i) for i in self.idx])])
        self.n, self.R, self.pin = int(self.offs[-1]), len(recs), int(pin)
        priors = [timing_nuisances(r) for r in recs]
        groups = timing_gains(recs, common_gain)
        # a condition's coordinates sit with its last recordings: n - 1 contrasts from the
        # second on, or with the common gain (timing.gains) n from the first
        owners = [js[len(js) - C.shape[1]:] for js, C in groups]
        for js in owners:
            for j in js:
                priors[j]["gain"] = GAIN_PRIOR
        self.keys = [list(q) for q in priors]
        self.prior = np.array([v for q in priors for v in q.values()], float)
        self.toffs = np.concatenate([[0], np.cumsum([len(k) for k in self.keys])]).astype(int)
        self.T = int(self.toffs[-1])
        # each condition's gains: (its recordings, contrasts, the contrasts' places in tz)
        self.gains = [(js, C, np.array([self.toffs[j] + self.keys[j].index("gain") for j in o]))
                      for (js, C), o in zip(groups, owners)]

    def bound(self) -> np.ndarray:
        """Each nuisance's bound (+-) in the search's order: the recordings' log
        resistivity factors, then the flat timing (BOUND prior SDs)."""
        return np.concatenate([np.full(self.R, DELTA_BOUND), TIMING_BOUND * self.prior])

    def flat_timing(self, timing: dict | None):
        """The flat tz of {recording: {key: value}} (FitResult.timing, each recording's own
        gain among them; a nuisance it lacks at 0, as read), or None without it."""
        if not timing or not self.T:
            return None
        tz = np.array([timing.get(r.name, {}).get(key, 0.0) for r, ks in zip(self.recs, self.keys) for key in ks],
                      float)
        for js, C, at in self.gains:
            tz[at] = C.T @ np.array([timing.get(self.recs[j].name, {}).get("gain", 0.0) for j in js])
        return tz

    def timing(self, tz) -> list:
        """Each recording's timing nuisances {key: value} from the flat tz, with its own
        gain (the contrasts' combination) under "gain"."""
        if tz is None:
            return [{} for _ in self.recs]
        out = [dict(zip(k, map(float, tz[a:b]))) for k, a, b in zip(self.keys, self.toffs[:-1], self.toffs[1:])]
        for js, C, at in self.gains:
            for j, g in zip(js, C @ np.asarray(tz, float)[at]):
                out[j]["gain"] = float(g)
        return out

    def gain_columns(self, d, hs) -> tuple:
        """The Jacobian's gain columns as COO (rows, cols, values; cols in tz), from `d`, the
        residuals' change along a step hs[c] of every condition c's last contrast
        (timing.helmert: nonzero in each recording): recording j's rows of the column of
        contrast m are C[j, m] times its own change over its own step, h C[j, -1]."""
        rows, cols, vals = [], [], []
        for (js, C, at), h in zip(self.gains, hs):
            for i, j in enumerate(js):
                a, b = self.offs[j], self.offs[j + 1]
                per = d[a:b] / (h * C[i, -1])
                for m in np.flatnonzero(C[i]):
                    rows.append(np.arange(a, b))
                    cols.append(np.full(b - a, at[m]))
                    vals.append(C[i, m] * per)
        return rows, cols, vals

    def jobs(self, p: Parameters, deltas, rtol=FIT_RTOL, tz=None) -> list:
        """The runs of `runs` as jobs for a Runner (to batch several in one call)."""
        if p.rtol > rtol:
            p = p.replace(rtol=rtol)
        out = []
        for d, r, t, tm in zip(deltas, self.recs, self.times, self.timing(tz)):
            protocol = r.protocol
            if any(tm.values()):
                try:
                    protocol = retimed(r, **tm).protocol
                except RecordingError as exc:
                    protocol = str(exc)
            try:
                q = scaled_resistivity(p, math.exp(d))
            except ValueError as exc:     # a step beyond the model's ranges (a spline's level past 1e25)
                q, protocol = p, f"{type(exc).__name__}: {exc}"
            out.append((q, protocol, r.load, t))
        return out

    def runs(self, p: Parameters, deltas, rtol=FIT_RTOL, tz=None) -> list:
        """Each recording on the model p with its resistivity factor exp(delta) and its
        drive's timing tz: strokes at every sample, or a message for a run that failed.
        The integrator's tolerance is at most rtol."""
        return self.runner(self.jobs(p, deltas, rtol, tz))

    def residuals(self, xs, deltas, tz=None) -> np.ndarray:
        n, R = self.n, self.R
        out = np.empty(n + R + self.pin + self.T)
        out[n + R + self.pin:] = 0.0 if tz is None else np.asarray(tz, float) / self.prior
        for j, (r, xm) in enumerate(zip(self.recs, xs)):
            sl = slice(self.offs[j], self.offs[j + 1])
            if isinstance(xm, str):
                out[sl] = FAILED
                continue
            out[sl] = (r.stroke[self.idx[j]] - align(r.stroke, xm, self.sigma)[0][self.idx[j]]) / self.sigma
        out[n:n + R] = np.asarray(deltas) / self.sigma_rep
        if self.pin:
            out[n + R] = PIN * np.sum(deltas) / self.sigma_rep
        return out


def fit_samples(rec, decimate: int) -> np.ndarray:
    """The samples of `rec` a fit uses: every `decimate`-th, and every one from a sample
    before each switch of its drive to SWITCH_SAMPLES after it (the transients that time
    the drive: SWITCH_SAMPLES), in order."""
    idx = np.arange(0, len(rec.t), decimate)
    if rec.switches is None or not len(rec.switches) or decimate <= 1:
        return idx
    near = np.zeros(len(rec.t), bool)
    for a, b in zip(np.searchsorted(rec.t, rec.switches - rec.dt), np.searchsorted(rec.t, rec.switches + SWITCH_SAMPLES)):
        near[a:b] = True
    near[idx] = True
    return np.flatnonzero(near)


def _solve(recs, base, spec, z0, runner, sigma, sigma_rep, decimate, max_nfev, progress, d0=None, t0=None,
           common_gain=False):
    """Least squares over `recs`: the spec's globals (none: base fixed), one delta per
    recording and each recording's drive timing (timing.py; started at t0, a
    FitResult.timing, else as read), each recording's offset read at rest (sensor_offset). Returns (the
    least_squares result, the Problem, the model's strokes at every sample at the
    solution). common_gain: each condition's monitors' common gain is a nuisance too
    (timing.gains)."""
    k, R = len(spec), len(recs)
    level = k > 0 and spec[0].is_level
    # with a common level in the fit, the recordings' factors are pinned to a zero sum:
    # the optimum has it anyway (a shift of the level against every factor leaves the
    # data as they are and changes only the prior, least at zero mean), and without the
    # pin that shift is a long valley that only the prior curves, along which the
    # search crawled and stopped early (factors all at +0.12 to +0.3)
    prob = Problem(recs, runner, sigma, sigma_rep, decimate, level and R > 1, common_gain)
    n, pin, offs, T = prob.n, prob.pin, prob.offs, prob.T
    tz0 = prob.flat_timing(t0)
    x0 = np.concatenate([np.asarray(z0, float), np.zeros(R) if d0 is None else np.asarray(d0, float),
                         np.zeros(T) if tz0 is None else tz0])
    lo = np.concatenate([[f.z_bounds()[0] for f in spec], -prob.bound()])
    hi = np.concatenate([[f.z_bounds()[1] for f in spec], prob.bound()])
    x0 = np.clip(x0, np.where(np.isfinite(lo), lo + 1e-9 * np.maximum(1, np.abs(lo)), lo),
                 np.where(np.isfinite(hi), hi - 1e-9 * np.maximum(1, np.abs(hi)), hi))
    # the trust-region steps solved exactly (SVD of a dense Jacobian) while it is small:
    # the iterative solver (LSMR) resolved the directions the data pin and neglected the
    # flat ones the priors alone curve (a common level against every recording's factor),
    # so the search stopped short in them
    dense = (n + R + pin + T) * (k + R + T) <= DENSE_MAX

    def simulate_many(xps):
        # several points' runs in one batch: the executor's workers stay busy across them
        # (9 recordings on 2 cores left one idle at every batch's end)
        jobs = [_jobs_at(prob, base, spec, xp, k, R, T) for xp in xps]
        runs = prob.runner([j for js in jobs for j in js])
        return [runs[i - len(js):i] for js, i in zip(jobs, np.cumsum([len(js) for js in jobs]))]

    def simulate_all(x):
        return simulate_many([x])[0]

    def fun(x):
        xs = simulate_all(x)
        last_runs[x.tobytes()] = xs
        if progress:
            progress(f"{runner.runs} runs")
        return prob.residuals(xs, x[k:k + R], x[k + R:] if T else None)

    last, last_runs = {}, {}

    def fun_cached(x):
        key = x.tobytes()
        if key not in last:
            last.clear()
            last_runs.clear()
            last[key] = fun(x)
        return last[key]

    def fun_many(xps):
        out = [prob.residuals(xs, xp[k:k + R], xp[k + R:] if T else None)
               for xp, xs in zip(xps, simulate_many(xps))]
        if progress:
            progress(f"{runner.runs} runs")
        return out

    def jac(x):
        # forward differences of FD_STEP in z (an adaptive solver's output is rough on
        # the scale of its tolerance: smaller steps measure that, not the derivative);
        # one set of runs per global, one for all deltas at once (disjoint rows) and one
        # per kind of timing nuisance (every recording's at once), all in one batch. Built
        # as COO triplets: a global's column is dense over the samples, a delta's holds its
        # recording's samples and its prior's row
        f0 = fun_cached(x)
        points = []
        hg = [FD_STEP if x[i] + FD_STEP <= hi[i] else -FD_STEP for i in range(k)]
        for i in range(k):
            xp = x.copy()
            xp[i] += hg[i]
            points.append(xp)
        hs = np.where(x[k:k + R] + FD_STEP <= hi[k:k + R], FD_STEP, -FD_STEP) if R else None
        # a recording's factor moves its samples exactly as the common level does (both
        # scale its whole law by exp(h)): the level's runs serve
        share = bool(R and level and hg[0] > 0 and np.all(hs > 0))
        if R and not share:
            xp = x.copy()
            xp[k:k + R] += hs
            points.append(xp)
        timing = []
        for name, h in TIMING_STEPS.items():
            which = [(j, prob.toffs[j] + prob.keys[j].index(name)) for j in range(R) if name in prob.keys[j]]
            if not which:
                continue
            xp = x.copy()
            steps = {}
            for j, i in which:
                steps[j] = h if x[k + R + i] + h <= hi[k + R + i] else -h
                xp[k + R + i] += steps[j]
            timing.append((which, steps, len(points)))
            points.append(xp)
        gain_at, gain_h = None, []
        if prob.gains:
            # every condition's gains at once, along its last contrast (prob.gain_columns);
            # backwards where the step forwards would cross the bound
            xp = x.copy()
            for _, _, at in prob.gains:
                i = k + R + at[-1]
                gain_h.append(GAIN_STEP if x[i] + GAIN_STEP <= hi[i] else -GAIN_STEP)
                xp[i] += gain_h[-1]
            gain_at = len(points)
            points.append(xp)
        fs = fun_many(points) if points else []
        rows, cols, vals = [], [], []
        for i in range(k):
            rows.append(np.arange(n))
            cols.append(np.full(n, i))
            vals.append((fs[i][:n] - f0[:n]) / hg[i])
        if R:
            d = (fs[0] - f0) * FD_STEP / hg[0] if share else fs[k] - f0
            rec = np.repeat(np.arange(R), np.diff(offs))      # each sample's recording
            rows += [np.arange(n), n + np.arange(R)]
            cols += [k + rec, k + np.arange(R)]
            vals += [d[:n] / hs[rec], np.full(R, 1.0 / sigma_rep)]
            if pin:
                rows.append(np.full(R, n + R))
                cols.append(k + np.arange(R))
                vals.append(np.full(R, PIN / sigma_rep))
        # the drives' timing, and each nuisance's prior row
        for which, steps, at in timing:
            d = fs[at] - f0
            for j, i in which:
                rows += [np.arange(offs[j], offs[j + 1]), [n + R + pin + i]]
                cols += [np.full(offs[j + 1] - offs[j], k + R + i), [k + R + i]]
                vals += [d[offs[j]:offs[j + 1]] / steps[j], [1.0 / prob.prior[i]]]
        if gain_at is not None:
            gr, gc, gv = prob.gain_columns(fs[gain_at] - f0, gain_h)
            ats = np.concatenate([at for _, _, at in prob.gains])
            rows += gr + [n + R + pin + ats]
            cols += [k + R + c for c in gc] + [k + R + ats]
            vals += gv + [1.0 / prob.prior[ats]]
        J = csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n + R + pin + T, k + R + T))
        return J.toarray() if dense else J

    with np.errstate(all="ignore"):
        sol = least_squares(fun_cached, x0, jac=jac, bounds=(lo, hi), x_scale="jac", ftol=1e-6, xtol=XTOL,
                            gtol=1e-8, max_nfev=max_nfev, method="trf", tr_solver="exact" if dense else "lsmr",
                            verbose=VERBOSE)
    # the solution's runs are those of its last evaluation when the search ended there
    xs = last_runs.get(sol.x.tobytes())
    return sol, prob, xs if xs is not None else simulate_all(sol.x)


def _jobs_at(prob, base, spec, xp, k, R, T) -> list:
    """prob's jobs at the point xp of the search; a point whose parameters the model
    refuses (a step beyond their ranges) gives failed runs, which reject the step."""
    try:
        p = apply(base, spec, xp[:k])
    except (ValueError, ArithmeticError) as exc:
        return [(base, f"{type(exc).__name__}: {exc}", r.load, t) for r, t in zip(prob.recs, prob.times)]
    return prob.jobs(p, xp[k:k + R], tz=xp[k + R:] if T else None)


def log_factors(f, recs) -> list:
    """Fit f's log resistivity factors of the recordings recs (0 where it has none)."""
    return [math.log(f.rho_factors.get(r.name, 1.0)) for r in recs]


def warm_deltas(warm, recs) -> list:
    """Start values of the recordings' log resistivity factors from an earlier fit: its
    factors less their mean over each condition. The deviations between repetitions are
    scatter that any model leaves to the nuisance; a condition's common factor is what
    the earlier model could not explain, and a candidate may: started there, the search
    kept most of it (Eq. 21 truth: the law came out scaled by 0.75, every factor 1.3)."""
    d = log_factors(warm, recs)
    by = {}
    for r, v in zip(recs, d):
        by.setdefault(r.condition(), []).append(v)
    return [v - float(np.mean(by[r.condition()])) for r, v in zip(recs, d)]


def _start_nuisances(warm, resume, recs, demean=False) -> tuple:
    """(the recordings' log resistivity factors, their drives' timing) a search starts
    from: a resumed search's exactly where it stopped, else the warm fit's - as they are,
    or with `demean` less each condition's mean (warm_deltas) - else None."""
    if resume is not None:
        return log_factors(resume, recs), resume.timing
    if warm is None:
        return None, None
    if demean:
        return warm_deltas(warm, recs), warm.timing
    return log_factors(warm, recs), warm.timing


def fit(dataset, spec, base: Parameters | None = None, holdout=None, executor=None, sigma_rep=SIGMA_REP,
        decimate=DECIMATE, z0=None, max_nfev=40, progress=None, warm=None, resume=None,
        held_out=True, demean=False, common_gain=False) -> FitResult:
    """Fit `spec` (list of FreeParameter) to the dataset's training recordings (module
    docstring). base: the parameters the spec is applied to (default the dataset's
    nominal actuator); holdout: conditions (V, F) to hold out (default choose_holdout);
    progress: a callable(str) told of each model evaluation; warm: a FitResult whose
    per-recording resistivity factors start this fit as they are (the same model at
    another N, or a candidate from its nested start: the start is then exactly the warm
    fit, and the search can only lower its cost), or with `demean` less their mean over
    each condition (warm_deltas: a candidate started away from the warm model, which may
    explain what a condition's factors shared). On a series resistance's dataset at N = 81
    (lab_fine) the warm fit's cost 30309 became 87390 at the nested start of an Eq. (21)
    law with the means removed, and 25 evaluations ended at 68558 - a BIC 7751 above the
    model the law extends; resume: a FitResult of this same spec
    whose search stopped early (max_nfev) - the search goes on from exactly where it
    stopped (its globals, factors and timing; base is its base), and the result counts
    its runs and time too; held_out=False: the held-out recordings are not fitted
    (heldout_rmse None: a start of several that race on their cost, _multistart);
    common_gain: each training condition's monitors' common gain is a nuisance too
    (timing.gains; gain_account.py - not with held-out recordings, whose common gain would
    be fitted on their own data). BLAS runs on one thread meanwhile (one_blas_thread)."""
    if common_gain and held_out:
        raise ValueError("common_gain: fit with held_out=False (a held-out condition's common gain is its own fit)")
    with threadpool_limits(1):
        if resume is None:
            return _fit(dataset, spec, base, holdout, executor, sigma_rep, decimate, z0, max_nfev, progress, warm,
                        held_out=held_out, demean=demean, common_gain=common_gain)
        f = _fit(dataset, spec, resume.base, holdout, executor, sigma_rep, decimate, resume.z, max_nfev, progress,
                 warm, resume, held_out=held_out, common_gain=common_gain)
        return replace(f, runs=f.runs + resume.runs, wall_time=f.wall_time + resume.wall_time)


def evaluate(dataset, fr: FitResult, params: Parameters, executor=None) -> FitResult:
    """fr's model at `params` (its fitted values at another N, say) with fr's own
    nuisances - each recording's resistivity factor and drive timing, as fitted - and
    nothing fitted again but each sensor's zero and time shift (align): one run per
    recording, training and held out, in one batch. A feasible point of the refit at
    `params` that starts there: the refit's training residuals can only be smaller, so a
    check that this point passes needs no refit (resolution._resolution_check). The result
    has fr's spec, k and n (its BIC compares with fits of the same data); `notes` says it
    was evaluated, not fitted."""
    wall = time.perf_counter()
    by = {r.name: r for r in dataset.recordings}
    train, held = [by[n] for n in fr.train], [by[n] for n in fr.heldout]
    decimate = fr.lsq["decimate"] if fr.lsq else DECIMATE
    sigma_rep = fr.lsq["sigma_rep"] if fr.lsq else SIGMA_REP
    runner = Runner(executor)
    probs = [Problem(rs, runner, fr.sigma, sigma_rep, decimate, False) for rs in (train, held)]
    deltas = [log_factors(fr, rs) for rs in (train, held)]
    tzs = [pb.flat_timing(fr.timing) for pb in probs]
    jobs = [pb.jobs(params, d, tz=tz) for pb, d, tz in zip(probs, deltas, tzs)]
    runs = runner(jobs[0] + jobs[1])
    xs = [runs[:len(jobs[0])], runs[len(jobs[0]):]]
    simulated, offsets, shifts, train_rmse, heldout_rmse = _aligned(train, xs[0], held, xs[1], fr.sigma,
                                                                    f"the model does not run at N = {params.N}")
    res = probs[0].residuals(xs[0], deltas[0], tzs[0])
    r_fit = res[:probs[0].n]
    return replace(fr, params=params, offsets=offsets, time_shifts=shifts, simulated=simulated,
                   train_rmse=train_rmse, heldout_rmse=heldout_rmse,
                   rss=float(r_fit @ r_fit) * fr.sigma ** 2, cost=0.5 * float(res @ res),
                   wall_time=time.perf_counter() - wall, runs=runner.runs, lsq=None, converged=False,
                   notes=[f"evaluated at N = {params.N} with the fit's values and nuisances, not refitted"])


def predicted_refit(dataset, fr: FitResult, params: Parameters, executor=None) -> dict | None:
    """What a refit of fr at `params` (its values at another N, say) would give, from one
    Gauss-Newton step: fr's training recordings run at params with fr's own nuisances (one
    run each, in one batch), and the step that fr's Jacobian (lsq J, at its solution) gives
    against those residuals. Returns {fit (a FitResult of fr's spec at the step's
    coordinates, fit.z, and its nuisances - the training recordings' factors and drive
    timing - where the step puts them: a refit warm from it starts at the step; fr's
    errors: model_values carries them), cost_at (the cost at fr's
    values there), cost_step (the step's linear prediction), runs}; None without fr's
    Jacobian. The step lies within fr's bounds (clipped)."""
    if not fr.lsq or "J" not in fr.lsq:
        return None
    lsq, k = fr.lsq, len(fr.spec)
    prob, deltas, tz = _train_problem(dataset, fr, executor, lsq["pin"])
    with threadpool_limits(1):      # the step's least squares too (one_blas_thread)
        xs = prob.runs(params, deltas, tz=tz)
        if any(isinstance(x, str) for x in xs):
            return None
        r = prob.residuals(xs, deltas, tz)
        J = lsq["J"]
        if J.shape[0] != r.size:
            return None
        dx = -np.linalg.lstsq(J, r, rcond=None)[0]
    lo = np.array([f.z_bounds()[0] for f in fr.spec])
    hi = np.array([f.z_bounds()[1] for f in fr.spec])
    z = np.clip(fr.z + dx[:k], lo, hi)
    r_step = r + J @ np.concatenate([z - fr.z, dx[k:]])
    base = fr.base.replace(N=params.N)
    # the step's nuisances too (within their bounds), so a refit warm from it starts at the step
    R = len(prob.recs)
    nu = np.clip(np.concatenate([deltas, [] if tz is None else tz]) + dx[k:], -prob.bound(), prob.bound())
    factors = {**fr.rho_factors, **{rec.name: math.exp(d) for rec, d in zip(prob.recs, nu[:R])}}
    timing = fr.timing
    if tz is not None:
        timing = {**fr.timing, **{rec.name: tm for rec, tm in zip(prob.recs, prob.timing(nu[R:])) if tm}}
    g = replace(fr, base=base, params=apply(base, fr.spec, z), z=z, rho_factors=factors, timing=timing,
                values={f.key: f.from_z(z[i]) for i, f in enumerate(fr.spec)},
                stderr={f.key: (f.from_z(z[i]) * fr.stderr[f.key] / max(abs(fr.values[f.key]), 1e-300) if f.log
                                else fr.stderr[f.key]) for i, f in enumerate(fr.spec)},
                notes=[f"predicted at N = {params.N} by one Gauss-Newton step from the fit at N = {fr.params.N}"])
    return {"fit": g, "cost_at": 0.5 * float(r @ r), "cost_step": 0.5 * float(r_step @ r_step),
            "runs": prob.runner.runs}


def _train_problem(dataset, fr: FitResult, executor, pin) -> tuple:
    """(Problem of fr's training recordings, their log resistivity factors, their drives'
    flat timing or None) as fr's search left them (its lsq record)."""
    by = {r.name: r for r in dataset.recordings}
    lsq = fr.lsq
    prob = Problem([by[n] for n in fr.train], Runner(executor), fr.sigma, lsq["sigma_rep"], lsq["decimate"], pin)
    return prob, lsq["deltas"], (lsq["tz"] if len(lsq["tz"]) else None)


def model_strokes(dataset, fr: FitResult, Ns, executor=None) -> list | None:
    """fr's model at its fitted values and each of the elements `Ns`: for each N, the
    strokes at every sample of fr's training recordings (each with its own resistivity
    factor and drive timing), all in one batch - no data enter. None when a run fails or
    fr has no fit record."""
    if not fr.lsq:
        return None
    prob, deltas, tz = _train_problem(dataset, fr, executor, False)
    with threadpool_limits(1):
        runs = prob.runner([j for N in Ns for j in prob.jobs(fr.params.replace(N=N), deltas, tz=tz)])
    if any(isinstance(x, str) for x in runs):
        return None
    R = prob.R
    return [[x[0] for x in runs[i * R:(i + 1) * R]] for i in range(len(Ns))]     # row 0: the stroke (_run)


def stroke_rms(a, b) -> float:
    """The RMS difference of two model_strokes lists (m, over every sample)."""
    return math.sqrt(sum(float(np.sum((x - y) ** 2)) for x, y in zip(a, b)) / sum(x.size for x in a))


def self_error(dataset, fr: FitResult, N_ref: int, executor=None) -> float | None:
    """The model's own discretization error at fr's fitted values: the RMS difference (m,
    model_strokes) between fr's model at its N and the same model at N_ref. None when a
    run fails or fr has no fit record."""
    s = model_strokes(dataset, fr, [fr.params.N, N_ref], executor)
    return None if s is None else stroke_rms(*s)


def condition_gains(recs, gains: dict) -> list:
    """Each condition's monitors' common gain, from the recordings' own gains ({name:
    gain}, those of recs that have one): [{voltage, force, gain (their mean), prior_sd (the
    per-recording prior on the mean of n: GAIN_PRIOR / sqrt(n))}], in the order the
    conditions first appear."""
    by = {}
    for r in recs:
        if r.name in gains:
            by.setdefault(r.condition(), []).append(gains[r.name])
    return [{"voltage": c[0], "force": c[1], "gain": float(np.mean(v)), "prior_sd": GAIN_PRIOR / math.sqrt(len(v))}
            for c, v in by.items()]


def heldout_common_gain(dataset, fr: FitResult, executor=None, max_nfev=40) -> dict | None:
    """fr's held-out recordings fitted again with fr's physics, their nuisances as before
    and each held-out condition's monitors' common gain free as well (timing.gains with
    common: the same per-recording prior GAIN_PRIOR, so a condition of n recordings has
    its common gain at GAIN_PRIOR / sqrt(n)). What a held-out condition shares is the
    physics' in every fit - a spring's force at one condition is what a 0.15 % gain does,
    and fitted there the gain took it - but a calibration is shared too: the lab rig's
    monitors read 0.2 % off per recording, a 3-recording condition's mean beyond 0.2 % in
    8 % of draws. So this is a second account of a held-out error, not a fit: {"rmse": the
    held-out stroke RMSE (m), "rmse_without": the same refit without the common gain (the
    control: fr's held-out nuisances need not be optimal where fr was evaluated at another
    N), "gains": {recording: its gain}, "conditions": [{"voltage", "force", "gain": the
    recordings' mean, "prior_sd"}], "converged", "runs"}; None when nothing was held out or
    no held-out recording's gain is a nuisance (timing.gains)."""
    by = {r.name: r for r in dataset.recordings}
    held = [by[n] for n in fr.heldout]
    groups = timing_gains(held, True)
    if not held or not groups:
        return None
    decimate = fr.lsq["decimate"] if fr.lsq else DECIMATE
    sigma_rep = fr.lsq["sigma_rep"] if fr.lsq else SIGMA_REP
    runner = Runner(executor)
    d0 = log_factors(fr, held)

    def rmse(xs):     # over every sample, as the held-out evaluation's (_aligned: the held-out ones as its first)
        return _aligned(held, xs, [], [], fr.sigma, "the fitted model does not run")[3]

    with threadpool_limits(1):
        out = [_solve(held, fr.params, [], [], runner, fr.sigma, sigma_rep, decimate, max_nfev, None, d0, fr.timing,
                      common_gain=common) for common in (False, True)]
    (_, _, xs0), (sol, prob, xs) = out
    timing = prob.timing(sol.x[len(held):])
    gains = {r.name: tm["gain"] for r, tm in zip(held, timing) if "gain" in tm}
    conditions = condition_gains(held, gains)
    return {"rmse": rmse(xs), "rmse_without": rmse(xs0), "gains": gains, "conditions": conditions,
            "converged": bool(out[0][0].success and sol.success), "runs": runner.runs}


def _aligned(train, xs, held, xs_h, sigma, fails: str) -> tuple:
    """Each recording's model stroke as its sensor saw it (align), training and held out:
    (simulated, offsets, time shifts, training RMSE, held-out RMSE or None without held-out
    recordings), over every sample. A run that failed (a message) raises FitError:
    `fails` says what did not run."""
    simulated, offsets, shifts = {}, {}, {}
    sq = {"train": [0.0, 0], "held": [0.0, 0]}
    for r, xm, part in [(r, xm, "train") for r, xm in zip(train, xs)] + [(r, xm, "held") for r, xm in zip(held, xs_h)]:
        if isinstance(xm, str):
            raise FitError(f"{r.name}: {fails} ({xm})")
        simulated[r.name], offsets[r.name], shifts[r.name] = align(r.stroke, xm, sigma)
        e = r.stroke - simulated[r.name]
        sq[part][0] += float(e @ e)
        sq[part][1] += e.size
    return (simulated, offsets, shifts, math.sqrt(sq["train"][0] / sq["train"][1]),
            math.sqrt(sq["held"][0] / sq["held"][1]) if held else None)


def _condition_of(dataset, c) -> tuple:
    """The dataset's condition a user's (V, F) names (within the grouping's tolerances:
    a condition's key is its first recording's values)."""
    from dfa_model.io.recordings import CONDITION_F, CONDITION_V
    V, F = float(c[0]), float(c[1])
    for k in dataset.conditions():
        if abs(k[0] - V) <= CONDITION_V * abs(V) and abs(k[1] - F) <= max(CONDITION_F * abs(F), 0.01):
            return k
    return (V, F)


def _fit(dataset, spec, base, holdout, executor, sigma_rep, decimate, z0, max_nfev, progress, warm,
         resume=None, held_out=True, demean=False, common_gain=False) -> FitResult:
    wall = time.perf_counter()
    base = base or dataset.params
    holdout = choose_holdout(dataset) if holdout is None else [_condition_of(dataset, c) for c in holdout]
    recs = dataset.recordings
    train = [r for r in recs if r.condition() not in holdout]
    held = [r for r in recs if r.condition() in holdout] if held_out else []
    if not train:
        raise FitError("holdout: every recording is held out; nothing to fit")
    runner = Runner(executor)
    sigma = float(np.median([noise_level(r) for r in recs]))
    k, R = len(spec), len(train)
    z_start = start(base, spec) if z0 is None else np.asarray(z0, float)
    d0, t0 = _start_nuisances(warm, resume, train, demean)
    sol, prob, xs = _solve(train, base, spec, z_start, runner, sigma, sigma_rep, decimate, max_nfev, progress, d0,
                           t0, common_gain)
    n, T = prob.n, prob.T
    x = sol.x
    notes = []
    if not sol.success:
        notes.append(f"the least-squares search stopped before converging ({sol.message})")
    # covariance of the globals (noise units: the residuals are already / sigma)
    J = sol.jac.toarray() if hasattr(sol.jac, "toarray") else np.asarray(sol.jac)
    lsq = {"J": J, "r": np.array(sol.fun), "deltas": np.array(x[k:k + R]), "tz": np.array(x[k + R:]),
           "sigma_rep": sigma_rep, "decimate": decimate, "pin": prob.pin}
    # the zero-sum pin is a device of the search: the level's error keeps the repetitions' mean
    J = np.vstack([J[:n + R], J[n + R + prob.pin:]])
    r_fit = sol.fun[:n]
    dof = max(n - (k + NUISANCES * R + T), 1)
    s2 = max(1.0, float(np.sum(r_fit ** 2)) / dof)
    rho1 = float(np.clip(np.corrcoef(r_fit[:-1], r_fit[1:])[0, 1], 0.0, 0.99)) if n > 3 else 0.0
    cov = np.linalg.pinv(J.T @ J) * s2 * (1 + rho1) / (1 - rho1)
    values, stderr = {}, {}
    for i, f in enumerate(spec):
        v = f.from_z(x[i])
        se_z = math.sqrt(max(cov[i, i], 0.0))
        values[f.key] = v
        stderr[f.key] = v * se_z if f.log else se_z * f.scale
    fitted = apply(base, spec, x[:k])
    factors = {r.name: math.exp(x[k + j]) for j, r in enumerate(train)}
    timing = {r.name: tm for r, tm in zip(train, prob.timing(x[k + R:])) if tm}
    # held out: the physics fixed at the fit, only each recording's nuisances (its offset,
    # resistivity factor and drive's timing, with the same priors) fitted
    if held:
        # started from the resumed search's own held-out fit, else the warm one's (a
        # racing start skipped it)
        own = resume if resume is not None and all(r.name in resume.rho_factors for r in held) else None
        h0, th = _start_nuisances(warm, own, held, demean)
        sol_h, prob_h, xs_h = _solve(held, fitted, [], [], runner, sigma, sigma_rep, decimate, max_nfev, progress, h0,
                                     th)
        factors.update({r.name: math.exp(sol_h.x[j]) for j, r in enumerate(held)})
        timing.update({r.name: tm for r, tm in zip(held, prob_h.timing(sol_h.x[len(held):])) if tm})
    else:
        xs_h = []
    simulated, offsets, shifts, train_rmse, heldout_rmse = _aligned(train, xs, held, xs_h, sigma,
                                                                    "the fitted model does not run")
    rss = float(np.sum(r_fit ** 2)) * sigma ** 2
    return FitResult(spec=list(spec), base=base, params=fitted, values=values, stderr=stderr, sigma=sigma,
                     train=[r.name for r in train], heldout=[r.name for r in held], rho_factors=factors,
                     offsets=offsets, time_shifts=shifts, simulated=simulated,
                     train_rmse=train_rmse, heldout_rmse=heldout_rmse, rss=rss, n=n,
                     k=k + NUISANCES * R + T, cost=float(sol.cost), wall_time=time.perf_counter() - wall, runs=runner.runs,
                     notes=notes, cov_z=cov[:k, :k].copy(), z=np.array(x[:k]), lsq=lsq, timing=timing,
                     converged=bool(sol.success))
