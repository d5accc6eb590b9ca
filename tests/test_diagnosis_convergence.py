"""The kept entries' values followed over doublings of N (diagnosis/convergence.py). Fits
stubbed with the numbers of a polarization branch under 1 Hz inversion on the lab_fine rig
(truth chi_p 0.125, tau_p 0.186 s at 651 points): fitted at N = 21, 41, 81, 161 it gave
chi_p 0.058, 0.078, 0.096, 0.113 while the held-out error hardly moved."""
from types import SimpleNamespace as NS

import pytest

from dfa_model import preset
from diagnosis import convergence as cv
from diagnosis.catalog import PHYSICS

BRANCH = next(e for e in PHYSICS if e.key == "polarization_branch")


def _fit(N, chi_p, tau_p, train=2.3e-6, held=2.4e-6, se=2e-4):
    p = preset("vshape-table1").replace(N=N, chi_p=chi_p, tau_p=tau_p)
    return NS(params=p, values={"chi_p": chi_p, "tau_p": tau_p}, stderr={"chi_p": se, "tau_p": se},
              train_rmse=train, heldout_rmse=held)


def _run(monkeypatch, by_N, nominal_N=21):
    """value_check from the fit at nominal_N, the refits drawn from by_N {N: fit}; returns
    (final, record, the N refitted in order)."""
    made = []

    def fake_fit(dataset, spec, base=None, **kw):
        made.append(base.N)
        assert kw["warm"].params.N == fine_N_of(base.N)     # warm from the fit one doubling coarser
        return by_N[base.N]

    def fine_N_of(N):
        return (N - 1) // 2 + 1

    monkeypatch.setattr(cv, "fit", fake_fit)
    ds = NS(params=preset("vshape-table1").replace(N=nominal_N))
    final, rec = cv.value_check(ds, None, [BRANCH], by_N[nominal_N], [], None, None, lambda s: None)
    return final, rec, made


def test_values_that_move_with_N_are_followed_and_the_finest_refit_is_the_final_model(monkeypatch):
    fits = {21: _fit(21, 0.058, 0.154, 2.35e-6), 41: _fit(41, 0.078, 0.159, 2.27e-6),
            81: _fit(81, 0.096, 0.168, 2.11e-6), 161: _fit(161, 0.113, 0.180, 1.68e-6)}
    final, rec, made = _run(monkeypatch, fits)
    assert made == [41, 81, 161]                    # 321 is past 8x the nominal N
    assert final is fits[161] and rec["N_final"] == 161
    assert not rec["converged"] and "past" in rec["stopped"]
    assert [s["values"]["chi_p"] for s in rec["steps"]] == [0.058, 0.078, 0.096, 0.113]
    assert rec["changes"]["chi_p"] == pytest.approx(1 - 0.096 / 0.113)


def test_values_that_settle_at_the_first_doubling_leave_the_final_model_as_it_was(monkeypatch):
    fits = {21: _fit(21, 0.100, 0.30), 41: _fit(41, 0.104, 0.31, 2.2e-6)}
    final, rec, made = _run(monkeypatch, fits)
    assert made == [41] and final is fits[21]
    assert rec["converged"] and rec["stopped"] is None and rec["N_final"] == 21


def test_a_value_the_data_hardly_fix_does_not_count_as_moving(monkeypatch):
    """40 % apart but within 3 standard errors: a refit's scatter, not resolution."""
    fits = {21: _fit(21, 0.05, 0.30, se=0.03), 41: _fit(41, 0.07, 0.31, se=0.03)}
    final, rec, made = _run(monkeypatch, fits)
    assert made == [41] and rec["converged"] and final is fits[21]


def test_a_finer_refit_that_fits_the_training_data_worse_is_not_taken(monkeypatch):
    """The values moved, but the refit at the finer N did not get as far (its training
    error 10 % up): the coarser model stays final, and the record says why it stopped."""
    fits = {21: _fit(21, 0.058, 0.154, 2.35e-6), 41: _fit(41, 0.078, 0.159, 2.6e-6)}
    final, rec, made = _run(monkeypatch, fits)
    assert made == [41] and final is fits[21]
    assert not rec["converged"] and "worse" in rec["stopped"] and rec["finer_worse"]
    from diagnosis.report import values_phrase
    text = values_phrase(NS(values_in_N=rec))
    assert "do not ask" in text and "N = 21 (values_in_N)" in text and "may move them further" not in text


def test_nothing_physical_kept_is_not_followed(monkeypatch):
    monkeypatch.setattr(cv, "fit", lambda *a, **k: pytest.fail("no refit expected"))
    f = _fit(21, 0.0, 0.1)
    nominal = NS(kind="nominal", key="nominal:t_lz", shows=(), spec=lambda p, ctx: [])
    assert cv.value_check(NS(params=f.params), None, [nominal], f, [], None, None, print) == (f, None)


def test_the_conclusion_says_when_the_values_had_not_settled(monkeypatch):
    from diagnosis.report import values_phrase
    fits = {21: _fit(21, 0.058, 0.154, 2.35e-6), 41: _fit(41, 0.078, 0.159, 2.27e-6),
            81: _fit(81, 0.096, 0.168, 2.11e-6), 161: _fit(161, 0.113, 0.180, 1.68e-6)}
    _, rec, _ = _run(monkeypatch, fits)
    text = values_phrase(NS(values_in_N=rec))
    assert "had not settled" in text and "chi_p 0.058, 0.078, 0.096, 0.113" in text and "N = 161" in text
    fits = {21: _fit(21, 0.100, 0.30), 41: _fit(41, 0.104, 0.31, 2.2e-6)}
    _, rec, _ = _run(monkeypatch, fits)
    assert values_phrase(NS(values_in_N=rec)) is None      # settled at once: nothing to say
