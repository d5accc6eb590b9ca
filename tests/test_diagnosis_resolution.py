"""The diagnosis rules out its own discretization before naming missing physics
(diagnosis.diagnose._resolution_check). Data from the paper's model at N = 81, fitted at
N = 21 with 0.5 um noise: the coarse model's error against the finer truth is 5x the
noise, and a stiffness takes up some of it - but its gain falls from 12 % to 1 % when the
elements double, so it is not named. (A polarization branch took up half of it until the
branch was rebuilt between its points as P (u + chi_p T0) linear: its own discretization
error near the front had made it the absorber. It is no longer kept on these data.)
Small and in this process (~10 s)."""
from __future__ import annotations

import importlib
import json
from functools import partial

import pytest

import diagnosis
from dfa_model.io import parameters
from dfa_model import preset
from dfa_model.io.recordings import read_dataset
from dfa_model.io.synthetic import Measurement, generate_dataset
from diagnosis.fit import InProcess
from diagnosis_parts import dg, patch


def _stubbed_fit(err, bic, N, sigma=1e-6, converged=True):
    """A stand-in FitResult: its held-out and training error, BIC, noise and N (and
    whether its search met its tolerances)."""
    from types import SimpleNamespace as NS
    return NS(heldout_rmse=err, train_rmse=err, bic=bic, sigma=sigma, params=preset("vshape-table1").replace(N=N),
              converged=converged, spec=[])


def _stub_point(monkeypatch, dg, err, bic, sigma=1e-6):
    """The kept model's values evaluated at the finer N (fit.evaluate, _KeptFine) stubbed:
    that point's error and BIC; returns the list of the N it was evaluated at."""
    calls = []

    def point(dataset, fr, params, executor=None):
        calls.append(params.N)
        return _stubbed_fit(err, bic, params.N, sigma)
    patch(monkeypatch, "evaluate", point)
    return calls


def _stubbed_diagnose(monkeypatch, without=None):
    """diagnosis.diagnose with the baseline's free parameters stubbed empty and, given
    `without`, _without (the kept model without an entry) stubbed by it."""
    patch(monkeypatch, "baseline_spec", lambda p, ctx: [])
    if without is not None:
        patch(monkeypatch, "_without", without)
    return dg


def _same_base(drop, kept, fitted, base, ctx):
    """A _without stub: the base as it is, no free parameters."""
    return base, []


def _entry(key, kind="physics"):
    """A stand-in catalog entry without free parameters."""
    from types import SimpleNamespace as NS
    return NS(kind=kind, key=key, spec=lambda p, ctx: [])


def _one_doubling():
    """diagnosis.diagnose.RAISE_MAX = 1 while in the context: no leap of two doublings
    after a kept entry (_leap), so a test reaches the resolution check's own rules with
    what the rounds kept at N = 21."""
    mp = pytest.MonkeyPatch()
    patch(mp, "RAISE_MAX", 1)
    return mp


def _coarse_data(folder):
    nominal = preset("vshape-table1").replace(N=21, rho_l=3e12)
    generate_dataset(folder / "data", nominal.replace(N=81, rho_l=2e12), nominal,
                     [(5000.0, 5.0), (6000.0, 5.0), (7000.0, 5.0)], repetitions=2, reset=0.5, hold=5.0, seed=3,
                     measurement=Measurement(noise=0.5e-6, quantum=0.1e-6))
    return read_dataset(folder / "data")


@pytest.fixture(scope="module")
def coarse(tmp_path_factory):
    folder = tmp_path_factory.mktemp("resolution")
    forms = [e for e in diagnosis.PHYSICS if e.name == "stiffness"]
    D = diagnosis.diagnose(_coarse_data(folder), executor=InProcess(), candidates=forms)
    return D, diagnosis.write_report(D, folder / "out"), folder / "out"


def _inertia_data(folder):
    """Inertia (m = 0.05 kg) in data from the model at N = 81, nominal N = 21, 0.5 um noise."""
    nominal = preset("vshape-table1").replace(N=21, rho_l=3e12)
    generate_dataset(folder / "data", nominal.replace(N=81, rho_l=2e12, m=0.05), nominal,
                     [(5000.0, 5.0), (6000.0, 5.0), (7000.0, 5.0)], repetitions=2, reset=0.5, hold=5.0, seed=3,
                     measurement=Measurement(noise=0.5e-6, quantum=0.1e-6))
    return read_dataset(folder / "data")


def test_a_kept_model_leaps_two_doublings_when_one_cuts_too_little(tmp_path):
    """_leap on real fits: inertia kept at N = 21 left 2.80 um held out against 0.52 um
    noise, 2.41 um at N = 41 (a cut of 14 %: short of the 20 % one doubling must make,
    more than the 10 % of LEAP_CUT) and 0.52 um at 81. Two doublings at once: inertia alone
    is named at the noise (with one doubling a stiffness was kept beside it for the coarse
    model's error, and dropped by the last entry's check: the test below)."""
    forms = [e for e in diagnosis.PHYSICS if e.name in ("inertia", "stiffness")]
    D = diagnosis.diagnose(_inertia_data(tmp_path), executor=InProcess(), candidates=forms)
    assert [(s["N"], s["N_fine"], s["after"]) for s in D.raised] == [(21, 41, "inertia"), (41, 81, "inertia")]
    assert D.raised[0]["error_fine"] > 0.8 * D.raised[0]["error"]             # one doubling cut too little
    assert not any(s.get("dropped") for s in D.raised)
    assert [e.key for e in D.chain] == ["inertia"] and D.final.params.N >= 81
    assert D.final.heldout_rmse < 1.1 * D.final.sigma and abs(D.final.params.m / 0.05 - 1) < 0.02


def test_an_entry_that_only_absorbs_resolution_error_is_not_named(coarse):
    D, report, out = coarse
    r = report["resolution"]
    assert [e.key for e in D.chain] == ["stiffness"]        # the rounds kept it at N = 21
    assert r["resolution_only"] and r["dropped"] == ["stiffness"], r
    assert r["gain"] > 0.08 and r["gain_fine"] < 0.25 * r["gain"]
    assert report["missing_physics"] == [] and "only took up the model's discretization error" in \
        report["conclusion"]
    # the check's outcome is the baseline at the finer N; that baseline, 12.9 noises off its
    # own solution (the data are the model's at N = 81), is refitted where it is within the
    # noise of itself (diagnose._again, no physics kept) and fits better there
    a = report["diagnosed_again"]
    assert a["first"]["N_final"] == 41 and a["check"]["refit"] and a["taken"]
    assert a["second"]["heldout_rmse"] < 0.6 * a["first"]["heldout_rmse"]
    assert D.final.params.N == a["N_again"] > 41 and report["fit"]["improved"] is not None
    assert parameters.load(out / "improved.toml").N == a["N_again"]
    text = (out / "improved.toml").read_text()
    assert "N raised from 21 to 41" in text and "the final model (the baseline at N = 41)" in text
    assert json.loads((out / "report.json").read_text())["resolution"]["N_fine"] == 41



