"""A recording's sensor zero (diagnosis.fit.align, sensor_offset) is a zero, not a stroke:
held within ZERO_MAX prior SDs. On a lab-rig dataset without a rest stretch (a branch under
unipolar pulses) the baseline's rho_l ran to where the actuator does not zip at all, and
each zero took up the whole stroke (+770 um against a 20 um prior), leaving 154 um: no
screen then saw the branch, and a spring was named at 58 noises. With the zero held the
branch was named at the truth's values (chi_p 0.0687 for 0.0689, tau_p 0.348 s for 0.347)."""
from __future__ import annotations

import numpy as np

from diagnosis.fit import OFFSET_PRIOR, ZERO_MAX, align, sensor_offset


def _plateau(n=5000, level=800e-6, zero=12e-6, noise=2e-6, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    stroke = level * (1.0 - np.exp(-t / 0.05)) + zero + rng.normal(0.0, noise, n)
    return t, stroke


def test_a_zero_that_would_take_up_the_stroke_is_held_at_its_cap():
    t, stroke = _plateau()
    still = np.zeros((2, t.size))                  # a model that does not zip: stroke and rate 0
    # no rest stretch in the model's run (every sample 'at rest' only if x <= 0; here all are):
    # the with-rest path reads the zero at rest, i.e. over the whole run
    off = sensor_offset(stroke, still[0], 2e-6)
    assert off == ZERO_MAX * OFFSET_PRIOR
    # the no-rest path (fitted over the whole run with the timing): a model that moves a little
    # (so that fewer than REST_MIN samples rest) and does not follow the plateau
    barely = np.vstack([np.full(t.size, 1e-9), np.zeros(t.size)])
    x, off, tau = align(stroke, barely, 2e-6)
    assert off == ZERO_MAX * OFFSET_PRIOR and tau == 0.0
    assert np.sqrt(np.mean((stroke - x) ** 2)) > 500e-6      # the mismatch stays in the residual


def test_a_zero_within_its_prior_is_fitted_as_before():
    t, stroke = _plateau()
    model = 800e-6 * (1.0 - np.exp(-t / 0.05))
    run = np.vstack([model, np.gradient(model, t)])
    x, off, tau = align(stroke, run, 2e-6)
    assert abs(off - 12e-6) < 0.5e-6 and abs(off) < ZERO_MAX * OFFSET_PRIOR
    assert np.sqrt(np.mean((stroke - x) ** 2)) < 2.2e-6
