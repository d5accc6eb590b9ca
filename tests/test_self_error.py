"""The final model's own discretization error at its fitted values (diagnosis/self_error.py):
no data enter, the model at its N against itself at 4x the elements."""
import warnings
from dataclasses import replace
from types import SimpleNamespace as NS

import pytest

from dfa_model import preset
from dfa_model.io.recordings import read_dataset
from dfa_model.io.synthetic import Measurement, generate_dataset
from diagnosis.catalog import PHYSICS, Context, baseline_spec
from diagnosis.fit import fit, self_error
from diagnosis.report import self_error_phrase
from diagnosis.rules import _prepared
from diagnosis.self_error import self_check

BRANCH = next(e for e in PHYSICS if e.key == "polarization_branch")


@pytest.fixture(scope="module")
def inversion(tmp_path_factory):
    """A strong polarization branch under 1 Hz polarity inversion, the truth at 161 points."""
    warnings.simplefilter("ignore")
    folder = tmp_path_factory.mktemp("self") / "data"
    nominal = preset("vshape-table1").replace(N=21, rho_l=3e12)
    meas = Measurement(noise=2e-6, quantum=0.4e-6, offset=15e-6, voltage_gain=0.002, voltage_noise=10.0,
                       force_noise=0.02, rho_spread=0.04)
    generate_dataset(folder, nominal.replace(rho_l=2e12, N=161, chi_p=0.24, tau_p=0.5), nominal,
                     [(6000.0, 3.0), (6000.0, 5.0)], repetitions=2, reset=3.0, hold=0.0, reset_frequency=1.0,
                     measurement=meas, seed=4, pretrigger=0.0, drive="inversion")
    ds = read_dataset(folder)
    ctx = Context.of(ds)
    p, spec = _prepared(ds.params.replace(chi_p=0.24, tau_p=0.5), [BRANCH], ctx)
    return ds, fit(ds, baseline_spec(ds.params, ctx), holdout=[]), fit(ds, spec, base=p, holdout=[])


def test_a_coarse_branch_is_far_from_its_own_continuum_and_the_plain_model_is_not(inversion):
    """The branch model at N = 21 is several noises off itself at N = 81, and the error falls
    with N; the plain model at the truth's rho_l is within the noise of itself. (The plain
    model *fitted* to these data is not: it takes rho_l to 2.9e11 ohm m, where the
    interface charges within a switch, and is 9.5 um off itself - the measure is the
    fitted model's, whatever it is.)"""
    ds, f0, fb = inversion
    e21, e41 = self_error(ds, fb, 81), self_error(ds, replace(fb, params=fb.params.replace(N=41)), 81)
    e0 = self_error(ds, f0, 81)
    en = self_error(ds, replace(f0, params=f0.params.replace(rho_l=2e12)), 81)
    print(f"\nplain rho_l {f0.params.rho_l:.3g}: {e0 * 1e6:.2f}; at 2e12 {en * 1e6:.2f}")
    print(f"\nbranch chi_p {fb.params.chi_p:.3g}: {e21 * 1e6:.2f} um at 21, {e41 * 1e6:.2f} at 41; "
          f"plain {e0 * 1e6:.2f} um; "
          f"noise {fb.sigma * 1e6:.2f}")
    assert e21 > 2 * fb.sigma and e41 < 0.7 * e21 and en < 0.5 * fb.sigma and e0 > fb.sigma
    rec = self_check(ds, fb, None, lambda s: None)
    assert rec["flagged"] and rec["N_ref"] == 81 and rec["rmse"] == pytest.approx(e21)
    assert rec["rmse_fine"] == pytest.approx(e41) and rec["N_fine"] == 41
    phrase = self_error_phrase(NS(self_error=rec))
    assert "off its own solution at N = 81" in phrase and "diagnose again with a finer N" in phrase
    resolved = self_check(ds, replace(f0, params=f0.params.replace(rho_l=2e12)), None, lambda s: None)
    assert not resolved["flagged"] and "rmse_fine" not in resolved
    assert self_error_phrase(NS(self_error=resolved)) is None


def _final(worst, sigma=1.7e-6):
    return NS(sigma=sigma, train_rmse=worst, heldout_rmse=0.9 * worst)


