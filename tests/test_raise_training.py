"""A final model whose training error alone is unexplained, refitted at finer N while that
error falls (diagnosis.resolution._raise_training). Fits stubbed with the numbers of a
unipolar null on the lab_fine rig (trial seed 591484664, dataset 0): the baseline at
N = 81, 161 and 321 left 3.59, 2.57 and 2.27 um in training against 1.59 um noise, the
held-out condition 1.78, 1.70 and 1.81 um."""
from types import SimpleNamespace as NS

from dfa_model import preset
from diagnosis import resolution as rs
from diagnosis.improved import TRAINING, raised_phrases

SIGMA = 1.59e-6


def _fit(N, train, held=1.75e-6):
    return NS(params=preset("vshape-table1").replace(N=N), train_rmse=train, heldout_rmse=held, sigma=SIGMA)


def _run(monkeypatch, by_N, current, f0=None, refits=None):
    made = []

    def fake_fit(dataset, spec, base=None, **kw):
        made.append(base.N)
        assert kw["warm"].params.N == (base.N - 1) // 2 + 1
        return by_N[base.N]
    monkeypatch.setattr(rs, "fit", fake_fit)
    ds = NS(params=preset("vshape-table1").replace(N=81))
    out = rs._raise_training(ds, None, [], current, current if f0 is None else f0, None, None,
                             [] if refits is None else refits, lambda s: None)
    return out, made


def test_a_training_error_that_falls_with_N_takes_the_finer_model(monkeypatch):
    fits = {81: _fit(81, 3.59e-6, 1.78e-6), 161: _fit(161, 2.57e-6, 1.70e-6), 321: _fit(321, 2.27e-6, 1.81e-6)}
    (final, f0, steps), made = _run(monkeypatch, fits, fits[81])
    # at 161 the training error is within 2 noises (3.18 um): nothing left to raise for
    assert made == [161] and final is fits[161] and f0 is fits[161]
    assert steps == [{"N": 81, "error": 3.59e-6, "N_fine": 161, "error_fine": 2.57e-6, "after": TRAINING}]
    assert raised_phrases(steps) == ["N raised from 81 to 161 for the trained conditions: the final model's training "
                                     "error 3.59 -> 2.57 um (the model's own resolution, not missing physics)"]


def test_it_stops_where_the_error_falls_less_or_the_held_out_error_rises(monkeypatch):
    # falls 12 %, short of the 20 % a raise asks
    fits = {81: _fit(81, 4.2e-6), 161: _fit(161, 3.7e-6)}
    (final, f0, steps), made = _run(monkeypatch, fits, fits[81])
    assert made == [161] and final is fits[81] and steps == []
    # falls, but the held-out condition fits 20 % worse
    fits = {81: _fit(81, 4.2e-6, 1.7e-6), 161: _fit(161, 2.9e-6, 2.05e-6)}
    (final, _, steps), _ = _run(monkeypatch, fits, fits[81])
    assert final is fits[81] and steps == []


def test_it_runs_only_on_an_unexplained_training_error_and_reuses_refits(monkeypatch):
    # held-out error unexplained: not this step's business
    f = _fit(81, 4.0e-6, 4.0e-6)
    (final, _, steps), made = _run(monkeypatch, {}, f)
    assert final is f and made == [] and steps == []
    # within the noise: nothing to do
    f = _fit(81, 2.0e-6)
    assert _run(monkeypatch, {}, f)[0][0] is f
    # a kept model (not the baseline): the baseline stays; a refit made earlier is used, not made again
    f, g, base = _fit(81, 3.59e-6), _fit(161, 2.57e-6), _fit(81, 9e-6)
    (final, f0, steps), made = _run(monkeypatch, {}, f, f0=base, refits=[(f, g)])
    assert made == [] and final is g and f0 is base and len(steps) == 1
    # no further than 8x the nominal N (81 -> 641)
    fits = {N: _fit(N, 20e-6 * 0.7 ** i) for i, N in enumerate((81, 161, 321, 641, 1281))}
    (final, _, steps), made = _run(monkeypatch, fits, fits[81])
    assert made == [161, 321, 641] and final is fits[641]
