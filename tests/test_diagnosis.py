"""Mismatch diagnosis on synthetic datasets (dfa_model.io.synthetic): a null dataset (only
the nominal rho_l wrong), a wrong nominal t_lz, a bad dataset. Small and short (N = 41,
1 s reset + 5 s hold, 3 loads x 2 repetitions) to keep CI fast. The concealed effects,
one per catalog entry and a combined case, are in test_diagnosis_proof.py."""
from __future__ import annotations

import json

import numpy as np
import pytest

import diagnosis
from dfa_model import preset
from dfa_model.io.recordings import read_dataset
from dfa_model.io.synthetic import Measurement, generate_dataset
from improved_support import check_improved
from diagnosis_parts import dg, patch

NOMINAL = preset("vshape-table1").replace(N=41, rho_l=3e12)
TRUTH = NOMINAL.replace(rho_l=2e12)
CONDITIONS = [(6000.0, 3.0), (6000.0, 5.0), (6000.0, 7.0)]


def _diagnose(tmp_path_factory, name, truth, seed, conditions=CONDITIONS, repetitions=2, candidates=None):
    folder = tmp_path_factory.mktemp(name)
    drawn = generate_dataset(folder / "data", truth, NOMINAL, conditions, repetitions=repetitions, reset=1.0,
                             hold=5.0, measurement=Measurement(rho_spread=0.03), seed=seed)
    ds = read_dataset(folder / "data")
    D = diagnosis.diagnose(ds, executor=None, candidates=candidates)
    report = diagnosis.write_report(D, folder / "out")
    return D, report, drawn, folder / "out"


@pytest.fixture(scope="module")
def null(tmp_path_factory):
    return _diagnose(tmp_path_factory, "null", TRUTH, 11)


def test_null_dataset_reports_no_missing_physics(null):
    D, report, drawn, out = null
    assert report["missing_physics"] == [] and report["fit"]["improved"] is None
    assert report["conclusion"].startswith("no missing physics found") and report["unexplained"] is None
    assert not report["mismatch"] and report["located"] == []
    # the wrong nominal rho_l (3e12) is corrected to the truth's (times the repetitions'
    # mean factor), within three standard errors
    c = report["corrected_parameters"]["rho_l"]
    mean_factor = np.exp(np.mean(np.log([r["rho_factor"] for r in drawn["recordings"]])))
    assert c["nominal"] == 3e12 and c["corrected"]
    assert abs(c["fitted"] - 2e12 * mean_factor) < 3 * c["stderr"] + 0.02 * 2e12
    # both errors at the noise level
    assert report["fit"]["baseline"]["heldout_rmse"] < 1.2 * D.baseline.sigma
    # the headline metric (average unzipping speed per condition) within 5 % (measured: up
    # to 3 %, the per-repetition resistivity factors being shrunk by their prior; with two
    # repetitions their SD is too rough to test 'within the spread' on a null dataset)
    for h in report["headline"]:
        assert abs(h["speed_error_baseline"]) < 0.05 * h["speed_measured"]
    on_disk = json.loads((out / "report.json").read_text())
    assert set(on_disk) >= {"mismatch", "missing_physics", "corrected_parameters", "located", "fit"}
    assert set(on_disk["fit"]["baseline"]) >= {"parameters", "train_rmse", "heldout_rmse"}
    assert (out / "report.md").is_file() and (out / "residuals.png").is_file()
    check_improved(D, report, out)
    assert "missing physics found: none" in (out / "improved.toml").read_text()


def test_a_wrong_nominal_value_is_corrected_not_taken_for_missing_physics(tmp_path_factory):
    D, report, drawn, out = _diagnose(tmp_path_factory, "tlz", TRUTH.replace(t_lz=13e-6), 13)
    assert report["missing_physics"] == [], [m["name"] for m in report["missing_physics"]]
    c = report["corrected_parameters"]["t_lz"]
    assert c["nominal"] == pytest.approx(10e-6) and c["corrected"]
    assert c["fitted"] == pytest.approx(13e-6, rel=0.05)
    assert "nominal value(s) corrected: t_lz" in report["conclusion"]
    assert report["fit"]["improved"]["heldout_rmse"] <= 0.5 * report["fit"]["baseline"]["heldout_rmse"]
    check_improved(D, report, out, fmu=True)
    assert "nominal values corrected: t_lz" in (out / "improved.toml").read_text()


def _entries(*names):
    return [e for e in diagnosis.PHYSICS + diagnosis.NOMINAL if e.name in names]