def test_physics_that_holds_is_refitted_where_the_model_resolves_the_data(monkeypatch):
    """Physics that keeps its gain at twice the elements and fits better there is the final
    model at that N (record 'refined'): the coarse model's own discretization error is not
    left to read as unexplained mismatch. On the lab rig (truth at 4x N, an exponential law
    outside the catalog's forms) the N = 21 fit left 5.23 um held out against 2.1 um noise
    ('unexplained mismatch'); its refit at N = 41 left 3.0 um. The rule, with the fits
    stubbed: refined when the finer kept fit is better; kept at N when it is not."""
    dg = _stubbed_diagnose(monkeypatch)

    res = _stubbed_fit

    entry = _entry("field_dependent_resistivity (spline)")
    base = preset("vshape-table1").replace(N=21)
    f0, current = res(9.3e-6, 0.0, 21), res(5.2e-6, -900.0, 21)
    # (finer baseline, finer kept): both hold the physics' gain; only the first fits better at N = 41.
    # The check passes on the kept fit's values evaluated at N = 41; the kept model, 5.2 noises
    # from the data, is still refitted there: it may be the final model
    for fine_base, fine_kept, refined in ((5.7e-6, 3.0e-6, True), (8.0e-6, 5.5e-6, False)):
        points = _stub_point(monkeypatch, dg, 1.05 * fine_kept, -1350.0)
        fits = iter([res(fine_base, -400.0, 41), res(fine_kept, -1400.0, 41)])
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        kept, final, rec = dg._resolution_check(None, base, None, [entry], current, f0, None, None, lambda s: None)
        assert kept == [entry] and not rec["resolution_only"], rec
        assert bool(rec.get("refined")) is refined and points == [41] and rec["kept_fine"] == "refitted"
        assert final.params.N == (41 if refined else 21) and final.heldout_rmse == min(fine_kept, 5.2e-6)
        assert rec["kept_fine_rmse"] == fine_kept
    # the kept model's refit that _raise_kept made and did not take is not made again, nor
    # evaluated; one of another fit (an entry kept since) is not used
    points = _stub_point(monkeypatch, dg, 3.2e-6, -1350.0)
    fits = iter([res(5.7e-6, -400.0, 41)])
    patch(monkeypatch, "fit", lambda *a, **k: next(fits))
    kept, final, rec = dg._resolution_check(None, base, None, [entry], current, f0, None, None, lambda s: None,
                                            refits=[(current, res(3.0e-6, -1400.0, 41))])
    assert rec["kept_fine_rmse"] == 3.0e-6 and final.heldout_rmse == 3.0e-6 and points == []
    fits = iter([res(5.7e-6, -400.0, 41), res(3.1e-6, -1400.0, 41)])
    kept, final, rec = dg._resolution_check(None, base, None, [entry], current, f0, None, None, lambda s: None,
                                            refits=[(res(5.2e-6, -900.0, 21), res(3.0e-6, -1400.0, 41))])
    assert rec["kept_fine_rmse"] == 3.1e-6 and points == [41]
    # a kept model at the noise (within 1.11 noises: nothing could cut its error by 10 %) that
    # passes on its evaluated values is not refitted: the final model stays at N
    at_noise = res(1.05e-6, -900.0, 21)
    points = _stub_point(monkeypatch, dg, 1.1e-6, -1350.0)
    fits = iter([res(5.7e-6, -400.0, 41)])
    kept, final, rec = dg._resolution_check(None, base, None, [entry], at_noise, f0, None, None, lambda s: None)
    assert kept == [entry] and final is at_noise and points == [41] and not rec.get("refined")
    assert rec["kept_fine"].startswith("evaluated") and rec["kept_fine_rmse"] == 1.1e-6
    # ... but a point that does not pass is not the verdict: the refit decides (here it passes)
    points = _stub_point(monkeypatch, dg, 5.6e-6, -420.0)
    fits = iter([res(5.7e-6, -400.0, 41), res(1.02e-6, -1400.0, 41)])
    kept, final, rec = dg._resolution_check(None, base, None, [entry], at_noise, f0, None, None, lambda s: None)
    assert kept == [entry] and not rec["resolution_only"] and rec["kept_fine"] == "refitted"
    assert rec["kept_fine_rmse"] == 1.02e-6 and final.heldout_rmse == 1.02e-6 and rec["refined"]
    # and one whose refit fails as well is dropped as resolution error
    points = _stub_point(monkeypatch, dg, 5.6e-6, -420.0)
    fits = iter([res(5.7e-6, -400.0, 41), res(5.4e-6, -405.0, 41)])
    kept, final, rec = dg._resolution_check(None, base, None, [entry], at_noise, f0, None, None, lambda s: None)
    assert kept == [] and rec["resolution_only"] and final.heldout_rmse == 5.7e-6


def test_a_truth_law_outside_the_parameter_file(tmp_path):
    """synthetic.generate_dataset(law=): the truth runs a law the parameter file cannot
    express (the diagnosis's held-out truths), named in the manifest; the recording
    differs from the constant law's."""
    from dfa_model.io.synthetic import ExponentialResistivity
    from diagnosis.catalog import zipped_field
    p = preset("vshape-table1").replace(N=21, rho_l=2e12)
    E6 = zipped_field(p, 6000.0)
    law = ExponentialResistivity(2e12 * 2.718281828 ** (E6 / 2.5e7), 2.5e7)
    assert abs(law.rho(E6) / 2e12 - 1) < 1e-6
    m = Measurement(noise=0.0, quantum=0.0, offset=0.0, rho_spread=0.0, voltage_noise=0.0, clock=0.0)
    runs = {}
    for name, lw in (("exp", law), ("const", None)):
        made = generate_dataset(tmp_path / name, p, conditions=[(7000.0, 5.0)], repetitions=1, reset=0.2, hold=2.0,
                                measurement=m, seed=1, law=lw)
        runs[name] = read_dataset(tmp_path / name).recordings[0].stroke
        assert (made["truth_law"] or "").startswith("ExponentialResistivity" if lw else "")
    # above E6 the exponential law is below 2e12: the interface charges faster, the stroke falls away sooner
    assert abs(runs["exp"][-1] - runs["const"][-1]) > 5e-6


def test_resolution_first_raises_N_while_the_finer_baseline_fits_better(monkeypatch):
    """Before any selection, N is raised while the baseline leaves more than RAISE_FLOOR
    noises and the finer baseline cuts its error below RAISE_GAIN (at most RAISE_MAX
    doublings): on the lab rig (truth at 4x N) a coarse N = 21 model's own error, 11 um
    against 1.5 um noise, was taken up by a spline law that was then named on a null
    dataset. Fits stubbed: the rule's three stops."""
    from types import SimpleNamespace as NS
    dg = _stubbed_diagnose(monkeypatch)

    def res(err, N):
        return NS(heldout_rmse=err, train_rmse=err, sigma=1e-6, params=preset("vshape-table1").replace(N=N))

    base = preset("vshape-table1").replace(N=21)
    cases = [  # (errors of the successive finer baselines, expected final N)
        ([5e-6, 3e-6], 81),            # two doublings, each better by > 20 %
        ([9.5e-6], 21),                # the finer fits no better: N stays
        ([1.2e-6], 41),                # one doubling reaches the noise floor: stop there
    ]
    for errs, N_end in cases:
        fits = iter([res(e, 21) for e in errs])
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        b, f, steps, _ = dg._resolve(None, base, None, res(11e-6, 21), None, None, lambda s: None)
        assert b.N == N_end and len(steps) == {21: 0, 41: 1, 81: 2}[N_end]
        assert [s["N_fine"] for s in steps] == [41, 81][:len(steps)]


def test_each_kept_entry_must_hold_on_its_own_when_the_elements_double(tmp_path):
    """Inertia in data from N = 81, fitted at N = 21 with 0.5 um noise: the rounds keep
    inertia, then a stiffness beside it that takes up some of what is left - the coarse
    model's discretization error. The set passes the resolution check (inertia's gain
    holds), so the last entry is refitted without it: the stiffness's own gain falls from
    11 % at N = 21 to 1 % at N = 41, and it is dropped (lab-rig trial: a field law was named
    beside inertia this way in 3 of 3 inertia datasets; a polarization branch was, on these
    data, until its own discretization error near the front was removed)."""
    forms = [e for e in diagnosis.PHYSICS if e.name in ("inertia", "stiffness")]
    mp = _one_doubling()        # with two, inertia's kept model leaps to N = 81 and no branch is kept (test above)
    # the rule under test is the first check's: its final model (inertia at N = 41, 2.41 um held
    # out, 4.6 noises) is 13 noises off its own solution, and the check again at N = 161
    # (diagnose._again) takes inertia there: m 0.04998 for 0.05, 0.92 um held out
    mp.setattr(importlib.import_module("diagnosis.diagnose"), "_again", lambda dataset, D, *a: D)
    try:
        D = diagnosis.diagnose(_inertia_data(tmp_path), executor=InProcess(), candidates=forms)
    finally:
        mp.undo()
    report = diagnosis.write_report(D, tmp_path / "out")
    assert [e.key for e in D.chain] == ["inertia", "stiffness"]
    assert [m["name"] for m in report["missing_physics"]] == ["inertia"]
    r = report["resolution"]
    (spring,) = [m for m in r["marginal"] if m["entry"] == "stiffness"]
    assert spring["dropped"] and spring["gain"] > 0.08 and spring["gain_fine"] < 0.25 * spring["gain"]
    assert r["dropped_marginal"] == ["stiffness"] and not r["resolution_only"]
    assert D.final.params.N == 41 and D.final.params.m > 0 and D.final.params.k == D.dataset.params.k
    assert "stiffness dropped" in report["conclusion"] and "inertia" in report["conclusion"]


