"""Proof on concealed effects: for every catalog entry, and for two entries at once, a
synthetic dataset whose truth has the effect (dfa_model.synthetic: 1 um sensor noise,
0.5 um quantization, 5 um zero offsets, 5 % rho_l spread between repetitions, nominal
rho_l 3e12 against a true 2e12). The effect is concealed: after the baseline fit, the
error in the paper's headline metric (average unzipping speed over the hold) lies within
the repetitions' spread in every condition. Without being told the truth, the diagnosis
must name the entry, recover its parameters within the stated tolerances, and cut the
held-out RMSE by at least half.

Size (for CI): N = 21 (truth and fit share it), 3 conditions x 3 repetitions. Protocol: the
paper's (3 s reset at 30 Hz, 20 s hold) for the effects that need the hold's length to
show beside the repetition scatter (a stiffness: the baseline trades its static offset
for unzipping speed over a hold, the less the longer; a field law: the liquid's field
decays over the hold), a 1 s reset and a 10 s hold for the others.
Tolerances are what the fit reaches at this size and noise, not what a textbook promises:
the parameter's own scatter over seeds is several of its standard errors (the residual
switch-timing error of 1 kHz voltage samples is not in the noise model)."""
from __future__ import annotations

import numpy as np
import pytest

import diagnosis
from dfa_model import preset
from dfa_model.dielectrics import from_parameters
from dfa_model.recordings import read_dataset
from dfa_model.synthetic import Measurement, generate_dataset
from diagnosis.fit import local_executor

NOMINAL = preset("vshape-table1").replace(N=21, rho_l=3e12)
TRUTH = NOMINAL.replace(rho_l=2e12)
LOADS = [(6000.0, 3.0), (6000.0, 5.0), (6000.0, 7.0)]
VOLTS = [(5000.0, 5.0), (6000.0, 5.0), (7000.0, 5.0)]
RESET_HZ = 30.0
PAPER, SHORT = (3.0, 20.0), (1.0, 10.0)    # (reset, hold) in s
E6 = 5.84e7      # the zipped liquid's field at 6 kV (V/m)

# entry: (truth changes, conditions, {key: (true value, relative tolerance)}, protocol)
CASES = {
    "stiffness": ({"k": 20.0}, VOLTS, {"k": (20.0, 0.15)}, PAPER),
    "inertia": ({"m": 0.05}, LOADS, {"m": (0.05, 0.05)}, SHORT),
    "polarization_branch": ({"chi_p": 0.01, "tau_p": 1.0}, LOADS, {"chi_p": (0.01, 0.1), "tau_p": (1.0, 0.2)}, SHORT),
    "series_resistance": ({"R_s": 1e6}, LOADS, {"R_s": (1e6, 0.05)}, SHORT),
    # Eq. (21) with an eighth of the paper's slope, rho_l 2e12 at the zipped field of 6 kV
    "field_dependent_resistivity": ({"law": "linear", "q_rho": 2e12 + 4e4 * E6, "m_rho": -4e4}, VOLTS, {}, PAPER),
}


def run(tmp_path_factory, name, changes, conditions, protocol=SHORT, seed=21):
    folder = tmp_path_factory.mktemp(name)
    truth = TRUTH.replace(**changes)
    reset, hold = protocol
    generate_dataset(folder / "data", truth, NOMINAL, conditions, repetitions=3, reset=reset, hold=hold,
                     reset_frequency=RESET_HZ, measurement=Measurement(noise=1e-6, rho_spread=0.05), seed=seed)
    ex = local_executor(2)
    try:
        D = diagnosis.diagnose(read_dataset(folder / "data"), executor=ex)
    finally:
        ex.shutdown()
    return D, diagnosis.write_report(D, folder / "out"), truth, folder / "out"


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


def check_found_and_improved(report):
    """What holds in every case: a systematic mismatch located, and the kept physics cuts
    the held-out error by more than the diagnosis' own threshold (10 %)."""
    assert report["mismatch"] and report["located"]
    base, imp = report["fit"]["baseline"], report["fit"]["improved"]
    assert imp["heldout_rmse"] < 0.9 * base["heldout_rmse"]


@pytest.mark.parametrize("entry", list(CASES))
def test_concealed_entry_is_named_recovered_and_proved(tmp_path_factory, entry):
    changes, conditions, expected, protocol = CASES[entry]
    D, report, truth, out = run(tmp_path_factory, entry, changes, conditions, protocol)
    names = [m["name"] for m in report["missing_physics"]]
    assert names == [entry], (names, report["candidates"])
    check_found_and_improved(report)
    fitted = report["missing_physics"][0]["parameters"]
    for key, (value, tol) in expected.items():
        assert fitted[key]["value"] == pytest.approx(value, rel=tol), (key, fitted[key])
    if entry == "field_dependent_resistivity":
        # whichever form was chosen, the fitted law follows the truth's over the fields the
        # liquid next to the front sees in these recordings: the zipped field at 5-7 kV,
        # falling by ~20 % over a 20 s hold as the interface charges (the truth runs from
        # 2.9e12 to 1.3e12 ohm m there; the baseline's constant law is off by up to 50 %)
        E = np.linspace(0.8 * 5 / 6 * E6, 7 / 6 * E6, 9)
        rho_fit = from_parameters(D.final.params).rho(E)
        rho_true = from_parameters(truth).rho(E)
        mean_factor = np.exp(np.mean([np.log(f) for f in D.final.rho_factors.values()]))
        dev = np.abs(rho_fit * mean_factor / rho_true - 1)
        assert dev.max() < 0.10, (E, rho_fit, rho_true)
    assert (out / "fitted_terms.png").is_file()
    assert not goal_misses(report), goal_misses(report)


def test_two_concealed_effects_are_both_named(tmp_path_factory):
    D, report, truth, out = run(tmp_path_factory, "combined", {"R_s": 1e6, "chi_p": 0.01, "tau_p": 1.0}, LOADS)
    names = [m["name"] for m in report["missing_physics"]]
    assert sorted(names) == ["polarization_branch", "series_resistance"], (names, report["candidates"])
    check_found_and_improved(report)
    assert not goal_misses(report)
    fitted = {k: v["value"] for m in report["missing_physics"] for k, v in m["parameters"].items()}
    assert fitted["R_s"] == pytest.approx(1e6, rel=0.1)
    assert fitted["chi_p"] == pytest.approx(0.01, rel=0.2)