def test_the_n_the_diagnosis_runs_again_at():
    """The branch above: 8.96 um at N = 21, 4.65 at 41 (0.52 per doubling), 1.7 um noise:
    81 -> 2.4, 161 -> 1.25 um, within 1 noise: N = 161, within 8x the nominal 21. Not
    where the final model reaches the noise: the workflow example's data, made by the
    model at N = 21, fit it at 0.97 noises while it is 13 noises off itself."""
    from diagnosis.self_error import again_N
    rec = {"N": 21, "N_ref": 81, "rmse": 8.96e-6, "rmse_fine": 4.65e-6, "ratio": 5.3, "flagged": True}
    far = _final(2.48e-6)                                          # 1.46 noises
    assert again_N(rec, 21, far) == 161
    assert again_N(rec, 11, far) == 81           # 8x a nominal 11 at most: the finest allowed
    assert again_N(dict(rec, N=161), 21, far) is None          # already at 8x the nominal
    assert again_N(dict(rec, rmse=3.0e-6, rmse_fine=1.5e-6), 21, far) is None   # under 2 noises: said only
    assert again_N(dict(rec, rmse_fine=9.5e-6), 21, far) is None                # not falling
    assert again_N(dict(rec, rmse_fine=None), 21, far) is None
    assert again_N(None, 21, far) is None
    assert again_N(rec, 21, _final(1.65e-6)) is None           # the data reached at N = 21 (0.97 noises)
    assert again_N(rec, 21, NS(sigma=1.7e-6, train_rmse=1.6e-6, heldout_rmse=2.2e-6)) == 161   # held out not


OWN = {"N": 21, "N_ref": 81, "rmse": 8.96e-6, "rmse_fine": 4.65e-6, "ratio": 5.3, "flagged": True}


def _fit(N, worst, bic=0.0):
    return NS(sigma=1.7e-6, params=NS(N=N), train_rmse=worst, heldout_rmse=0.9 * worst, bic=bic, heldout=["r"])


def _entry(key):
    return NS(name=key.split(" (")[0], key=key, kind="physics")


@pytest.fixture
def again(monkeypatch):
    """diagnose._again on a first outcome stubbed as the inversion draw's (the branch and
    an Eq. (21) law at N = 21, 8.96 um off itself, 2.48 um), with the check and the
    finishing steps stubbed: `check` sets what the check at the finer N returns."""
    import importlib
    dg = importlib.import_module("diagnosis.diagnose")
    from dfa_model.io.recordings import Dataset
    calls, check = [], {}
    branch, law = _entry("polarization_branch"), _entry("field_dependent_resistivity (Eq. 21)")

    def resolution_check(dataset, base, ctx, kept, current, f0, holdout, executor, say, refits=(), Nf=None,
                         every=False, **kw):
        calls.append({"N": base.N, "Nf": Nf, "every": every, "kept": [e.key for e in kept]})
        return check["out"](kept, current)
    monkeypatch.setattr(dg, "_resolution_check", resolution_check)
    monkeypatch.setattr(dg, "_finish", lambda dataset, ctx, kept, current, f0, holdout, executor, refits, say, D,
                        check=None: D)
    ds = Dataset(folder=None, params=preset("vshape-table1").replace(N=21), recordings=[])

    def run(kept=(branch, law)):
        D = dg.Diagnosis(ds, _fit(21, 6e-6), _fit(21, 2.48e-6), list(kept), [], [], [], 100.0, NS(), self_error=OWN)
        return dg._again(ds, D, None, lambda s: None, None, 0.0)
    return run, calls, check, branch, law


def test_the_check_runs_again_where_the_model_is_within_the_noise_of_itself(again):
    from diagnosis.improved import again_phrase
    run, calls, check, branch, law = again
    check["out"] = lambda kept, current: ([branch], _fit(161, 1.86e-6), {"dropped_marginal": [law.key]})
    D = run()
    assert calls == [{"N": 21, "Nf": 161, "every": True, "kept": [branch.key, law.key]}]
    assert [e.key for e in D.missing_physics] == ["polarization_branch"] and D.final.params.N == 161
    assert D.again["taken"] and D.again["first"]["missing_physics"] == [branch.key, law.key]
    text = again_phrase(D)
    assert "the resolution check again at N = 161 (the dataset's 21)" in text
    assert "8.96 um off its own solution at N = 81" in text and f"{law.key} dropped there" in text