def test_one_condition_suggests_a_nominal_value_but_does_not_correct_it(tmp_path_factory):
    """Repetitions of one condition: nothing can be held out, so the t_lz the training fit
    moves (to the truth's 13 um) is an unverified suggestion, not a correction: the final
    model and improved.toml keep the nominal 10 um, and the report says why."""
    D, report, _, out = _diagnose(tmp_path_factory, "one_condition", TRUTH.replace(t_lz=13e-6), 13,
                                  conditions=[(6000.0, 5.0)], candidates=diagnosis.NOMINAL)
    assert [e.name for e in D.chain] == ["nominal:t_lz"]               # the rounds chose it on training data
    assert D.kept == [] and not D.improved and [e.name for e in D.unverified] == ["nominal:t_lz"]
    assert report["fit"]["improved"] is None and report["missing_physics"] == []
    assert "t_lz" not in report["corrected_parameters"] and report["nothing_held_out"] == "one condition"
    assert not report["corrected_parameters"]["rho_l"]["heldout_checked"]
    (u,) = report["unverified_suggestions"]
    assert u["name"] == "t_lz" and u["kind"] == "nominal" and u["nominal"] == pytest.approx(10e-6)
    assert u["suggested"] == pytest.approx(13e-6, rel=0.05) and "nothing could be held out" in u["reason"]
    assert "nothing could be held out (one condition): t_lz listed as unverified suggestions, not corrections" in \
        report["conclusion"] and "corrected" not in report["conclusion"].replace("not corrections", "")
    on_disk = json.loads((out / "report.json").read_text())
    assert set(on_disk) >= {"mismatch", "missing_physics", "corrected_parameters", "located", "fit",
                            "unverified_suggestions"}
    md = (out / "report.md").read_text()
    assert "## Unverified suggestions" in md and "Nothing could be held out (one condition)" in md
    text = (out / "improved.toml").read_text()
    from dfa_model.io import parameters
    assert parameters.load(out / "improved.toml").t_lz == NOMINAL.t_lz
    assert "nominal values corrected" not in text and "suggested t_lz: 1.3" in text
    check_improved(D, report, out)


def test_one_recording_names_no_physics(tmp_path_factory):
    """A single recording of a device with a hidden stiffness: the stiffness the training
    fit adds is listed as an unverified suggestion, not as missing physics; improved.toml
    keeps k = 0."""
    D, report, _, out = _diagnose(tmp_path_factory, "one_recording", TRUTH.replace(k=300.0), 7,
                                  conditions=[(6000.0, 5.0)], repetitions=1,
                                  candidates=_entries("stiffness", "nominal:t_lz"))
    assert D.kept == [] and [e.name for e in D.unverified] == ["stiffness"]
    assert report["missing_physics"] == [] and D.missing_physics == []
    (u,) = report["unverified_suggestions"]
    assert u["kind"] == "physics" and u["nominal"] == {"k": 0.0} and u["suggested"]["k"] > 100.0
    assert "stiffness listed as unverified suggestions, not missing physics" in report["conclusion"]
    assert "missing physics:" not in report["conclusion"]
    from dfa_model.io import parameters
    assert parameters.load(out / "improved.toml").k == 0.0
    assert "suggested physics stiffness: k = " in (out / "improved.toml").read_text()
    assert "stiffness (physics)" in (out / "report.md").read_text()