def test_resolution_first_after_each_kept_entry(monkeypatch):
    """Resolution first runs again after each kept entry (_raise_kept): while the kept model
    leaves more than RAISE_FLOOR noises and its refit at twice the elements cuts that below
    RAISE_GAIN, the next rounds run at the finer N, with the baseline (and the fit the last
    entry was added to) refitted there so the later checks compare models at one N. On the
    lab rig inertia fitted at N = 21, 41 and 81 left 10.7, 4.5 and 2.0 um against 1.7 um
    noise while the baseline fitted no better at the finer N; a field law had been named
    beside it. Fits stubbed: the rule's stops, the budget and the references refitted."""
    from types import SimpleNamespace as NS
    dg = _stubbed_diagnose(monkeypatch)
    entry, other = _entry("inertia"), _entry("series_resistance")

    def res(err, N):     # a BIC that falls with the error
        return NS(heldout_rmse=err, train_rmse=err, bic=1e12 * err, sigma=1e-6,
                  params=preset("vshape-table1").replace(N=N))

    base = preset("vshape-table1").replace(N=21)
    f0 = res(20e-6, 21)

    def run(errs, kept, before, budget):
        calls = []
        fits = iter(errs)

        def fake(dataset, spec, base, **kw):
            calls.append(base.N)
            return res(next(fits), base.N)
        patch(monkeypatch, "fit", fake)
        return dg._raise_kept(None, base, None, kept, res(10.7e-6, 21), f0, before, None, None, lambda s: None,
                              budget), calls

    # two doublings: (kept, baseline) refitted at 41, then at 81
    (b, f, _, cur, bef, steps, tried), calls = run([4.5e-6, 19e-6, 2.0e-6, 18e-6], [entry], f0, 2)
    assert b.N == 81 and cur.params.N == 81 and f.params.N == 81 and calls == [41, 41, 81, 81]
    assert bef is f            # the last entry was added to the baseline: its refit is the new reference
    assert tried is None       # every refit was taken
    assert [(s["N"], s["N_fine"], s["after"]) for s in steps] == [(21, 41, "inertia"), (41, 81, "inertia")]
    # the budget left by resolution first before the selection bounds it
    (b, *_, steps, _), calls = run([4.5e-6, 19e-6], [entry], f0, 1)
    assert b.N == 41 and len(steps) == 1 and calls == [41, 41]
    assert run([], [entry], f0, 0)[1] == []
    # the finer kept model fits no better (above RAISE_GAIN of the error), nor at twice those
    # elements (_leap: above RAISE_GAIN^2): N stays, handed on with the refit at one doubling
    # (the resolution check would make the same refit)
    (b, f, _, cur, bef, steps, tried), calls = run([9.5e-6, 8e-6], [entry], f0, 2)
    assert b.N == 21 and f is f0 and steps == [] and calls == [41, 81]
    assert tried[0] is cur and tried[1].params.N == 41 and tried[1].heldout_rmse == 9.5e-6
    # ... with one doubling left, no leap; nor when one doubling cut under LEAP_CUT (10.5 of 10.7 um)
    (b, f, _, cur, bef, steps, tried), calls = run([9.5e-6], [entry], f0, 1)
    assert b.N == 21 and steps == [] and calls == [41]
    (b, f, _, cur, bef, steps, tried), calls = run([10.5e-6], [entry], f0, 2)
    assert b.N == 21 and steps == [] and calls == [41]
    # a leap: a stiffness on a Peano-HASEL pouch (truth at 651 points) left 4.41, 3.68 and 1.91 um
    # at N = 21, 41 and 81 against 1.68 um noise; the kept model at the finer N is the leap's, the
    # baseline refitted there, and two steps are told (they use up the budget)
    (b, f, _, cur, bef, steps, tried), calls = run([9.0e-6, 4.0e-6, 18e-6], [entry], f0, 2)
    assert b.N == 81 and cur.params.N == 81 and cur.heldout_rmse == 4.0e-6 and f.params.N == 81
    assert calls == [41, 81, 81] and tried is None and bef is f
    assert [(s["N"], s["N_fine"], s["error_fine"]) for s in steps] == [(21, 41, 9.0e-6), (41, 81, 4.0e-6)]
    # a second entry: the fit it was added to is refitted at the finer N as well
    before = res(12e-6, 21)
    (b, f, kept, cur, bef, steps, _), calls = run([4.5e-6, 19e-6, 6e-6], [other, entry], before, 1)
    assert calls == [41, 41, 41] and bef.params.N == 41 and bef.heldout_rmse == 6e-6 and kept == [other, entry]
    # ... and when the last entry's gain does not hold there (4.6 against 5 um: short of acceptance)
    # it is dropped: the model without it is the kept model at the finer N
    (b, f, kept, cur, bef, steps, _), calls = run([4.5e-6, 19e-6, 5e-6], [other, entry], before, 2)
    assert kept == [other] and cur.heldout_rmse == 5e-6 and cur.params.N == 41 and bef is None
    assert b.N == 41 and f.params.N == 41 and steps[-1]["dropped"] == "inertia" and calls == [41, 41, 41]
    # a kept model under UNEXPLAINED noises is not leapt for
    made = []
    patch(monkeypatch, "fit", lambda dataset, spec, base, **kw: made.append(base.N) or res(1.8e-6, base.N))
    assert dg._raise_kept(None, base, None, [entry], res(1.9e-6, 21), f0, f0, None, None, lambda s: None,
                          2)[5] == [] and made == [41]
    # within RAISE_FLOOR noises nothing is tried
    patch(monkeypatch, "fit", lambda *a, **k: pytest.fail("no refit expected"))
    assert dg._raise_kept(None, base, None, [entry], res(1.4e-6, 21), f0, f0, None, None, lambda s: None,
                          2)[5] == []


