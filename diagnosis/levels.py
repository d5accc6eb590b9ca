"""Where a field law's fit starts: the constant resistivity each hold voltage's training
recordings prefer on their own.

A field-dependent resistivity is, seen from the recordings, a different resistivity at
each voltage. The baseline fits one level to every voltage at once, and when the law is
steep that common level is no voltage's: on a dataset whose truth is Eq. (21) reaching
its floor between the conditions' fields (3.4e12 ohm m at 5 kV, its 1e11 floor at 8 kV,
unipolar pulses), the baseline settled at 1.4e10, 250x under the 5 kV value, and the
law fits started there stalled at 171-197 um held out (84 noises before). Started from
the law through the voltages' own levels, Eq. (21) and a three-knot spline reached
16-18 um on the same data.

`voltage_levels` scans one constant level per training voltage over a log grid around
the fit's level (one batch of runs, the fit's timing and every recording's sensor zero
as the fit aligns them, resistivity factors at 1): the levels are starts, not estimates.
"""
from __future__ import annotations

import numpy as np

from dfa_model.io.recordings import CONDITION_V
from dfa_model.io.synthetic import scaled_resistivity

from .fit import Problem, Runner
from .model import rho_at, zipped_field

LEVEL_DECADES = 3.0   # the scan's half width around the fit's level (decades)
LEVEL_STEPS = 4       # grid points per decade (a factor 1.78 between them)
LEVEL_BOUNDS = (1e8, 1e16)   # the baseline's own bounds on the level (catalog.baseline_spec)
LEVEL_VOLTAGES = 4    # voltages scanned at most, spread over the training voltages' range
LEVEL_RECORDINGS = 3  # recordings of each voltage scanned at most


def voltage_levels(dataset, f, ctx, executor=None) -> tuple:
    """((E, rho), ...) ascending in E: per hold voltage of f's training recordings (at most
    LEVEL_VOLTAGES of them, the lowest and the highest among them; LEVEL_RECORDINGS of each), the
    resistivity level (the fit's law scaled at every field, its value at ctx.E_ref) whose
    runs fit that voltage's training recordings best on the grid; E the field there, on
    E_ref's scale: E_ref is the mean front field over the middle voltage's hold
    (catalog.hold_field), a few percent under the zipped field, and the zipped field
    scales with the voltage. Empty with fewer than two training voltages: one voltage says
    nothing about a law's shape."""
    by = {r.name: r for r in dataset.recordings}
    volts = _voltages([by[n] for n in f.train])
    if len(volts) < 2 or f.lsq is None:
        return ()
    # at most LEVEL_VOLTAGES voltages (the lowest and highest among them) and
    # LEVEL_RECORDINGS recordings of each: the levels are starts, and 150 recordings at
    # 30 voltages would otherwise cost 25 runs each
    volts = [volts[i] for i in sorted({round(j) for j in np.linspace(0, len(volts) - 1, LEVEL_VOLTAGES)})]
    train, group = [], []        # the recordings scanned, and each one's voltage (index in volts)
    for n in f.train:
        r = by[n]
        v = min(range(len(volts)), key=lambda i: abs(r.condition()[0] - volts[i]))
        if abs(r.condition()[0] - volts[v]) <= CONDITION_V * volts[v] and group.count(v) < LEVEL_RECORDINGS:
            train.append(r)
            group.append(v)
    level = rho_at(f.params, ctx.E_ref)
    scale = ctx.E_ref / zipped_field(f.params, ctx.V_ref)
    grid = level * 10.0 ** np.linspace(-LEVEL_DECADES, LEVEL_DECADES, int(2 * LEVEL_DECADES * LEVEL_STEPS) + 1)
    grid = grid[(grid >= LEVEL_BOUNDS[0]) & (grid <= LEVEL_BOUNDS[1])]
    prob = Problem(train, Runner(executor), f.sigma, f.lsq["sigma_rep"], f.lsq["decimate"], False)
    tz = prob.flat_timing(f.timing)
    zeros = np.zeros(len(train))
    jobs = [j for L in grid for j in prob.jobs(scaled_resistivity(f.params, L / level), zeros, tz=tz)]
    runs = prob.runner(jobs)
    R = len(train)
    sse = np.full((len(grid), len(volts)), np.inf)
    for g in range(len(grid)):
        xs = runs[g * R:(g + 1) * R]
        if any(isinstance(x, str) for x in xs):
            continue
        res = prob.residuals(xs, zeros, tz)[:prob.n]
        per = np.add.reduceat(res * res, prob.offs[:-1])      # each recording's sum of squares
        sse[g] = np.bincount(group, per, minlength=len(volts))
    out = []
    for v in range(len(volts)):
        if not np.isfinite(sse[:, v]).any():
            continue
        out.append((zipped_field(f.params, volts[v]) * scale, float(grid[int(np.argmin(sse[:, v]))])))
    return tuple(sorted(out)) if len(out) >= 2 else ()


def _voltages(recs) -> list:
    """The recordings' hold voltages (their conditions' |V|), those within CONDITION_V of
    each other one voltage (conditions at one voltage and several loads share a level)."""
    out = []
    for V in sorted(r.condition()[0] for r in recs):
        if not out or V - out[-1] > CONDITION_V * out[-1]:
            out.append(V)
    return out
