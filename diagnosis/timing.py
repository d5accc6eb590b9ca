"""The drive's timing as a nuisance of every fit. A recording's drive is read off its
voltage record (recordings._interpret), to a fraction of a sample where a regular reset's
many switches lie on one grid - but a reset of a few switches is read switch by switch,
each within its sample, its generator runs on its own clock, not the data-acquisition
system's (0.1 % apart is common), which a few switches do not show, and the hold starts
when the generator's timer says. The zipping each switch starts moves at ~1 m/s: on the
lab rig's unipolar drive (2 Hz, 1 s reset: 3 switches and the hold's) the switches were
read up to 0.5 ms off, the model at the truth's own parameters missed a clean recording
by 5.3 um RMS (216 um at a switch), and the rounds named inertia on a null dataset.

Such a recording's timing (and a gridded reset's hold start) is fitted with the physics in
every fit (fit._solve), like its resistivity factor: the reset's `shift`, its generator's
`clock` and the hold's start `hold_shift` (recordings.retimed), with priors from how each
was read (nuisances()).
Fitted once on the baseline instead, it took up what a missing entry does right after a
switch (a mass's lag: inertia then left 11.9 um held out on a trial dataset against 4.3
with the timing as read; a series resistance's charging delay: R_s 8.2e5 for 1e6).

The drive's level is read off the same record, through the voltage monitor, whose gain is
a calibration (a high-voltage amplifier's monitor output or a divider is specified to
0.1-1 %). V^2 sets the force: the lab rig's 0.2 % per recording (issue 24) is 0.4 % of the
force: on a unipolar null (1.03 um noise as drawn) the baseline left 2.84 um held out,
1.36 um with the monitor exact. Each recording's gain (recordings.retimed: the drive is the
read levels over 1 + gain) is a nuisance of every fit too, but only as it differs between a
condition's repetitions (gains(): zero-sum contrasts per condition); fitted so, 1.67 um, as
with the drawn gains replaced by each condition's mean, and each gain within 0.01 % of its
drawn difference. What a condition's recordings share stays the physics': free in every
recording, even under a prior, the gains of a 3 N and a 7 N condition took up most of a
nominal t_lz 30 % off (held out 19.4 -> 3.2 um before any correction), and relative to a
condition's first recording (its mean still free) a stiffness proof named a polarization
branch."""
from __future__ import annotations

import math

import numpy as np

CLOCK_MIN_SWITCHES = 3   # a clock rate needs the reset's switches at three instants or more to show
GRID_PINNED = 20       # a reset put on a grid (recordings._regular_switches) by this many switches or more has its
#                        timing pinned (a line through n switches, each read within its sample, ends ~dt sqrt(1/3n)
#                        off: 0.04 ms for a 30 Hz reset of 3 s, 0.3 ms for a 4 Hz one of 1 s)
CLOCK_PRIOR = 1e-3     # prior SD of a drive's clock rate error (relative)
STEPS = {"shift": 5e-5, "clock": 1e-4, "hold_shift": 5e-5}   # difference steps (s, relative, s)
TIMING = tuple(STEPS)  # the nuisances that move the switches (the gain moves the levels)
GAIN_PRIOR = 5e-3      # prior SD of a voltage monitor's gain error (relative: a calibration's 0.5 %)
GAIN_HOLD = 2.0        # s of the drive's last level a recording needs for its gain to be a nuisance (gains())
GAIN_STEP = 2e-3       # difference step of a gain contrast (0.4-1.6 e-3 of a recording's level: above the
#                        integration's roughness at the fits' tolerance, well inside the prior)
BOUND = 5.0            # each nuisance within this many prior SDs


def nuisances(rec) -> dict:
    """The timing nuisances of a recording and their prior SDs. A drive whose reset was
    read switch by switch (too few switches for a grid) has the reset's shift and the
    hold's start (each read from one crossing: uniform within its sample, SD
    dt / sqrt(12)) and, with CLOCK_MIN_SWITCHES reset switches or more, its clock
    (CLOCK_PRIOR). A reset on a regular grid of GRID_PINNED switches or more has its timing
    pinned by them (a 30 Hz reset of 1 s: 0.04 ms and 1e-4; a grid of fewer has the
    nuisances of a reset read switch by switch), but not its hold's start: on the generator's
    own timer, it joins the wave's line within HOLD_ON_GRID samples or stands as read,
    either way only to within its sample - the hold's start alone is a nuisance there (a
    fresh trial's unipolar null: a 500 um spike at it, 5.94 -> 5.18 um held out with it
    fitted; fitted once on the baseline rather than in every fit, it had taken up part of a
    series resistance's charging delay). A single switch's timing is the recording's time
    shift (fit.align)."""
    n = 0 if rec.switches is None else len(rec.switches)
    if n < 2:
        return {}
    sd = rec.dt / math.sqrt(12.0)
    if rec.gridded and n - 1 >= GRID_PINNED:
        return {"hold_shift": sd}
    out = {"shift": sd}
    if n - 1 >= CLOCK_MIN_SWITCHES:
        out["clock"] = CLOCK_PRIOR
    out["hold_shift"] = sd
    return out


def gains(recs, common: bool = False) -> list:
    """The monitors' gain nuisances of recordings `recs`: for each condition with two or
    more recordings whose drive was read off their record, (their indices in recs, C) with
    C orthonormal contrasts (n x n-1, columns orthogonal to ones: Helmert's). The gains are
    C a: they sum to zero over the condition, and a ~ N(0, GAIN_PRIOR^2) i.i.d. is the
    per-recording prior restricted to that subspace. common: C is a whole orthonormal basis
    (n x n: the contrasts, then ones / sqrt(n)), the condition's common gain free too under
    the same per-recording prior (a condition of one recording included) - only where the
    physics is fixed (fit.heldout_common_gain): in a fit of the physics it takes up forces
    the model misses at that condition. Only recordings that hold their last
    level GAIN_HOLD s or more: under a polarity inversion throughout, with no rest before
    it, the fitted sensor zero takes up the static stroke a gain sets, the gain shows only in
    the switches' transients, and on the lab rig's nulls it wandered to 2-2.8 % (4-6 prior
    SDs) there, with no verdict better for it (the draws of record on the converged truth,
    2026-11-29)."""
    by = {}
    for j, r in enumerate(recs):
        if r.switches is not None and len(r.switches) and r.levels[-1] and r.duration - r.reset_end >= GAIN_HOLD:
            by.setdefault(r.condition(), []).append(j)
    if common:
        return [(js, np.column_stack([helmert(len(js)), np.full(len(js), 1.0 / math.sqrt(len(js)))]))
                for js in by.values()]
    return [(js, helmert(len(js))) for js in by.values() if len(js) >= 2]


def helmert(n: int) -> np.ndarray:
    """n x (n-1) orthonormal contrasts: column m is (1, ..., 1, -(m+1), 0, ...) / norm,
    m + 1 ones; the last column is nonzero in every row (fit._solve times every gain
    from a step along it)."""
    C = np.zeros((n, n - 1))
    for m in range(n - 1):
        C[:m + 1, m] = 1.0
        C[m + 1, m] = -(m + 1.0)
        C[:, m] /= math.sqrt((m + 1.0) * (m + 2.0))
    return C
