"""rounds._race: where the screens' one linearized step cannot order the shortlist's
entries (their predicted BIC falls within SCREEN_SKIP of the best one's), each runs
START_NFEV evaluations first and the leaders by cost are fitted first, from where their
probes stopped (rounds._multistart reuses them)."""
from types import SimpleNamespace as NS

from diagnosis_parts import dg, patch


class P(dict):
    def replace(self, **kw):
        return P({**self, **kw})



def _setup(monkeypatch, costs):
    """A fake fit whose cost after a probe is costs[key]; returns the calls made."""
    calls = []

    def fake_fit(dataset, spec, base=None, max_nfev=None, resume=None, held_out=True, **kw):
        calls.append((spec, max_nfev, held_out, None if resume is None else resume.name))
        if resume is not None:
            return NS(cost=resume.cost / 2, converged=True, name="resumed", bic=0.0, train_rmse=1e-6)
        return NS(cost=costs[spec], converged=False, name=spec, bic=costs[spec], train_rmse=2e-6)

    patch(monkeypatch, "fit", fake_fit)
    patch(monkeypatch, "_spec", lambda p, ctx, entries: entries[-1].key)
    return calls


def _prepared(keys):
    return {k: (NS(key=k, starts=None), P(a=0.0)) for k in keys}


def test_entries_the_screens_cannot_order_are_probed_and_the_leader_is_fitted_first(monkeypatch):
    # the combined case's second round: Eq. (21) a hair ahead of the branch by the screen
    listed = ["law (Eq. 21)", "law (spline)", "branch", "t_lz"]
    screens = {"law (Eq. 21)": {"predicted_delta_bic": -17167.0}, "law (spline)": {"predicted_delta_bic": 10.8},
               "branch": {"predicted_delta_bic": -16837.0}, "t_lz": {"predicted_delta_bic": -4766.0}}
    calls = _setup(monkeypatch, {"law (Eq. 21)": 1.2e5, "branch": 8.5e4})
    order, raced = dg._race(None, listed, screens, _prepared(listed), [], None, None, None, None,
                            NS(bic=0.0), lambda s: None, 1)
    # the branch led after START_NFEV evaluations: it goes first; the law's forms follow it;
    # t_lz (4766: more than SCREEN_SKIP short of the best) was not probed and keeps its place
    assert order == ["branch", "law (Eq. 21)", "law (spline)", "t_lz"]
    assert sorted(raced) == ["branch", "law (Eq. 21)"]
    assert sorted(calls) == [("branch", dg.START_NFEV, False, None), ("law (Eq. 21)", dg.START_NFEV, False, None)]
    # the fit of a probed candidate goes on from its probe, held out included, with no new probe
    calls.clear()
    e, p = _prepared(["branch"])["branch"]
    best, errors, stopped = dg._multistart(None, "branch", p, [{}], None, None, None, None, raced["branch"])
    assert calls == [("branch", dg.CANDIDATE_NFEV - dg.START_NFEV, True, "branch")]
    assert best.name == "resumed" and not errors and not stopped
    rec = dg._race_record(raced["law (Eq. 21)"], NS(bic=2e5))
    assert rec == {"evaluations": dg.START_NFEV, "delta_bic": 1.2e5 - 2e5, "train_rmse": 2e-6}


def test_a_shortlist_the_screens_order_is_left_as_it_is(monkeypatch):
    """One entry within SCREEN_SKIP of the best (forms of one entry compete in full fits
    anyway), or a contender a judge would probe (not shortlisted on its own screen): no
    probe."""
    listed = ["law (Eq. 21)", "law (spline)", "branch"]
    screens = {"law (Eq. 21)": {"predicted_delta_bic": -17167.0}, "law (spline)": {"predicted_delta_bic": -17000.0},
               "branch": {"predicted_delta_bic": -8000.0}}
    calls = _setup(monkeypatch, {})
    order, raced = dg._race(None, listed, screens, _prepared(listed), [], None, None, None, None, NS(bic=0.0),
                            lambda s: None, 0)
    assert order == listed and raced == {} and calls == []
    screens["branch"]["predicted_delta_bic"] = -16837.0
    order, raced = dg._race(None, listed, screens, _prepared(listed), [], None, {"law (Eq. 21)", "law (spline)"},
                            None, None, NS(bic=0.0), lambda s: None, 0)
    assert order == listed and raced == {} and calls == []


def test_a_probe_that_got_further_than_its_screen_is_what_the_skip_rule_weighs():
    screens = {"branch": {"predicted_delta_bic": -100.0}, "law (Eq. 21)": {"predicted_delta_bic": -80.0}}
    current = NS(bic=1000.0)
    raced = {"branch": ([NS(bic=600.0), NS(bic=700.0)], [])}
    assert dg._hope(screens, "branch", raced, current) == -400.0       # the probe's best start
    assert dg._hope(screens, "law (Eq. 21)", raced, current) == -80.0  # not probed: its screen
    raced["law (Eq. 21)"] = ([NS(bic=990.0)], [])
    assert dg._hope(screens, "law (Eq. 21)", raced, current) == -80.0  # the screen hoped for more


def test_a_leader_whose_probe_beats_twice_the_next_screen_spares_its_probe(monkeypatch):
    """The screens' order was right (data made at the fit's own N): the branch's probe fell
    41393, twice Eq. (21)'s screen is 33711 - Eq. (21) is not probed (it would be skipped once
    the branch is accepted near the noise); the order stays the screens'."""
    listed = ["branch", "law (Eq. 21)", "law (spline)"]
    screens = {"branch": {"predicted_delta_bic": -21907.0}, "law (Eq. 21)": {"predicted_delta_bic": -16856.0},
               "law (spline)": {"predicted_delta_bic": 10.8}}
    calls = _setup(monkeypatch, {"branch": 1e5 - 41393.0, "law (Eq. 21)": 1e5})
    order, raced = dg._race(None, listed, screens, _prepared(listed), [], None, None, None, None, NS(bic=1e5),
                            lambda s: None, 1)
    assert order == listed and list(raced) == ["branch"] and [c[0] for c in calls] == ["branch"]
    # a probe that fell less than that: the next one is probed
    calls = _setup(monkeypatch, {"branch": 1e5 - 30000.0, "law (Eq. 21)": 1e5 - 35000.0})
    order, raced = dg._race(None, listed, screens, _prepared(listed), [], None, None, None, None, NS(bic=1e5),
                            lambda s: None, 1)
    assert sorted(raced) == ["branch", "law (Eq. 21)"] and order == ["law (Eq. 21)", "law (spline)", "branch"]