def test_the_last_entry_is_checked_when_the_finer_baseline_fits_no_better(monkeypatch):
    """When the baseline fits no better at twice the elements (a large missing effect
    dominates its misfit) the set stands as a whole, but the last of two physics entries
    is still refitted without it there (which needs no finer baseline): on the lab rig a
    field law kept beside a polarization branch cut the error by 23 % at N = 41 and by 1 %
    at N = 81, and is dropped. Fits stubbed."""
    dg = _stubbed_diagnose(monkeypatch, _same_base)
    branch, law = _entry("polarization_branch"), _entry("field_dependent_resistivity (Eq. 21)")

    res = partial(_stubbed_fit, sigma=1.26e-6)

    base = preset("vshape-table1").replace(N=41)
    f0, before, current = res(6.21e-6, 0.0, 41), res(1.87e-6, -9000.0, 41), res(1.44e-6, -15000.0, 41)
    for without, dropped in ((1.41e-6, True), (1.90e-6, False)):
        # finer baseline (worse: inconclusive), finer kept model without the law; its values at
        # N = 81 pass against that when the law holds, and the kept model is not refitted; when
        # they do not, its refit decides; then (the law kept) without the branch, which holds
        # (_earlier_entries_check)
        points = _stub_point(monkeypatch, dg, 1.45e-6, -15500.0, 1.26e-6)
        fits = iter([res(7.32e-6, 0.0, 81), res(without, -15990.0 if dropped else -9000.0, 81)]
                    + ([res(1.40e-6, -16000.0, 81)] if dropped else [res(5.0e-6, -3000.0, 81)]))
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        kept, final, rec = dg._resolution_check(None, base, None, [branch, law], current, f0, None, None,
                                                lambda s: None, before=before)
        assert "inconclusive" in rec and points == [81] and next(fits, None) is None
        assert [m["entry"] for m in rec["marginal"]] == [law.key] + ([] if dropped else [branch.key])
        if dropped:
            assert kept == [branch] and rec["dropped_marginal"] == [law.key] and final.params.N == 81
            assert rec["marginal"][0]["gain_fine"] == pytest.approx(1 - 1.40 / 1.41)    # decided on the refit
        else:
            assert kept == [branch, law] and final is current and rec["dropped_marginal"] == []
    # the model without the last entry at the finer N is the refit _raise_kept made of the fit it
    # was added to, when there is one: not fitted again
    points = _stub_point(monkeypatch, dg, 1.45e-6, -15500.0, 1.26e-6)
    fits = iter([res(7.32e-6, 0.0, 81), res(5.0e-6, -3000.0, 81)])
    patch(monkeypatch, "fit", lambda *a, **k: next(fits))
    kept, final, rec = dg._resolution_check(None, base, None, [branch, law], current, f0, None, None,
                                            lambda s: None, before=before,
                                            refits=[(before, res(1.90e-6, -9000.0, 81))])
    assert kept == [branch, law] and rec["marginal"][0]["rmse_without"] == 1.90e-6 and next(fits, None) is None
    # a single physics entry: nothing more is fitted once the premise fails
    fits = iter([res(7.32e-6, 0.0, 81)])
    patch(monkeypatch, "fit", lambda *a, **k: next(fits))
    kept, final, rec = dg._resolution_check(None, base, None, [branch], before, f0, None, None, lambda s: None,
                                            before=f0)
    assert kept == [branch] and final is before and "marginal" not in rec


def test_the_last_entry_stands_where_the_kept_model_fits_worse_at_the_finer_N(monkeypatch):
    """The check at twice the elements assumes the finer model nearer the data. On the
    ideal rig (data made at the fit's own N = 21) a series resistance + branch kept at
    1.71 um held out fitted 3.76 um at N = 41, where the resistance alone left 4.41 um: a
    gain of 41 % at N = 21 and 15 % at 41 - the branch, real, would have been dropped. The
    kept model itself fitting clearly worse at the finer N (RES_WORSE), that N cannot judge
    the entry: it stands (record 'premise'). Where the kept model fits better there, or
    about as well, the rule is as before: the entry that only took up resolution error is
    dropped. Fits stubbed."""
    dg = _stubbed_diagnose(monkeypatch, _same_base)
    rs, branch = _entry("series_resistance"), _entry("polarization_branch")
    res = partial(_stubbed_fit, sigma=1.0e-6)
    base = preset("vshape-table1").replace(N=21)
    f0, before, current = res(29.6e-6, 0.0, 21), res(2.88e-6, -70000.0, 21), res(1.71e-6, -72000.0, 21)
    # the third: the kept model at the finer N only a hair worse (0.1 %) than at N - not the
    # coarse grid's data; the entry that faded there is dropped
    for kept_fine, without, stands in ((3.76e-6, 4.41e-6, True), (1.50e-6, 1.55e-6, False), (1.712e-6, 1.80e-6, False)):
        _stub_point(monkeypatch, dg, 1.2 * kept_fine, -60000.0)
        fits = iter([res(30.7e-6, 0.0, 41), res(without, -65000.0, 41), res(kept_fine, -65500.0, 41),
                     res(29.0e-6, -1000.0, 41)])
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        kept, final, rec = dg._resolution_check(None, base, None, [rs, branch], current, f0, None, None,
                                                lambda s: None, before=before)
        assert "inconclusive" in rec
        last = rec["marginal"][0]
        assert last["entry"] == branch.key and last["gain_fine"] == pytest.approx(1 - kept_fine / without)
        assert last["gain_fine"] < 0.5 * last["gain"]          # what the check alone would drop
        if stands:
            assert not last["dropped"] and "finer N" in last["premise"]
            assert kept == [rs, branch] and final is current and rec["dropped_marginal"] == []
        else:
            assert last["dropped"] and "premise" not in last
            assert kept == [rs] and rec["dropped_marginal"] == [branch.key]


def test_an_entry_kept_before_others_must_hold_on_top_of_them(monkeypatch):
    """Backward elimination (_earlier_entries_check): a spring kept first on a branch's
    dataset (its BIC fall 13685 against the branch's 13218) was still named after the
    branch was kept two rounds later. Each physics entry kept before the last is refitted
    out at the finer N, and dropped when the kept model no longer passes acceptance
    against the model without it; one that still does stays. Fits stubbed."""
    dropped_by = []
    dg = _stubbed_diagnose(monkeypatch, lambda drop, kept, fitted, base, ctx: (dropped_by.append(drop.key) or base, []))
    spring, eps, branch = _entry("stiffness"), _entry("nominal:eps_r_l", "nominal"), _entry("polarization_branch")

    res = partial(_stubbed_fit, sigma=2.5e-6)

    base = preset("vshape-table1").replace(N=21)
    f0, before, current = res(7.43e-6, 0.0, 21), res(4.19e-6, -38000.0, 21), res(3.67e-6, -44000.0, 21)
    for spring_without, dropped in ((2.85e-6, True), (3.60e-6, False)):
        dropped_by.clear()
        # finer baseline (worse: inconclusive), without the branch (last), without the spring; the
        # kept model's values at N = 41 pass against both where the spring holds, else its refit
        # decides
        _stub_point(monkeypatch, dg, 2.9e-6, -58000.0, 2.5e-6)
        fits = iter([res(7.60e-6, 0.0, 41), res(4.40e-6, -40000.0, 41),
                     res(spring_without, -59995.0 if dropped else -50000.0, 41)]
                    + ([res(2.81e-6, -60000.0, 41)] if dropped else []))
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        kept, final, rec = dg._resolution_check(None, base, None, [spring, eps, branch], current, f0, None, None,
                                                lambda s: None, before=before)
        assert dropped_by == [branch.key, spring.key]
        assert [m["entry"] for m in rec["marginal"]] == [branch.key, spring.key]
        assert [m.get("later", False) for m in rec["marginal"]] == [False, True]
        if dropped:
            assert kept == [eps, branch] and rec["dropped_marginal"] == [spring.key]
            assert final.heldout_rmse == spring_without and rec["refined"]
        else:
            assert kept == [spring, eps, branch] and rec["dropped_marginal"] == [] and final is current