def test_dfa_diagnose_bad_dataset_is_one_line(tmp_path, capsys):
    from dfa_model.cli import main
    (tmp_path / "actuator.toml").write_text(NOMINAL.to_toml())
    assert main(["diagnose", str(tmp_path), "--out", str(tmp_path / "out")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dfa: error: {tmp_path}: no recordings (*.csv); expected one file per test"]
    assert not (tmp_path / "out").exists()


EDITS = [(r"^rho_l = \S+", "rho_l = -1.0", "rho_l"),
         (r"^l_e = \S+", "l_e = 0.1", "l_e"),
         (r"^\[mechanics\]", "[mechanics]\nmass = 0.1", "mass"),
         (r"^t_f = \S+", "t_f = 1e3", "t_f")]


@pytest.mark.parametrize("pattern, new, key", EDITS)
def test_an_improved_model_edited_into_inconsistency_is_the_parameter_error(null, tmp_path, pattern, new, key):
    """improved.toml is a parameter file like any other: an edit that breaks it is one
    line naming the key (exit 2), never a traceback."""
    import re

    from improved_support import dfa
    _, _, _, out = null
    text = (out / "improved.toml").read_text()
    edited, n = re.subn(pattern, new, text, count=1, flags=re.M)
    assert n == 1
    bad = tmp_path / "improved.toml"
    bad.write_text(edited)
    r = dfa("simulate", "--params", bad, "--voltage", "6000", "--duration", "1", "--json")
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert r.stderr.count("\n") == 1 and key in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_a_strong_screen_is_fitted_while_the_mismatch_is_large():
    """Issue 24, item 3: a law of another shape predicted a 3 % held-out gain from its
    first step (the shortlist asks 5 %) and was never fitted; the verdict read 'no missing
    physics' at 8x the noise. While the current model's error is STRONG_ERROR noises or
    more, a form whose first step predicts a BIC fall of BIC_MIN or more is fitted
    whatever its held-out prediction; near the noise the held-out veto stands."""
    from diagnosis.rounds import shortlist
    from diagnosis.rules import BIC_MIN
    screens = {
        "series_resistance": {"predicted_delta_bic": -400.0, "chi2_reduction": 420.0, "heldout_ratio": 0.6},
        "field_dependent_resistivity (spline)": {"predicted_delta_bic": -300.0, "chi2_reduction": 320.0,
                                                 "heldout_ratio": 0.97},
        "inertia": {"predicted_delta_bic": -0.5 * BIC_MIN, "chi2_reduction": 20.0, "heldout_ratio": 0.99},
        "stiffness": {"predicted_delta_bic": 5.0, "chi2_reduction": 2.0, "heldout_ratio": 1.2},
    }
    assert shortlist(screens) == ["series_resistance"]
    strong = shortlist(screens, strong=True)
    assert "field_dependent_resistivity (spline)" in strong and "series_resistance" in strong
    # a weak screen (under BIC_MIN) or one predicting no fall at all stays out either way
    assert "inertia" not in strong and "stiffness" not in strong
    # no verdict of "unexplained mismatch" before the strong screens were fitted: a branch
    # under unipolar pulses left 2.3 noises, its first step predicted a held-out loss, and
    # fitted it cut the held-out error 6.72 -> 3.75 um (STRONG_ERROR had been 3)
    from diagnosis.rules import STRONG_ERROR, UNEXPLAINED
    assert STRONG_ERROR <= UNEXPLAINED


def test_the_strong_screens_the_share_left_out_are_fitted_when_the_shortlist_explains_nothing():
    """The round's screens of a branch (chi_p 0.04, tau_p 2.8 s) under unipolar pulses
    (fresh lab_fine draw, seed 635608772, dataset 10): its first step, at the baseline's
    level, predicted 1.6 % of the best chi-square fall and the share (SCREEN_REL) left it
    out; a nominal t_lz was kept at 2.6 noises. When no accepted fit of the shortlist gets
    the worst error below STRONG_ERROR noises, the LATE_TOP best strong screens it left out
    are fitted too (judged by a few evaluations); the weak ones never, and none when a
    shortlisted fit explains the mismatch or the mismatch was not large."""
    from types import SimpleNamespace as NS
    from diagnosis.rounds import _cut_strong, _queue, shortlist
    from diagnosis.rules import LATE_TOP, STRONG_ERROR

    def sc(chi2, pdb, ratio):
        return {"chi2_reduction": chi2, "predicted_delta_bic": pdb, "heldout_ratio": ratio}
    screens = {"stiffness": sc(265070, -10761, 0.922), "inertia": sc(1721, -38.6, 1.001),
               "field_dependent_resistivity (Eq. 21)": sc(117951, -3756, 1.262),
               "field_dependent_resistivity (spline)": sc(0.0, 9.5, 1.0), "polarization_branch": sc(6110, -152, 1.017),
               "series_resistance": sc(0.0, 9.5, 1.0), "nominal:t_lz": sc(371101, -19930, 0.502),
               "nominal:rho_f": sc(183588, -6446, 1.002), "nominal:eps_r_l": sc(354296, -17988, 0.799),
               "nominal:b": sc(7003, -187, 1.001)}
    listed = shortlist(screens, strong=True)
    assert "polarization_branch" not in listed and "nominal:t_lz" in listed
    assert _cut_strong(screens, listed) == ["nominal:b", "polarization_branch", "inertia"][:LATE_TOP]
    sigma = 2.52e-6
    current = NS(bic=0.0, heldout_rmse=13.4e-6, train_rmse=15.0e-6, sigma=sigma)
    t_lz = NS(bic=-20258.0, heldout_rmse=6.64e-6, train_rmse=6.63e-6, sigma=sigma)     # accepted, 2.6 noises
    fits = {}
    order = []
    for key, late in _queue(listed, screens, fits, current, True):
        order.append((key, late))
        if key == "nominal:t_lz":
            fits[key] = t_lz
    assert [k for k, late in order if not late] == listed
    assert [k for k, late in order if late] == _cut_strong(screens, listed)
    # a shortlisted fit below STRONG_ERROR noises, or no large mismatch to begin with: no late fits
    near = NS(bic=-30000.0, heldout_rmse=0.9 * STRONG_ERROR * sigma, train_rmse=2.5e-6, sigma=sigma)
    assert all(not late for _, late in _queue(listed, screens, {"nominal:t_lz": near}, current, True))
    assert all(not late for _, late in _queue(listed, screens, {"nominal:t_lz": t_lz}, current, False))
    # nothing weak: a screen under BIC_MIN is not among them
    screens["inertia"] = sc(1721, -5.0, 1.001)
    assert "inertia" not in _cut_strong(screens, listed)
    # report.json's `unexplained.tried` says which fits came late
    from diagnosis.report import tried
    rounds = [{"polarization_branch": {"fitted": True, "late": True, "heldout_rmse": 2.75e-6, "train_rmse": 4.4e-6,
                                       "delta_bic": -31777.0},
               "nominal:t_lz": {"fitted": True, "heldout_rmse": 6.64e-6, "train_rmse": 6.63e-6, "delta_bic": -20258.0}}]
    rows = tried(NS(rounds=rounds))
    assert rows["polarization_branch"]["late"] and "late" not in rows["nominal:t_lz"]


def test_a_training_error_far_above_the_noise_is_unexplained():
    """A held-out condition between the trained ones can reach the noise while the model
    misses the trained ones (a stiffness of 44 N/m under loads of 2, 6 and 7 N, the 6 N
    held out: 3.05 um held out, 27 um in training, 2.64 um noise): not "no missing
    physics found" but an unexplained mismatch in training, and its strong screens are
    fitted (rules._worst_error). Within the noise both ways: explained."""
    from types import SimpleNamespace as NS
    from diagnosis.report import conclusion, unexplained
    sigma = 2.64e-6

    def D(held, train):
        f = NS(heldout_rmse=held, train_rmse=train, sigma=sigma, timing={}, heldout=["V6kV_F6N_r1"])
        return dg.Diagnosis(dataset=NS(recordings=[]), baseline=f, final=f, kept=[], rounds=[], windows=[],
                            trends=[], wall_time=0.0)
    d = D(3.05e-6, 27e-6)
    assert d.unexplained and d.unexplained_by == (27e-6, "training")
    text = conclusion(d)
    assert text.startswith("unexplained mismatch") and "training stroke RMSE of 27 um" in text
    assert "held out 3.05 um" in text and "no missing physics found" not in text
    assert unexplained(d)["measure"] == "training"
    assert dg._worst_error(d.final) == 27e-6 >= dg.STRONG_ERROR * sigma
    # the held-out error decides first when it is itself unexplained
    assert D(6e-6, 27e-6).unexplained_by == (6e-6, "held-out")
    ok = D(3.05e-6, 3.4e-6)
    assert not ok.unexplained and conclusion(ok).startswith("no missing physics found")
    assert dg._worst_error(ok.final) < dg.STRONG_ERROR * sigma


def test_a_fitted_sensor_zero_is_told_as_blind_to_a_stiffness():
    """Under reset + hold without a rest stretch the model never rests on its stop, so
    each sensor zero is fitted and takes up a constant stroke offset: a stiffness of
    41.7 N/m was missed so and named with a 0.5 s rest stretch (lab rig). The verdict
    says so when every zero was fitted; a recording whose model rests on the stop for
    REST_MIN samples or more reads its zero and is not listed."""
    from types import SimpleNamespace as NS
    import numpy as np
    from diagnosis.fit import REST_MIN
    from diagnosis.report import conclusion, zeros_fitted
    t = np.arange(0, 2.0, 1e-3)
    moving = 1e-3 * (1 - np.exp(-t / 0.01)) + 5e-6              # starts with the drive (offset 5 um)
    rests = np.where(t < 0.1, 0.0, 1e-3) - 3e-6                  # 100 samples at rest first (offset -3 um)
    recs = [NS(name=k, switches=np.zeros(0), levels=(6000.0,), duration=20.0) for k in "ab"]   # one DC stretch

    def D(sims):
        f = NS(heldout_rmse=2e-6, train_rmse=2e-6, sigma=2e-6, timing={}, heldout=["b"],
               simulated=dict(zip("ab", sims)), offsets={"a": 5e-6 if sims[0] is moving else -3e-6,
                                                           "b": 5e-6 if sims[1] is moving else -3e-6})
        return dg.Diagnosis(dataset=NS(recordings=recs), baseline=f, final=f, kept=[], rounds=[], windows=[],
                            trends=[], wall_time=0.0)
    blind = D([moving, moving])
    assert zeros_fitted(blind) == ["a", "b"] and "a stiffness is hard to tell" in conclusion(blind)
    half = D([moving, rests])
    assert zeros_fitted(half) == ["a"] and "hard to tell" not in conclusion(half)
    assert np.count_nonzero(rests + 3e-6 <= 0) >= REST_MIN


def test_a_drive_that_never_holds_a_polarity_is_told_as_blind_to_the_charge():
    """Under a polarity inversion throughout (1 Hz: 0.5 s a polarity) the interface charge
    stays near zero, and the lab rig's field laws and branch left their baselines within
    1.1 noises: the verdict says so when every recording is such a drive and neither is
    named. A reset + hold (its 10 s DC), unipolar pulses then DC, and a staircase (one
    polarity over its steps) hold a polarity long enough; pauses at 0 V split nothing."""
    from types import SimpleNamespace as NS
    import numpy as np
    from diagnosis.report import HOLD_MIN, charge_hidden, conclusion, longest_hold

    def rec(name, switches, levels, T):
        return NS(name=name, switches=np.array(switches, float), levels=tuple(levels), duration=T)
    inv = rec("inv", np.arange(0.5, 23.0, 0.5), [6000.0 * (-1) ** k for k in range(46)], 23.0)
    reset_hold = rec("rh", np.arange(1 / 60, 3.0, 1 / 60), [6000.0 * (-1) ** k for k in range(180)], 23.0)
    unipolar = rec("uni", [0.25, 0.5, 0.75, 1.0], [5000.0, 0.0, 5000.0, 0.0, 5000.0], 11.0)
    stair = rec("stair", [1.5, 3.0], [3000.0, 4500.0, 6000.0], 4.5)
    paused = rec("paused", [1.0, 1.05, 2.0], [6000.0, 0.0, 6000.0, -6000.0], 3.0)   # the reader's 0 V pause
    assert longest_hold(inv) == pytest.approx(0.5) and longest_hold(reset_hold) == pytest.approx(20.0, abs=0.02)
    assert longest_hold(unipolar) == pytest.approx(10.0) and longest_hold(stair) == pytest.approx(4.5)
    assert longest_hold(paused) == pytest.approx(1.0) and 1.0 < HOLD_MIN     # a 0 V pause ends a stretch

    def D(recs, kept=()):
        f = NS(heldout_rmse=2e-6, train_rmse=2e-6, sigma=2e-6, timing={}, heldout=[recs[-1].name],
               simulated={}, offsets={})
        return dg.Diagnosis(dataset=NS(recordings=recs), baseline=f, final=f, kept=list(kept), rounds=[],
                            windows=[], trends=[], wall_time=0.0)
    blind = D([inv, paused])
    assert charge_hidden(blind) == ["inv", "paused"] and "record a DC hold" in conclusion(blind)
    mixed = D([inv, reset_hold])
    assert charge_hidden(mixed) == ["inv"] and "DC hold" not in conclusion(mixed)
    assert charge_hidden(D([unipolar, stair])) == []
    law = NS(name="field_dependent_resistivity", kind="physics", key="field_dependent_resistivity", variant="")
    assert "DC hold" not in conclusion(D([inv, paused], kept=[law]))


def test_the_headline_speed_needs_a_hold():
    """The paper's headline metric is the unzipping speed over the DC hold. A polarity
    inversion throughout reads as a reset with a hold of a few ms: no row for it (it had
    reported speeds of -6 um/s with a spread of 73), while a 10 s hold has its row."""
    from types import SimpleNamespace as NS
    import numpy as np
    from diagnosis.report import headline
    t = np.arange(0.0, 13.0, 1e-3)
    x = 1e-3 - 2e-5 * np.clip(t - 3.0, 0.0, None)          # creeping at 20 um/s after a 3 s reset

    def D(reset_end):
        recs = [NS(name=f"r{i}", t=t, stroke=x + 1e-6 * i, reset_end=reset_end, duration=float(t[-1]))
                for i in range(3)]
        ds = NS(recordings=recs, conditions=lambda: {(6000.0, 5.0): recs})
        base = NS(simulated={r.name: x for r in recs})
        return NS(dataset=ds, baseline=base, final=base, improved=False)
    rows = headline(D(3.0))
    assert len(rows) == 1 and rows[0]["speed_measured"] == pytest.approx(20e-6, rel=0.01)
    assert headline(D(float(t[-1]) - 0.03)) == []


def test_a_stopped_search_resumes_exactly_where_it_stopped(null):
    """A fit stopped by max_nfev and resumed (fit(resume=...)) goes on from its own end:
    its globals, its recordings' factors as they were (not less a condition's mean, as a
    warm start takes them) and its timing. Resumed for one evaluation it cannot step and
    returns the same cost; resumed to the budget it ends where one search with that
    budget ends; its runs and time count the first part too."""
    from diagnosis.catalog import PHYSICS
    from diagnosis.fit import fit
    D = null[0]
    e = next(x for x in PHYSICS if x.key == "stiffness")
    p = e.prepare(D.baseline.params, D.context)
    spec = dg._spec(p, D.context, [e])
    start = p.replace(**e.starts(p, D.context)[-1])
    short = fit(D.dataset, spec, base=start, warm=D.baseline, max_nfev=3)
    assert not short.converged
    same = fit(D.dataset, spec, warm=D.baseline, max_nfev=1, resume=short)
    assert same.cost == pytest.approx(short.cost, rel=1e-9)
    assert same.runs > short.runs and same.wall_time > short.wall_time
    on = fit(D.dataset, spec, warm=D.baseline, max_nfev=12, resume=short)
    whole = fit(D.dataset, spec, base=start, warm=D.baseline, max_nfev=15)
    assert on.cost < short.cost
    assert on.cost == pytest.approx(whole.cost, rel=0.02)
    assert on.values["k"] == pytest.approx(whole.values["k"], rel=0.05, abs=0.5)


def test_several_starts_race_a_few_evaluations_and_the_leader_goes_on(monkeypatch):
    """_multistart: with several starts each fit runs START_NFEV evaluations; the one of
    least cost (not the first, not the last) is resumed to CANDIDATE_NFEV in all; a start
    the model cannot run is an error in the evidence, not the end; racing starts skip the
    held-out recordings (compared by cost), so even a leader that converged goes on for
    its held-out fit, and a leader whose resumed search fails is no fit at all (never one
    without held-out evidence); a single start gets the whole budget at once, held out
    included. A form fitted only because the mismatch is large (a judge) is probed even
    from one start, with its held-out recordings, and goes on only if the judge passes it;
    _probe_passes asks a held-out fall of SCREEN_HELDOUT."""
    from types import SimpleNamespace as NS

    calls = []
    costs = {1.0: 5.0, 2.0: 3.0, 3.0: 4.0}

    held = []

    def fake_fit(dataset, spec, base=None, max_nfev=None, resume=None, held_out=True, **kw):
        calls.append((None if base is None else base["a"], max_nfev, resume))
        held.append(held_out)
        if resume is not None:
            if resume.name == 4.0:
                raise ValueError("the resumed search failed")
            return NS(cost=resume.cost / 2, converged=True, name="resumed")
        if base["a"] == 9.0:
            raise ValueError("the model does not run there")
        return NS(cost=costs[base["a"]], converged=base.get("done", False), name=base["a"])

    patch(monkeypatch, "fit", fake_fit)

    class P(dict):
        def replace(self, **kw):
            return P({**self, **kw})
    p = P(a=0.0)
    race = lambda starts, judge=None: dg._multistart(None, [], p, starts, None, None, None, judge)  # noqa: E731
    best, errors, stopped = race([{"a": 1.0}, {"a": 2.0}, {"a": 9.0}, {"a": 3.0}])
    assert [c[1] for c in calls[:4]] == [dg.START_NFEV] * 4
    assert calls[4][1] == dg.CANDIDATE_NFEV - dg.START_NFEV and calls[4][2].name == 2.0
    assert best.name == "resumed" and best.cost == 1.5 and len(errors) == 1 and "does not run" in errors[0]
    assert not stopped and held == [False] * 4 + [True]
    calls.clear()
    held.clear()
    best, _, stopped = race([{"a": 1.0}, {"a": 2.0, "done": True}])
    assert best.name == "resumed" and calls[-1][2].name == 2.0 and held == [False, False, True] and not stopped
    costs[4.0] = 1.0
    best, errors, _ = race([{"a": 1.0}, {"a": 4.0}])
    assert best is None and "failed" in errors[-1]
    calls.clear()
    held.clear()
    best, _, _ = race([{"a": 3.0}])
    assert calls == [(3.0, dg.CANDIDATE_NFEV, None)] and best.name == 3.0 and held == [True]
    # judged: probed from its one start, stopped there or resumed as the judge says
    calls.clear()
    held.clear()
    best, _, stopped = race([{"a": 3.0}], judge=lambda f: False)
    assert calls == [(3.0, dg.START_NFEV, None)] and best.name == 3.0 and stopped and held == [True]
    calls.clear()
    best, _, stopped = race([{"a": 1.0}, {"a": 3.0}], judge=lambda f: f.name == 3.0)
    assert [c[1] for c in calls] == [dg.START_NFEV, dg.START_NFEV, dg.CANDIDATE_NFEV - dg.START_NFEV]
    assert best.name == "resumed" and not stopped
    # the judge passes only the costlier start: that one goes on
    calls.clear()
    best, _, stopped = race([{"a": 2.0}, {"a": 1.0}], judge=lambda f: f.name == 1.0)
    assert calls[-1][2].name == 1.0 and best.name == "resumed" and not stopped
    ref = NS(heldout_rmse=1.0)
    assert dg._probe_passes(NS(heldout_rmse=1.0 - dg.SCREEN_HELDOUT), ref)
    assert not dg._probe_passes(NS(heldout_rmse=1.0 - 0.5 * dg.SCREEN_HELDOUT), ref)
    assert dg._probe_passes(NS(heldout_rmse=None), ref)


def test_the_data_choose_the_spline_knots(monkeypatch):
    """Issue 24, item 2: the spline law's complexity is the data's choice. From the fitted
    two-knot law, each fit adds a knot, starts from the last law resampled (so it starts
    where that one ended) and is kept while the BIC falls by more than SHAPE_BIC; the
    search and its steps go into the evidence. Here the fake fits' BIC falls steeply to 4
    knots and then by less than SHAPE_BIC: 4 knots are kept and the 5-knot fit ends the
    search (checked here with stand-in fits; the real fits in test_improved_spline.py)."""
    from types import SimpleNamespace as NS

    from diagnosis.catalog import PHYSICS, Context
    entry = next(e for e in PHYSICS if e.variant == "spline")
    nominal = preset("vshape-table1").replace(N=11)
    ctx = Context(7000.0, 6000.0, 6e7)
    bic = {2: 0.0, 3: -40.0, 4: -60.0, 5: -60.0 + 0.5 * dg.SHAPE_BIC, 6: -200.0}
    starts = []

    def fake_fit(dataset, spec, base, **kw):
        starts.append(base)
        assert [f.key for f in spec[-(base.n_knots - 1):]] == [f"d_rho{k}" for k in range(1, base.n_knots)]
        return NS(params=base.replace(d_rho1=base.d_rho1 + 0.1), bic=bic[base.n_knots], heldout_rmse=1e-6, sigma=1e-7)

    patch(monkeypatch, "fit", fake_fit)
    p2 = entry.prepare(nominal, ctx).replace(d_rho1=1.0)
    assert p2.law == "spline" and p2.n_knots == 2
    first = NS(params=p2, bic=bic[2], heldout_rmse=2e-6, sigma=1e-7)
    search = lambda rivals=(): dg._more_shape(None, entry, first, lambda q: entry.spec(q, ctx), ctx,  # noqa: E731
                                              None, None, lambda s: None, rivals)
    best, steps = search()
    assert best.params.n_knots == 4 and [s["n_knots"] for s in steps] == [2, 3, 4, 5]
    assert [s["delta_bic"] for s in steps] == [0.0, -40.0, -60.0, bic[5]]
    # each fit starts from the last kept law through one knot more, passing through it at the knots
    from dfa_model.physics.dielectrics import from_parameters
    prev = p2
    for q in starts:
        E, r = from_parameters(q).knots
        assert np.allclose(r, from_parameters(prev).rho(E), rtol=1e-9)
        prev = q.replace(d_rho1=q.d_rho1 + 0.1)
    # a rival form of the entry that fits better and leaves the error at the noise: more
    # knots could only fit noise, so there is no search (a rival worse than the form, or
    # one above the noise, does not stop it)
    starts.clear()
    assert search([NS(bic=-1.0, heldout_rmse=1.05e-7, sigma=1e-7)]) == (first, []) and not starts
    assert search([NS(bic=+1.0, heldout_rmse=1.05e-7, sigma=1e-7)])[0].params.n_knots == 4
    assert search([NS(bic=-1.0, heldout_rmse=3e-7, sigma=1e-7)])[0].params.n_knots == 4
    # a first form the model it is fitted on top of would not accept (a held-out fall under
    # HELDOUT_MIN) starts no search: its knots would only bend it to another entry's effect;
    # an accepted one does
    search_on = lambda current: dg._more_shape(None, entry, first, lambda q: entry.spec(q, ctx), ctx,  # noqa: E731
                                               None, None, lambda s: None, (), current)
    starts.clear()
    held = 2e-6 / (1 - 0.5 * dg.HELDOUT_MIN)
    assert search_on(NS(bic=bic[2] + 100.0, heldout_rmse=held)) == (first, []) and not starts
    assert search_on(NS(bic=bic[2] + 100.0, heldout_rmse=2e-6 / (1 - 2 * dg.HELDOUT_MIN)))[0].params.n_knots == 4
    assert search_on(NS(bic=bic[2] + 0.5 * dg.BIC_MIN, heldout_rmse=1e-5)) == (first, [])


def test_a_job_carries_evenly_spaced_sample_times_in_three_numbers():
    """A run's job carries a 1 kHz recording's times as (t0, dt, n): a Dask scheduler had
    warned of a 21.6 MiB graph at every batch of 150 recordings. The times it rebuilds are
    the recording's within 1e-9 of a sample; uneven times travel as they are."""
    import pickle

    from diagnosis.fit import _times, sample_times
    t = np.arange(23001) * 1e-3 - 0.1
    spec = sample_times(t)
    assert isinstance(spec, tuple) and len(pickle.dumps(spec)) < 100
    assert np.max(np.abs(_times(spec) - t)) < 1e-12
    uneven = t.copy()
    uneven[100] += 2e-4
    assert sample_times(uneven) is not None and np.array_equal(_times(sample_times(uneven)), uneven)


def test_a_large_batch_of_runs_goes_in_few_tasks_in_order():
    """More runs than TASKS go to the executor in chunks (a scheduler's per-task cost), and
    come back in the order of the jobs."""
    import importlib
    F = importlib.import_module("diagnosis.fit")

    class Counting:
        tasks = 0

        def map(self, fn, items):
            items = list(items)
            Counting.tasks += len(items)
            return map(fn, items)

    calls = []
    real = F._run
    try:
        F._run = lambda job: calls.append(job) or job * 10
        out = F.Runner(Counting())(list(range(150)))
    finally:
        F._run = real
    assert out == [10 * j for j in range(150)] and calls == list(range(150))
    assert F.TASKS <= Counting.tasks <= 2 * F.TASKS


def test_entries_neutral_on_a_bound_start_off_it_too():
    """A stiffness, a mass and a branch are neutral at 0, on their bound, where the fit is
    not convex (the lab rig's k = 49 N/m: from 0 the search stayed at 0, or stopped at
    5 N/m above the baseline's cost; from 44 N/m it reached 36 N/m): each is fitted from
    the neutral point where it has one and from a start off the bound within its bounds,
    and the screen probes that start as well."""
    from diagnosis.catalog import PHYSICS, Context
    from diagnosis.screen import probes
    p = preset("vshape-table1").replace(N=21)
    ctx = Context(V_max=7000.0, V_ref=6000.0, E_ref=5.84e7)
    for name, key in (("stiffness", "k"), ("inertia", "m"), ("polarization_branch", "chi_p")):
        e = next(x for x in PHYSICS if x.name == name)
        spec = {f.key: f for f in e.spec(p, ctx)}
        off = [st for st in e.starts(p, ctx) if st.get(key, 0.0) > 0]
        assert off, name
        for st in off:
            lo, hi = spec[key].z_bounds()
            assert lo < spec[key].to_z(st[key]) < hi, (name, st)
        assert any(getattr(q, key) == off[0][key] and one_sided for q, one_sided in probes(e, p, ctx)), name


def test_a_window_all_on_one_side_reads_so_in_the_report():
    """locate.runs_z gives -inf for a window whose residuals all lie on one side (the
    most systematic a window can be); report.md says that rather than '-inf'."""
    import math
    import numpy as np
    from diagnosis.locate import runs_z
    from diagnosis.report import _runs_text
    assert runs_z(np.full(50, 1e-6)) == -math.inf
    assert _runs_text(runs_z(np.full(50, 1e-6))) == "all one sign"
    assert _runs_text(-3.21) == "-3.2"


def test_an_entry_that_fits_only_the_trained_conditions_is_said_so():
    """report.training_only: a tried entry at the noise in training but worse held out
    than the final model (a knee between the trained voltages, under inversion) is listed;
    one that is not at the noise, or that predicts the held-out ones better, is not."""
    from diagnosis.report import training_only
    s = 1.42e-6
    rows = {"law": {"fitted": True, "train_rmse": 1.77e-6, "heldout_rmse": 8.38e-6},
            "spring": {"fitted": True, "train_rmse": 4.0e-6, "heldout_rmse": 9.0e-6},      # 2.8 noises in training
            "branch": {"fitted": True, "train_rmse": 1.5e-6, "heldout_rmse": 4.0e-6},      # better held out
            "mass": {"fitted": False, "why": "not shortlisted"}}
    out = training_only(rows, s, 4.79e-6)
    assert [r["candidate"] for r in out] == ["law"]
    assert training_only(rows, s, None) == []


def test_each_recording_gets_its_own_protocol_file_even_with_a_dot_in_its_name(tmp_path):
    """Recordings are named by their files' stems; a voltage written 6.5kV put a dot in
    them, and cutting a suffix off again wrote every recording's protocol to V6.toml."""
    from pathlib import Path
    from types import SimpleNamespace

    from dfa_model.io.recordings import Recording, _drive
    from dfa_model.waveforms import Load, Protocol
    from diagnosis.improved import write_protocols
    recs = []
    for F in (1.0, 2.0):
        t = np.arange(0.0, 2.0005, 1e-3)
        r = Recording(f"V6.5kV_F{F:g}N_r1", Path(f"V6.5kV_F{F:g}N_r1.csv"), t, t * 0, t * 0, t * 0, None,
                      np.arange(t.size))
        r.switches, r.levels, r.load = np.array([0.5]), (0.0, 6500.0), Load(F)
        _drive(r)
        recs.append(r)
    paths = write_protocols(SimpleNamespace(dataset=SimpleNamespace(recordings=recs)), tmp_path)
    assert paths == {r.name: f"protocols/{r.name}.toml" for r in recs}
    for r in recs:
        assert Protocol.from_toml(tmp_path / paths[r.name]).load.F == pytest.approx(r.load.F)