def test_a_check_that_keeps_the_coarse_model_says_the_first_outcome_stands(again):
    from diagnosis.improved import again_phrase
    run, calls, check, branch, law = again
    check["out"] = lambda kept, current: (kept, current, {"refined": False})
    D = run()
    assert len(calls) == 1 and D.final.params.N == 21 and not D.again["taken"]
    assert "the first outcome stands" in again_phrase(D)


def test_without_physics_the_final_model_is_refitted_there_not_checked(again, monkeypatch):
    """Nothing named (the baseline) or a nominal correction only: no check to run; the
    final model refitted at the N where it is within the noise of itself is the final model
    where it fits better (a nominal t_lz at N = 81 on the lab rig, 2.8 noises off itself:
    4.31 -> 4.24 um at N = 161), else the first outcome stands. Kept corrections must keep
    their gain over the baseline there, as physics must at the resolution check: a unipolar
    null's t_lz, 13 % at N = 81 and -25 % at 161, is dropped (the baseline at 161 final)."""
    import importlib
    from diagnosis.improved import again_phrase
    dg = importlib.import_module("diagnosis.diagnose")
    run, calls, check, branch, law = again
    made = []
    for worst, taken in ((2.0e-6, True), (2.6e-6, False)):
        monkeypatch.setattr(dg, "_fine_baseline", lambda ds, fb, ctx, f0, h, ex, fine=None, w=worst:
                            made.append(("baseline", fb.N)) or _fit(fb.N, w))
        D = run(kept=[])
        assert calls == [] and D.again["check"]["refit"] and D.again["taken"] == taken
        assert D.final.params.N == (161 if taken else 21)
        text = again_phrase(D)
        assert text.startswith("the final model (the baseline at N = 21) was 8.96 um off its own solution")
        assert ("it fits better" if taken else "it fits no better") in text
    assert made == [("baseline", 161)] * 2
    t_lz = NS(name="nominal:t_lz", key="nominal:t_lz", kind="nominal")

    class Kept:
        def __init__(self, ds, p, ctx, kept, current, h, ex, refits):
            made.append(("kept", p.N, [e.key for e in kept]))

        def fit(self):
            return _fit(161, 2.0e-6, bic=-5000.0)
    monkeypatch.setattr(dg, "_KeptFine", Kept)
    from dfa_model.io.recordings import Dataset
    ds = Dataset(folder=None, params=preset("vshape-table1").replace(N=21), recordings=[])
    # the correction keeps its gain at N = 161 (the baseline 5.5 um there): refitted, taken;
    # the baseline as good there: the correction only took up the grid's error, dropped
    for fine_base, dropped in ((5.5e-6, False), (2.1e-6, True)):
        monkeypatch.setattr(dg, "_fine_baseline", lambda ds, fb, ctx, f0, h, ex, fine=None, w=fine_base:
                            made.append(("baseline", fb.N)) or _fit(fb.N, w))
        final = NS(sigma=1.7e-6, params=preset("vshape-table1").replace(N=21), train_rmse=2.48e-6,
                   heldout_rmse=2.2e-6, bic=-5000.0)
        D = dg.Diagnosis(ds, _fit(21, 6e-6), final, [t_lz], [], [], [], 100.0, NS(), self_error=OWN)
        D = dg._again(ds, D, None, lambda s: None, None, 0.0)
        assert ("kept", 161, ["nominal:t_lz"]) in made and made[-1] == ("baseline", 161) and calls == []
        assert D.again["taken"] and D.final.params.N == 161
        assert [e.key for e in D.kept] == ([] if dropped else ["nominal:t_lz"])
        assert D.again["check"].get("dropped") == (["nominal:t_lz"] if dropped else None)
        text = again_phrase(D)
        assert "the final model (nominal:t_lz at N = 21)" in text
        assert ("only took up the model's discretization error" in text) == dropped
        made.clear()
    # nothing held out (one condition): the final model stays the baseline, nothing refitted
    D = dg.Diagnosis(ds, NS(**{**vars(_fit(21, 6e-6)), "heldout": []}), final, [], [], [], [], 100.0, NS(),
                     self_error=OWN)
    assert dg._again(ds, D, None, lambda s: None, None, 0.0) is D and made == []