def test_an_entry_is_checked_deeper_when_the_rest_is_not_resolved(monkeypatch):
    """_deeper: on the lab rig an Eq. (21) law kept before inertia cut 37 % on top of
    inertia at N = 41 (2.70 -> 1.71 um, 1.26 um noise) and nothing at N = 81 (1.37 ->
    1.36 um): inertia alone was not resolved at 41 (its values gave 6.69 um at N = 21).
    Such an entry is checked again at twice the elements and dropped there; when the rest
    is resolved (its values at N = 21 within 1/RAISE_GAIN of its error) the check at 41
    stands, and with no doublings left (budget 0) it stands too. Fits stubbed."""
    dg = _stubbed_diagnose(monkeypatch, _same_base)
    # the set's own cut (_shrinks: 73.9 um^2 at N = 21, 49.6 at 41) would take the whole
    # check to N = 81 first: this test is of the last entry's check alone
    patch(monkeypatch, "RES_CUT", 0.0)
    law, inertia = _entry("field_dependent_resistivity (Eq. 21)"), _entry("inertia")
    res = partial(_stubbed_fit, sigma=1.26e-6)
    base = preset("vshape-table1").replace(N=21)
    f0, before, current = res(8.83e-6, 0.0, 21), res(6.98e-6, -9000.0, 21), res(2.02e-6, -48000.0, 21)
    for inertia_at_21, budget, dropped in ((6.69e-6, 2, True), (2.9e-6, 2, False), (6.69e-6, 0, False)):
        evaluated = []

        def point(dataset, fr, params, executor=None):
            evaluated.append((round(fr.heldout_rmse * 1e8), params.N))
            err = {(202, 41): 1.71e-6, (650, 21): 7.0e-6, (270, 21): inertia_at_21, (171, 81): 1.40e-6}
            return res(err[(round(fr.heldout_rmse * 1e8), params.N)], -59000.0 if params.N == 81 else -60000.0,
                       params.N)
        patch(monkeypatch, "evaluate", point)
        fits = iter([res(7.25e-6, 0.0, 41), res(6.50e-6, -20000.0, 41), res(2.70e-6, -55000.0, 41)]
                    + ([res(1.37e-6, -60000.0, 81), res(1.36e-6, -60005.0, 81)] if dropped
                       else [res(1.70e-6, -60001.0, 41)]))
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        kept, final, rec = dg._resolution_check(None, base, None, [law, inertia], current, f0, None, None,
                                                lambda s: None, before=before, budget=budget)
        law_rec = [m for m in rec["marginal"] if m["entry"] == law.key][0]
        if dropped:
            assert kept == [inertia] and rec["dropped_marginal"] == [law.key]
            assert law_rec["N_check"] == 81 and law_rec["rmse_without"] == 1.37e-6
            assert final.heldout_rmse == 1.37e-6 and final.params.N == 81 and rec["N_final"] == 81
            assert (171, 81) in evaluated            # the kept model's point at 81 was tried first
        else:
            assert kept == [law, inertia] and rec["dropped_marginal"] == [] and "N_check" not in law_rec
            assert all(n != 81 for _, n in evaluated)
            assert ((270, 21) in evaluated) == (budget > 0)   # no doublings left: not even evaluated


def test_a_cut_that_shrinks_with_the_elements_is_checked_at_twice_those(monkeypatch):
    """_shrinks on the kept set: on a null dataset under polarity inversion with a converged truth
    (lab_fine, 651 points) a polarization branch kept at N = 21 cut the held-out error 2.07
    -> 1.55 um (1.30 um noise); at N = 41 1.80 -> 1.47 um, a relative gain of 0.73 of
    itself, which RES_SHRINK passes, but only 57 % of the squared error it had removed; at
    N = 81 1.57 -> 1.40 um (11 %, under half of 25 %): dropped there. An exponential law
    on an inversion dataset removed 64 % as much at N = 41 (3.37 -> 2.24 um at 21, 2.83 ->
    1.98 at 41) and holds at 81 (2.56 -> 1.64 um): the final model is at N = 81. A cut that
    holds at 41, or no doublings left, leaves the check at 41. The numbers are those runs';
    the fits stubbed."""
    dg = _stubbed_diagnose(monkeypatch)
    entry = _entry("polarization_branch")
    res = partial(_stubbed_fit, sigma=1.26e-6)
    base = preset("vshape-table1").replace(N=21)
    cases = {   # name: (f0, kept at 21, [(baseline, kept point, kept refit) at 41, at 81], budget)
        "null": ((2.07e-6, 1.55e-6), [(1.80e-6, 1.50e-6, 1.47e-6), (1.57e-6, 1.42e-6, 1.40e-6)], 2),
        "null, no doubling left": ((2.07e-6, 1.55e-6), [(1.80e-6, 1.50e-6, 1.47e-6)], 0),
        "law": ((3.37e-6, 2.24e-6), [(2.83e-6, 2.05e-6, 1.98e-6), (2.56e-6, 1.70e-6, 1.64e-6)], 2),
        "cut holds": ((3.37e-6, 2.24e-6), [(2.83e-6, 1.40e-6, 1.38e-6)], 2),
        # a linear law under inversion (fresh lab_fine draw): its cut at 41 was 76 % of that at 21, but at
        # N = 81 the baseline fitted no better (5.86 against 5.82 um) and the kept refit worse (5.26 against
        # 4.39): the premise fails, the check at 41 stands (it had dropped the real law)
        "deeper fits no better": ((6.20e-6, 4.39e-6), [(5.82e-6, 4.40e-6, 4.39e-6), (5.86e-6, 5.30e-6, 5.26e-6)],
                                  2),
        # a spline law on an inversion null (lab_fine, trial seed 429800168, #10): at N = 81 the kept model a
        # hair worse than at 41 (1.476 against 1.461 um, 1 %) while the baseline reached 1.486 um (1.04
        # noises): the deeper check is made - dropped, where the check at 41 had named it
        "null, deeper a hair worse": ((1.778e-6, 1.467e-6), [(1.651e-6, 1.47e-6, 1.461e-6),
                                                              (1.486e-6, 1.48e-6, 1.476e-6)], 2),
    }
    for name, ((e0, ek), levels, budget) in cases.items():
        f0, current = res(e0, 0.0, 21), res(ek, -900.0, 21)
        points = {41 if i == 0 else 81: lv[1] for i, lv in enumerate(levels)}
        patch(monkeypatch, "evaluate", lambda ds, fr, params, executor=None: res(points[params.N], -1300.0,
                                                                                       params.N))
        order = []
        for i, (b, _, k) in enumerate(levels):
            n = 41 if i == 0 else 81
            order += [res(b, -400.0, n), res(k, -1400.0, n)]
        fits = iter(order)
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        said = []
        kept, final, rec = dg._resolution_check(None, base, None, [entry], current, f0, None, None, said.append,
                                                budget=budget)
        if name == "null, deeper a hair worse":
            assert kept == [] and rec["resolution_only"] and rec["N_fine"] == 81, rec
            assert final.params.N == 81 and final.heldout_rmse == 1.486e-6
        elif name == "null":
            assert kept == [] and rec["resolution_only"] and rec["N_fine"] == 81, rec
            assert rec["first_check"]["N"] == 41 and rec["first_check"]["cut_ratio"] == pytest.approx(0.566, abs=0.01)
            assert final.params.N == 81 and final.heldout_rmse == 1.57e-6
            assert any("again at N = 81" in s for s in said)
        elif name == "law":
            assert kept == [entry] and rec["refined"] and final.params.N == 81 and final.heldout_rmse == 1.64e-6
            assert rec["N_fine"] == 81 and rec["first_check"]["cut_ratio"] == pytest.approx(0.644, abs=0.01)
        elif name == "deeper fits no better":
            assert kept == [entry] and rec["N_fine"] == 41 and not rec["resolution_only"], rec
            assert rec["first_check"]["deeper"]["inconclusive"] and rec["first_check"]["deeper"]["N"] == 81
            assert next(fits).heldout_rmse == 5.26e-6     # the kept model at 81 was not refitted
            assert any("the check at N = 41 stands" in s for s in said)
        else:   # the check at 41 stands: kept, the final model refitted there
            assert kept == [entry] and rec["N_fine"] == 41 and "first_check" not in rec, (name, rec)
            assert final.params.N == 41
        assert next(fits, None) is None          # every stubbed fit was made: no more


