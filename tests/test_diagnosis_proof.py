"""Proof on concealed effects (diagnosis.proofs: the designs): for every catalog entry,
and for two entries at once, a synthetic dataset whose truth has the effect, concealed
in the paper's headline metric. Without being told the truth, the diagnosis must name
the entry, recover its parameters within the stated tolerances, and cut the held-out
RMSE by at least half.

Size (for CI): N = 21 (truth and fit share it), seed 21. Tolerances are what the fit
reaches at this size and noise, not what a textbook promises: the parameter's own scatter
over seeds is several of its standard errors (the residual switch-timing error of 1 kHz
voltage samples is not in the noise model). The null and wrong-nominal designs are in
tests/test_diagnosis.py."""
from __future__ import annotations

import numpy as np
import pytest

from dfa_model.physics.dielectrics import from_parameters
from diagnosis.rules import HELDOUT_MIN, MAX_ROUNDS
from diagnosis.proofs import CASES, E6, run
from improved_support import check_improved

ENTRIES = ["stiffness", "inertia", "polarization_branch", "series_resistance", "field_dependent_resistivity",
           "combined"]


def goal_misses(report) -> list:
    """The proof's two goals, checked together: concealed (the baseline's headline error
    within the repetition spread in every condition) and proved (held-out RMSE at most
    half the baseline's). Returns what is missed."""
    misses = [f"not concealed at {h['voltage'] / 1e3:g} kV, {h['force']:g} N: baseline error "
              f"{h['speed_error_baseline'] * 1e6:+.2f} um/s, spread {h['speed_spread'] * 1e6:.2f} um/s"
              for h in report["headline"] if not h["concealed"]]
    base, imp = report["fit"]["baseline"], report["fit"]["improved"]
    if imp["heldout_rmse"] > 0.5 * base["heldout_rmse"]:
        misses.append(f"held-out RMSE {base['heldout_rmse'] * 1e6:.2f} -> {imp['heldout_rmse'] * 1e6:.2f} um, "
                      f"not halved")
    return misses


@pytest.mark.parametrize("name", ENTRIES)
def test_concealed_effect_is_named_recovered_and_proved(tmp_path, name):
    case = CASES[name]
    D, report, truth = run(name, tmp_path)
    names = [m["name"] for m in report["missing_physics"]]
    assert sorted(names) == sorted(case.expected), (names, report["candidates"])
    assert report["mismatch"] and report["located"]
    fitted = {k: v["value"] for m in report["missing_physics"] for k, v in m["parameters"].items()}
    for key, (value, tol) in case.tolerances.items():
        assert fitted[key] == pytest.approx(value, rel=tol), (key, fitted[key])
    if name == "field_dependent_resistivity":
        # whichever form was chosen, the fitted law follows the truth's over the fields the
        # liquid next to the front sees in these recordings: the zipped field at 5-7 kV,
        # falling by ~20 % over a 20 s hold as the interface charges (the truth runs from
        # 2.9e12 to 1.3e12 ohm m there; the baseline's constant law is off by up to 50 %),
        # within 10 % once the repetitions' mean resistivity factor is applied
        E = np.linspace(0.8 * 5 / 6 * E6, 7 / 6 * E6, 9)
        rho_fit = from_parameters(D.final.params).rho(E)
        rho_true = from_parameters(truth).rho(E)
        mean_factor = np.exp(np.mean([np.log(f) for f in D.final.rho_factors.values()]))
        assert np.max(np.abs(rho_fit * mean_factor / rho_true - 1)) < 0.10, (E, rho_fit, rho_true)
    assert (tmp_path / "out" / "fitted_terms.png").is_file()
    assert not goal_misses(report), goal_misses(report)
    # no round is run beyond reach: after the round whose kept model leaves the held-out
    # error within 1 / (1 - HELDOUT_MIN) sensor noises (no candidate can cut it by
    # HELDOUT_MIN), none follows; otherwise one more screens and keeps nothing
    if not D.raised and len(D.chain) < MAX_ROUNDS:
        last = D.rounds[len(D.chain) - 1][D.chain[-1].key]["heldout_rmse"]
        reach = (1 - HELDOUT_MIN) * last <= D.baseline.sigma
        assert len(D.rounds) == len(D.chain) + (0 if reach else 1), (last, D.baseline.sigma, len(D.rounds))
    # the improved model as a file every command takes (the FMU for every entry but the
    # combined one, whose two entries are each built alone)
    check_improved(D, report, tmp_path / "out", fmu=name != "combined")
