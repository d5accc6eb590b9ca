"""Error norms keep a NaN: a step whose error has one NaN component must not pass.

max() compares with >, so max(err, nan) is err: the full model's scaled norm and the
surrogate's stage errors came out finite over a state with a NaN in it, and the
integrators' `isfinite` checks on them never fired.
"""
import math

import numpy as np

from dfa_model.numerics.integrator import _wnorm
from dfa_model.numerics.stepping import worst


def test_worst_keeps_nan_in_either_place_and_is_max_otherwise():
    nan = float("nan")
    assert math.isnan(worst(1.0, nan))
    assert math.isnan(worst(nan, 1.0))
    assert math.isnan(worst(worst(0.0, nan), 2.0))    # and stays NaN down a loop
    assert worst(1.0, 2.0) == 2.0
    assert worst(2.0, 1.0) == 2.0


def test_full_models_norm_is_nan_when_one_component_is():
    v = np.array([1e-3, np.nan, 5e-4])
    y = np.ones(3)
    assert math.isnan(_wnorm(v, y, y, np.ones(3), 1e-3, 0))
    # the finite case unchanged: the largest scaled component
    v = np.array([1e-3, 2e-3, 5e-4])
    assert _wnorm(v, y, y, np.ones(3), 1e-3, 0) == 2e-3 / (1e-3 * 2.0)