def test_a_deeper_refit_clearly_worse_is_judged_when_converged_and_refitted_further_when_not(monkeypatch):
    """An Eq. (21) law on a unipolar null (lab_fine, trial seed 998262936, #6): the plain model
    converges slowly there (5.12, 3.61, 3.08 um at N = 81, 161, 321 against 1.29 um noise);
    the law cut it to 2.67 and 2.47 um (36 % of the squared error at 161), and at 321 its
    warm refit, converged, left 2.82 um - clearly worse than at 161 while the baseline fitted
    better. The deeper check had stood down on it (a refit that did not get there) and the
    law was named; converged, the refit is judged: its gain (9 % against 48 %) did not hold,
    dropped. A refit stopped short at RES_NFEV evaluations goes on first; still short and
    worse, the check at twice the elements stands. (N = 21, 41, 81 here; the fits stubbed.)"""
    dg = _stubbed_diagnose(monkeypatch)
    entry = _entry("field_dependent_resistivity (Eq. 21)")
    res = partial(_stubbed_fit, sigma=1.29e-6)
    base = preset("vshape-table1").replace(N=21)
    points = {41: 2.50e-6, 81: 2.85e-6}
    patch(monkeypatch, "evaluate", lambda ds, fr, params, executor=None: res(points[params.N], -1300.0, params.N))
    for converged in (True, False):
        f0, current = res(5.12e-6, 0.0, 21), res(2.67e-6, -900.0, 21)
        order = [res(3.61e-6, -400.0, 41), res(2.47e-6, -1400.0, 41), res(3.08e-6, -400.0, 81),
                 res(2.82e-6, -1400.0, 81, converged=converged)]
        if not converged:
            order.append(res(2.80e-6, -1410.0, 81, converged=False))     # the search goes on: still short
        fits = iter(order)
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        said = []
        kept, final, rec = dg._resolution_check(None, base, None, [entry], current, f0, None, None, said.append,
                                                budget=2)
        if converged:
            assert kept == [] and rec["resolution_only"] and rec["N_fine"] == 81, rec
            assert final.params.N == 81 and final.heldout_rmse == 3.08e-6
        else:
            assert kept == [entry] and rec["N_fine"] == 41 and rec["first_check"]["deeper"]["inconclusive"], rec
            assert rec["first_check"]["deeper"]["kept_rmse"] == 2.80e-6
            assert any("refitted further" in s for s in said)
        assert next(fits, None) is None


def test_a_last_entry_whose_cut_shrinks_is_checked_deeper(monkeypatch):
    """_deeper on the last entry's own cut (_shrinks): on a lab_fine inversion dataset
    (inertia hidden, truth at 651 points, 1.11 um noise) an Eq. (21) law kept beside
    inertia cut 1.57 -> 1.16 um at N = 21 (26 %) and 1.42 -> 1.16 at 41 (18 %: RES_SHRINK
    passes it), where inertia alone, at 1.27 noises, counts as resolved - but its cut of
    the squared error fell to 59 %. At N = 81 it cut 4 %: dropped, the final model inertia
    alone there. The numbers are that run's; fits stubbed."""
    dg = _stubbed_diagnose(monkeypatch, _same_base)
    law, inertia = _entry("field_dependent_resistivity (Eq. 21)"), _entry("inertia")

    def res(err, N):
        return _stubbed_fit(err, 1e10 * err, N, sigma=1.11e-6)

    base = preset("vshape-table1").replace(N=21)
    f0, before, current = res(4.45e-6, 21), res(1.57e-6, 21), res(1.162e-6, 21)
    points = {41: 1.16e-6, 81: 1.19e-6}
    patch(monkeypatch, "evaluate", lambda ds, fr, params, executor=None: res(points[params.N], params.N))
    fits = iter([res(4.40e-6, 41),      # the baseline at 41
                 res(1.415e-6, 41),     # inertia alone at 41
                 res(1.158e-6, 41),     # the kept model refitted at 41 (its cut on the point fell short)
                 res(1.199e-6, 81),     # inertia alone at 81
                 res(1.195e-6, 81)])    # the kept model refitted at 81 (the point did not pass)
    patch(monkeypatch, "fit", lambda *a, **k: next(fits))
    said = []
    kept, final, rec = dg._resolution_check(None, base, None, [inertia, law], current, f0, None, None, said.append,
                                            before=before, budget=2)
    assert kept == [inertia] and rec["dropped_marginal"] == [law.key] and "first_check" not in rec, rec
    (row,) = rec["marginal"]
    assert row["N_check"] == 81 and row["gain_fine"] < 0.05 and row["rmse_without"] == 1.199e-6
    assert final.params.N == 81 and final.heldout_rmse == 1.199e-6
    assert any("again at N = 81 (it removed 59% of the squared error" in x for x in said), said
    assert next(fits, None) is None
    # with no doubling left the check at 41 stands (the old verdict: both named)
    fits = iter([res(4.40e-6, 41), res(1.415e-6, 41)])
    kept, final, rec = dg._resolution_check(None, base, None, [inertia, law], current, f0, None, None,
                                            lambda x: None, before=before, budget=0)
    assert kept == [inertia, law]


def test_a_model_left_unexplained_is_refitted_from_neutral_nuisances(monkeypatch):
    """_cold_refit: a strong polarization branch under unipolar pulses (lab_fine), kept at
    N = 21 and refitted warm up to N = 161, stayed at 10.4 um held out against 2.9 um noise;
    refitted there from neutral per-recording nuisances it reached 3.4 um, its cost 8x
    lower. The refit is made only for a kept model at UNEXPLAINED noises or more (held out
    or in training), and taken only when its cost is lower. Fits stubbed."""
    from types import SimpleNamespace as NS
    dg = _stubbed_diagnose(monkeypatch)
    entry = _entry("polarization_branch")

    def res(held, train, cost, N=161):
        return NS(heldout_rmse=held, train_rmse=train, cost=cost, sigma=2.9e-6,
                  params=preset("vshape-table1").replace(N=N))

    f0 = res(183e-6, 190e-6, 1e8)
    warm = res(10.4e-6, 12.2e-6, 2.47e5)
    calls = []

    def cold(dataset, spec, base=None, warm=None, **k):
        calls.append(warm)
        return res(3.4e-6, 4.3e-6, 2.97e4)
    patch(monkeypatch, "fit", cold)
    final, rec = dg._cold_refit(None, None, [entry], warm, f0, None, None, lambda s: None)
    assert final.heldout_rmse == 3.4e-6 and rec["taken"] and rec["rmse"] == 10.4e-6 and calls == [None]
    # a refit that costs more is not taken
    patch(monkeypatch, "fit", lambda *a, **k: res(11e-6, 12e-6, 3e5))
    final, rec = dg._cold_refit(None, None, [entry], warm, f0, None, None, lambda s: None)
    assert final is warm and not rec["taken"] and rec["rmse_cold"] == 11e-6
    # nor one whose cost is lower by a hair and whose error is within RES_BETTER (a spline law: 6.9472 ->
    # 6.9471 um held out, taken, made the final model another fit than the tried entry's)
    patch(monkeypatch, "fit", lambda *a, **k: res(10.39e-6, 12.1e-6, 2.46e5))
    final, rec = dg._cold_refit(None, None, [entry], warm, f0, None, None, lambda s: None)
    assert final is warm and not rec["taken"]
    # not tried: within UNEXPLAINED noises both held out and in training, nothing kept, or the baseline
    patch(monkeypatch, "fit", lambda *a, **k: pytest.fail("no refit expected"))
    near = res(5.7e-6, 5.5e-6, 1e4)
    assert dg._cold_refit(None, None, [entry], near, f0, None, None, lambda s: None) == (near, None)
    assert dg._cold_refit(None, None, [], warm, f0, None, None, lambda s: None) == (warm, None)
    assert dg._cold_refit(None, None, [entry], f0, f0, None, None, lambda s: None) == (f0, None)
    # training at 2 noises with the held-out condition near the noise: tried
    patch(monkeypatch, "fit", lambda *a, **k: res(3.0e-6, 3.1e-6, 10.0))
    final, rec = dg._cold_refit(None, None, [entry], res(3.2e-6, 6.0e-6, 2e4), f0, None, None, lambda s: None)
    assert rec["taken"] and final.train_rmse == 3.1e-6


