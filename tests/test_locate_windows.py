"""locate's signatures on short windows: under polarity inversion the "after reset" window
can be 0.2 s or shorter, with nothing after its first 0.2 s to compare with - numpy warned
"Mean of empty slice" and "invalid value encountered in scalar divide", which `dfa
diagnose` printed as warnings to the user."""
import warnings

import numpy as np

from diagnosis.locate import _signature


def test_a_short_after_reset_window_is_described_without_warnings():
    t = np.arange(0.0, 0.15, 1e-3)
    r = 2e-6 * np.ones_like(t)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sig = _signature("after reset", None, t, r, 1e-6)
    assert "fast drop" not in sig and "um" in sig       # described by the window's trend


def test_a_fast_drop_after_the_reset_is_still_told():
    t = np.arange(0.0, 1.0, 1e-3)
    r = np.where(t < 0.2, -10e-6, -1e-6)
    assert "fast drop right after the charge reset" in _signature("after reset", None, t, r, 1e-6)
