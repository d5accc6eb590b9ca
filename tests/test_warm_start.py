"""Where a fit's per-recording nuisances start (fit._start_nuisances, rounds._multistart):
as the warm fit left them from a candidate's nested start and for a refit of the same
model, less each condition's mean only from a start away from the nested model. An Eq. (21)
law's nested start beside a series resistance had cost 87390 against the warm fit's 30309
with the means removed, and its search ended with a BIC 7751 above the model it extends."""
import importlib
import math
from types import SimpleNamespace as NS

fitmod = importlib.import_module("diagnosis.fit")        # the module (the package exports the function)
rounds = importlib.import_module("diagnosis.rounds")


def _recs():
    return [NS(name=f"c{c}_r{r}", condition=(lambda c=c: (6000.0, float(c)))) for c in (4, 6) for r in (1, 2)]


WARM = NS(rho_factors={"c4_r1": 0.96, "c4_r2": 0.98, "c6_r1": 1.04, "c6_r2": 1.02}, timing={"c4_r1": {"gain": 1e-3}})


def test_the_warm_fits_factors_as_they_are_unless_demeaned():
    recs = _recs()
    d, tm = fitmod._start_nuisances(WARM, None, recs)
    assert d == [math.log(WARM.rho_factors[r.name]) for r in recs] and tm is WARM.timing
    dm, _ = fitmod._start_nuisances(WARM, None, recs, demean=True)
    for c in ((0, 1), (2, 3)):                     # each condition's mean taken out
        assert abs(dm[c[0]] + dm[c[1]]) < 1e-12
        assert abs(dm[c[0]] - (d[c[0]] - 0.5 * (d[c[0]] + d[c[1]]))) < 1e-12
    assert fitmod._start_nuisances(None, None, recs, demean=True) == (None, None)


def test_only_starts_away_from_the_nested_model_are_demeaned(monkeypatch):
    seen = []

    def fake_fit(dataset, spec, base=None, **kw):
        seen.append((base, kw["demean"]))
        return NS(cost=float(len(seen)), converged=True, heldout_rmse=None)

    monkeypatch.setattr(rounds, "fit", fake_fit)
    p = NS(replace=lambda **k: ("moved", tuple(sorted(k))))
    rounds._multistart(None, [], p, [{}, {"s_rho": -3.0}], None, None, WARM)
    assert seen[0] == (p, False) and seen[1] == (("moved", ("s_rho",)), True)