def test_close_rivals_are_compared_at_twice_the_elements(monkeypatch):
    """_tie_break: a slow branch beat the spline law at N = 41 by a BIC fall of 28859
    against 27374 (lab rig, a power-law truth) and was named; at N = 81 the spline fitted
    better. Accepted rivals of another entry within TIE_SHARE of the best's fall are
    refitted at twice the elements and the lower BIC there is kept; a rival further off,
    or another form of the same entry, is not refitted. Fits stubbed."""
    from types import SimpleNamespace as NS
    patch(monkeypatch, "_spec", lambda p, ctx, entries: [])
    res = partial(_stubbed_fit, sigma=2.13e-6)
    current = res(9.22e-6, 0.0, 41)
    fits = {"polarization_branch": res(3.78e-6, -28859.0, 41),
            "field_dependent_resistivity (spline)": res(4.20e-6, -27374.0, 41),
            "field_dependent_resistivity (Eq. 21)": res(5.22e-6, -25176.0, 41)}
    prepared = {k: (NS(key=k), None) for k in fits}
    refits = []

    def fake(dataset, spec, base=None, warm=None, **k):
        refits.append((base.N, warm.bic))
        return {-28859.0: res(3.56e-6, -40000.0, 81), -27374.0: res(3.22e-6, -47238.0, 81)}[warm.bic]
    patch(monkeypatch, "fit", fake)
    ev = {k: {} for k in fits}
    pick, made = dg._tie_break(None, list(fits), "polarization_branch", fits, prepared, [], current, None, None,
                               None, lambda s: None, ev)
    assert pick == "field_dependent_resistivity (spline)" and made.params.N == 81 and made.bic == -47238.0
    assert refits == [(81, -28859.0), (81, -27374.0)]            # the two leaders only, at N = 81
    assert ev["polarization_branch"]["tie"]["kept"] == pick and "tie" not in ev["field_dependent_resistivity (Eq. 21)"]
    # resolution first after the entry is kept reuses that refit (the same call) instead of making it again
    patch(monkeypatch, "fit", lambda *a, **k: pytest.fail("the tie-break's refit is made again"))
    f0, fine = res(9.22e-6, 0.0, 41), res(7.5e-6, 0.0, 81)
    base, _, _, kept_fit, _, steps, _ = dg._raise_kept(None, preset("vshape-table1").replace(N=41), None,
                                                    [prepared[pick][0]], fits[pick], f0, f0, None, None,
                                                    lambda s: None, 1, fine, made)
    assert base.N == 81 and kept_fit is made and steps[0]["error_fine"] == 3.22e-6
    # a rival short of TIE_SHARE of the best's fall: the coarse BIC decides, nothing refitted
    refits.clear()
    fits["field_dependent_resistivity (spline)"] = res(4.20e-6, -0.8 * 28859.0, 41)
    fits["field_dependent_resistivity (Eq. 21)"] = res(5.22e-6, -0.85 * 28859.0, 41)
    assert dg._tie_break(None, list(fits), "polarization_branch", fits, prepared, [], current, None, None, None,
                         lambda s: None, {k: {} for k in fits}) == ("polarization_branch", None) and refits == []
    # another form of the best's own entry is no rival
    fits = {"field_dependent_resistivity (spline)": res(4.2e-6, -28000.0, 41),
            "field_dependent_resistivity (Eq. 21)": res(4.3e-6, -27900.0, 41)}
    assert dg._tie_break(None, list(fits), "field_dependent_resistivity (spline)", fits, prepared, [], current, None,
                         None, None, lambda s: None, {k: {} for k in fits}) == ("field_dependent_resistivity (spline)",
                                                                                None)
    assert refits == []


def test_raised_steps_are_told_before_the_selection_and_after_an_entry():
    """report.md's conclusion and improved.toml tell each run of raises: before the
    selection (the baseline's error) or after a kept entry (the kept model's)."""
    from diagnosis.improved import raised_phrases
    steps = [{"N": 21, "error": 11e-6, "N_fine": 41, "error_fine": 6e-6, "after": None},
             {"N": 41, "error": 4.5e-6, "N_fine": 81, "error_fine": 2e-6, "after": "inertia"}]
    a, b = raised_phrases(steps)
    assert a.startswith("N raised from 21 to 41 before the selection: the baseline's error 11 -> 6 um")
    assert b.startswith("N raised from 41 to 81 after inertia was kept: the kept model's error 4.5 -> 2 um")
    # two doublings in one run read as one phrase; a step without `after` (older reports) as before
    one = raised_phrases([{**steps[0], "after": "inertia"}, {**steps[1]}])
    assert len(one) == 1 and "from 21 to 81 after inertia" in one[0] and "11 -> 2 um" in one[0]
    assert raised_phrases([{k: v for k, v in steps[0].items() if k != "after"}])[0].endswith(
        "(the model's own resolution, not missing physics)")
    assert raised_phrases([]) == []


def test_resolution_last_when_nothing_was_kept(monkeypatch):
    """When the rounds keep nothing while the baseline leaves more than RAISE_FLOOR noises,
    the selection runs once more at twice the elements (_retry_finer): on the lab rig a
    fast polarization branch (tau_p = 0.12 s) left 2.19 um against 1.17 um noise at N = 41,
    too small a screen to fit there, and was named at N = 81 (1.23 um, chi_p 0.0144 against
    0.0151). Not when something was kept, the baseline is within the floor, nothing is held
    out or no doubling is left; the baseline refit _resolve made is reused. Fits stubbed."""
    from types import SimpleNamespace as NS
    dg = _stubbed_diagnose(monkeypatch)
    calls = []

    def fake(dataset, spec, base, **kw):
        calls.append(base.N)
        return NS(heldout_rmse=2.16e-6, train_rmse=2.2e-6, sigma=1.17e-6, heldout=["h"], params=base)
    patch(monkeypatch, "fit", fake)
    base = preset("vshape-table1").replace(N=41)
    f0 = NS(heldout_rmse=2.19e-6, train_rmse=2.3e-6, sigma=1.17e-6, heldout=["h"], params=base)
    b, ff, step = dg._retry_finer(None, base, None, f0, [], None, None, lambda s: None, 1)
    assert b.N == 81 and ff.params.N == 81 and calls == [81]
    assert step == {"N": 41, "error": 2.19e-6, "N_fine": 81, "error_fine": 2.16e-6, "after": dg.NOTHING_KEPT}
    fine = NS(heldout_rmse=2.1e-6, sigma=1.17e-6, params=base.replace(N=81))
    calls.clear()
    assert dg._retry_finer(None, base, None, f0, [], None, None, lambda s: None, 1, fine)[1] is fine and not calls
    entry = NS(kind="physics", key="inertia")
    near = NS(heldout_rmse=1.7e-6, train_rmse=1.7e-6, sigma=1.17e-6, heldout=["h"], params=base)
    alone = NS(heldout_rmse=None, train_rmse=2.3e-6, sigma=1.17e-6, heldout=[], params=base)
    for args in ((f0, [entry], 1), (near, [], 1), (alone, [], 1), (f0, [], 0)):
        assert dg._retry_finer(None, base, None, args[0], args[1], None, None, lambda s: None, args[2]) is None
    assert not calls
    from diagnosis.improved import raised_phrases
    assert "after the selection kept nothing (resolution last)" in raised_phrases([step])[0]


def test_a_fit_evaluated_at_another_N(coarse):
    """fit.evaluate: a fit's values and nuisances run at another N, nothing refitted but
    each sensor's zero and time shift - the point a check at the finer N tries before any
    refit (_KeptFine). At the fit's own N it is the fit (same errors and BIC); at twice
    the elements the baseline's refit there, which starts from those values, fits the
    training data at least as well."""
    from diagnosis.fit import evaluate
    D, _, _ = coarse
    f0 = D.baseline
    same = evaluate(D.dataset, f0, f0.params, InProcess())
    assert same.train_rmse == pytest.approx(f0.train_rmse, rel=1e-9)
    assert same.heldout_rmse == pytest.approx(f0.heldout_rmse, rel=1e-9)
    assert same.bic == pytest.approx(f0.bic, rel=1e-9) and same.runs == len(D.dataset.recordings)
    fine = evaluate(D.dataset, f0, f0.params.replace(N=41), InProcess())
    assert fine.params.N == 41 and "not refitted" in fine.notes[0] and not fine.converged
    assert fine.train_rmse != f0.train_rmse
    assert D.again["first"]["N_final"] == 41 and D.again["first"]["train_rmse"] <= fine.train_rmse


def test_the_selection_runs_again_where_a_kept_set_s_cut_shrinks(monkeypatch):
    """_reselect_due: on a converged truth (lab_fine, three loads at 6 kV, 1.86 um noise) a
    polarization branch was named as an Eq. (21) law at N = 21 (7.97 -> 4.51 um held out);
    at N = 41 the baseline left 7.87 um and the law 5.93 um: it holds (a 25 % gain against
    43 %) but removes 62 % of the squared error it removed, and leaves 3.2 noises - the
    selection must run again at 41 (where the branch reached 2.87 um). Not when the cut
    holds, the model at 41 is within UNEXPLAINED noises, the finer baseline fits no better,
    nothing is held out or no doubling is left. The numbers are those runs'; fits stubbed."""
    from types import SimpleNamespace as NS
    dg = _stubbed_diagnose(monkeypatch)
    entry = _entry("field_dependent_resistivity (Eq. 21)")
    sigma = 1.86e-6

    def res(err, bic, N, heldout=("h",)):
        return NS(heldout_rmse=err if heldout else None, train_rmse=err, bic=bic, sigma=sigma, heldout=list(heldout),
                  params=preset("vshape-table1").replace(N=N))
    base = preset("vshape-table1").replace(N=21)
    cases = {   # name: (f0, kept at 21, baseline at 41, kept point at 41, kept refit at 41, budget, due)
        "branch as a law": (7.97e-6, 4.51e-6, 7.87e-6, 6.3e-6, 5.93e-6, 2, True),
        "cut holds": (7.97e-6, 4.51e-6, 7.87e-6, 4.6e-6, 4.5e-6, 2, False),
        "resolved at 41": (8.0e-6, 4.0e-6, 5.0e-6, 4.2e-6, 3.6e-6, 2, False),   # shrinks, but 1.9 noises at 41
        "finer baseline no better": (7.97e-6, 4.51e-6, 8.0e-6, 6.3e-6, 5.93e-6, 2, False),
        "no doubling left": (7.97e-6, 4.51e-6, 7.87e-6, 6.3e-6, 5.93e-6, 0, False),
        "within the noise at 21": (3.5e-6, 3.0e-6, 3.4e-6, 3.2e-6, 3.2e-6, 2, False),
    }
    for name, (e0, ek, eb, ep, er, budget, due) in cases.items():
        f0, current = res(e0, 0.0, 21), res(ek, -20000.0, 21)
        patch(monkeypatch, "evaluate", lambda ds, fr, params, executor=None: res(ep, -9000.0, params.N))
        fits = iter([res(eb, 0.0, 41), res(er, -12000.0, 41)])
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        refits = []
        ff, fk, got = dg._reselect_due(None, base, None, [entry], current, f0, None, None, refits, None, budget)
        assert got == due, name
        if due:
            assert ff.heldout_rmse == eb and fk.heldout_rmse == er and refits == [(current, fk)]
            step = dg._reselect_step(base, [entry], current, f0, ff, fk)
            assert step["cut_ratio"] == pytest.approx((eb ** 2 - er ** 2) / (e0 ** 2 - ek ** 2))
            assert step["cut_ratio"] == pytest.approx(0.62, abs=0.01) and step["after"] == dg.RESELECTED
    # nothing held out: the rounds' choices are suggestions, no reselection
    f0n = res(7.97e-6, 0.0, 21, heldout=())
    assert dg._reselect_due(None, base, None, [entry], res(4.51e-6, -2e4, 21, ()), f0n, None, None, [], None, 2)[2] \
        is False
    # the model taken: the lower BIC at the finer N; report.json and the conclusion say which and why
    from diagnosis.improved import raised_phrases
    from diagnosis.report import reselect_phrase
    f0, current, ff, fk = res(7.97e-6, 0.0, 21), res(4.51e-6, -2e4, 21), res(7.87e-6, 0.0, 41), res(5.93e-6, -1.2e4, 41)
    step = dg._reselect_step(base, [entry], current, f0, ff, fk)
    branch = _entry("polarization_branch")
    rec = dg._reselect_record(step, fk, [branch], res(2.87e-6, -4.5e4, 41))
    assert rec["kept"] == "second" and rec["second"] == ["polarization_branch"] and rec["N_fine"] == 41
    phrase = reselect_phrase(NS(reselect=rec))
    assert "run again at N = 41, the selection kept polarization_branch" in phrase and "taken" in phrase
    assert dg._reselect_record(step, fk, [], ff)["kept"] == "first"       # nothing kept there: the law stands
    told = raised_phrases([step])
    assert told == ["N raised from 21 to 41 after the selection kept field_dependent_resistivity (Eq. 21): at N = 41 "
                    "it removed 62% of the squared error it removed at N = 21 and left 4.51 -> 5.93 um, unexplained "
                    "at both: the selection was run again there"], told
    # a raise after the second selection kept an entry is told on its own
    assert len(raised_phrases([step, {"N": 41, "error": 4e-6, "N_fine": 81, "error_fine": 2e-6,
                                      "after": "polarization_branch"}])) == 2


def test_the_trained_conditions_judge_where_the_held_out_one_is_near_the_noise(monkeypatch):
    """A stiffness of 33.9 N/m under loads of 3, 6 and 7 N at 6 kV, the 6 N held out
    (unipolar, lab_fine, trial seed 890441317, #7; 2.60 um noise): the baseline at N = 81
    left 3.12 um held out and 8.14 um in training. The stiffness cut the held-out error by
    14 % there and 3 % at N = 161 - near the noise no model cuts it much - and was dropped as
    the model's discretization error; in training it cut 66 % and 62 %: it holds. Where the
    held-out error is itself far off, it alone judges (dropped). Fits stubbed."""
    from types import SimpleNamespace as NS
    dg = _stubbed_diagnose(monkeypatch)
    entry = _entry("stiffness")
    base = preset("vshape-table1").replace(N=81)

    def res(held, train, bic, N):
        return NS(heldout_rmse=held, train_rmse=train, bic=bic, sigma=2.60e-6, converged=True, spec=[],
                  params=preset("vshape-table1").replace(N=N))
    patch(monkeypatch, "evaluate", lambda ds, fr, params, executor=None: res(2.74e-6, 3.0e-6, -50.0, params.N))
    for held0, kept_expected in ((3.12e-6, [entry]), (6.0e-6, [])):
        f0, current = res(held0, 8.14e-6, 0.0, 81), res(held0 * 0.86, 2.77e-6, -61019.0, 81)
        fits = iter([res(2.75e-6 if held0 < 5e-6 else 5.3e-6, 7.0e-6, -100.0, 161),      # the baseline at 161
                     res(2.67e-6 if held0 < 5e-6 else 5.25e-6, 2.66e-6, -60000.0, 161)])  # the kept model's refit
        patch(monkeypatch, "fit", lambda *a, **k: next(fits))
        said = []
        kept, final, rec = dg._resolution_check(None, base, None, [entry], current, f0, None, None, said.append,
                                                budget=0)
        assert kept == kept_expected, rec
        if kept:
            assert not rec["resolution_only"] and rec["training"]["holds"] and rec["gain_fine"] < 0.05
            assert any("the trained ones are not" in s for s in said)
        else:
            assert rec["resolution_only"] and "training" not in rec
