"""The randomized trial's design (benchmarks/bench_diagnosis_trial.py) and the revealed
sizes it draws from on the lab rig (benchmarks/bench_revealed_sizes.py): which entries are
drawn, at which sizes, and how a revealed size is read off a ladder."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_diagnosis_trial as trial  # noqa: E402
import bench_revealed_sizes as sizes  # noqa: E402


def _size(case):
    t = case["truth"]
    if case["effect"] == "field_dependent_resistivity":
        return -t["m_rho"] if "m_rho" in t else t["s"] * 2e12 / 5.5e7
    return t[trial.RANGES[case["effect"]][0]]


def test_the_ideal_sizes_draw_every_entry_in_turn_within_their_ranges():
    cases = [trial.draw(i, 7) for i in range(24)]
    assert [c["effect"] for c in cases] == [trial.EFFECTS[i % len(trial.EFFECTS)] for i in range(24)]
    for c in cases:
        if c["effect"] != "null":
            _, lo, hi = trial.RANGES[c["effect"]]
            assert lo <= _size(c) <= hi


@pytest.mark.parametrize("drive", sorted(trial.REVEALED_LAB))
def test_the_revealed_sizes_leave_out_what_the_lab_rig_does_not_reveal(drive):
    rng_of = trial.ranges("lab", drive, "revealed")
    hidden = {e for e, v in trial.REVEALED_LAB[drive].items() if v is None}
    assert hidden.isdisjoint(rng_of)
    cases = [trial.draw(i, 11, True, rng_of) for i in range(3 * (len(rng_of) + 1))]
    drawn = {c["effect"] for c in cases}
    assert drawn == {"null", *rng_of}          # each drawn entry and the null, in turn
    for c in cases:
        if c["effect"] != "null":
            v = trial.REVEALED_LAB[drive][c["effect"]]
            assert v * (1 - 1e-9) <= _size(c) <= 4 * v * (1 + 1e-9)


@pytest.mark.parametrize("drive", sorted(trial.REVEALED_FINE))
def test_the_converged_truths_sizes_leave_out_what_it_does_not_reveal(drive):
    """lab_fine's sizes (REVEALED_FINE): every entry it does not reveal is left out, and the
    branch is drawn where BRANCH_TAU_FINE reveals it, at 1-4x its size at the drawn tau_p."""
    rng_of = trial.ranges("lab_fine", drive, "revealed")
    hidden = {e for e, v in trial.REVEALED_FINE[drive].items() if v is None}
    assert hidden.isdisjoint(rng_of)
    taus = trial.branch_sizes("lab_fine", drive)
    assert ("polarization_branch" in rng_of) == bool(taus)
    cases = [trial.draw(i, 13, True, rng_of) for i in range(4 * (len(rng_of) + 1))]
    assert {c["effect"] for c in cases} == {"null", *rng_of}
    for c in cases:
        if c["effect"] == "polarization_branch":
            tau = c["truth"]["tau_p"]
            v = trial.branch_size_at(taus, tau)
            assert max(taus[0][0], 0.1) <= tau <= min(taus[-1][0], 3.0)
            assert v * (1 - 1e-9) <= _size(c) <= 4 * v * (1 + 1e-9), (tau, v, _size(c))
        elif c["effect"] != "null":
            v = trial.REVEALED_FINE[drive][c["effect"]]
            assert v * (1 - 1e-9) <= _size(c) <= 4 * v * (1 + 1e-9)


def test_a_branch_is_drawn_at_its_own_time_constants_revealed_size(monkeypatch):
    """A branch revealed at 0.04 (tau_p 0.3 s), 0.02 (1 s) and 0.01 (3 s), not at 0.1 s:
    tau_p drawn within 0.3-3 s, chi_p at 1-4x the log-log line through those at tau_p."""
    table = ((0.1, None), (0.3, 0.04), (1.0, 0.02), (3.0, 0.01))
    monkeypatch.setitem(trial.BRANCH_TAU, "lab_fine", {"reset_hold": table})
    taus = trial.branch_sizes("lab_fine", "reset_hold")
    assert taus == ((0.3, 0.04), (1.0, 0.02), (3.0, 0.01))
    assert math.isclose(trial.branch_size_at(taus, 1.0), 0.02)
    assert math.isclose(trial.branch_size_at(taus, math.sqrt(3.0)), 0.02 / math.sqrt(2.0))
    assert math.isclose(trial.branch_size_at(taus, 10.0), 0.01)
    rng_of = trial.ranges("lab_fine", "reset_hold", "revealed")
    assert rng_of["polarization_branch"][1:3] == (0.02, 0.08)
    effects = [e for e in trial.EFFECTS if e == "null" or e in rng_of]     # draw's turns
    i0 = effects.index("polarization_branch")
    cases = [trial.draw(i0 + len(effects) * k, 5, False, rng_of) for k in range(30)]
    assert {c["effect"] for c in cases} == {"polarization_branch"}
    taus_drawn = [c["truth"]["tau_p"] for c in cases]
    assert min(taus_drawn) >= 0.3 and max(taus_drawn) <= 3.0 and min(taus_drawn) < 0.5 and max(taus_drawn) > 2.0
    for c in cases:
        v = trial.branch_size_at(taus, c["truth"]["tau_p"])
        assert v * (1 - 1e-9) <= c["truth"]["chi_p"] <= 4 * v * (1 + 1e-9)
    # revealed at the fast time constants only (under inversion): tau_p drawn among those
    monkeypatch.setitem(trial.BRANCH_TAU, "lab_fine", {"reset_hold": ((0.1, 0.04), (1.0, 0.16), (3.0, None))})
    rng_of = trial.ranges("lab_fine", "reset_hold", "revealed")
    effects = [e for e in trial.EFFECTS if e == "null" or e in rng_of]
    i0 = effects.index("polarization_branch")
    drawn = [trial.draw(i0 + len(effects) * k, 5, False, rng_of)["truth"]["tau_p"] for k in range(30)]
    assert 0.1 <= min(drawn) and max(drawn) <= 1.0 and max(drawn) > 0.6
    # not revealed at any tau_p: not drawn
    monkeypatch.setitem(trial.BRANCH_TAU, "lab_fine", {"reset_hold": ((1.0, None),)})
    assert "polarization_branch" not in trial.ranges("lab_fine", "reset_hold", "revealed")


def test_a_spring_is_not_drawn_under_reset_and_hold_on_the_lab_rig_but_is_on_the_ideal_one():
    assert "stiffness" not in trial.ranges("lab", "reset_hold", "revealed")
    assert "stiffness" in trial.ranges("ideal", "reset_hold", "revealed")
    assert trial.ranges("lab", "reset_hold", "ideal") == trial.RANGES


def _rows(entry, table):
    return [{"entry": entry, "value": v, "draw": d, "heldout_noises": h} for v, hs in table.items()
            for d, h in enumerate(hs)]


def test_a_revealed_size_doubles_the_error_over_the_same_draws_floor():
    e = "inertia"
    lad = sizes.LADDERS[e]
    # floors 1.0 (a noise), 2.5 and 1.2: the doubled error is 2.0, 5.0 and 2.4
    table = {0.0: [0.9, 2.5, 1.2], lad[1]: [1.9, 4.0, 2.0], lad[2]: [2.1, 4.9, 2.5], lad[3]: [3.0, 6.0, 3.0]}
    assert sizes.revealed_size(_rows(e, table), e) == lad[2]      # median ratio 2.0 there, 1.6 below
    table[lad[2]] = [2.1, 4.0, 2.3]
    assert sizes.revealed_size(_rows(e, table), e) == lad[3]
    assert sizes.revealed_size(_rows(e, {0.0: [1.0] * 3, lad[1]: [1.5] * 3}), e) is None


def test_the_ladders_start_from_the_same_draw_without_the_entry():
    for e, lad in sizes.LADDERS.items():
        assert lad[0] == 0.0 and all(b > a for a, b in zip(lad, lad[1:]))
        assert sizes.truth_keys(e, 0.0) == {}
        assert sizes.truth_keys(e, lad[1])
    assert math.isclose(sizes.truth_keys("field_dependent_resistivity", 1e5)["q_rho"], 2e12 + 1e5 * 5.5e7)


def test_the_fine_lab_rigs_truth_is_the_continuum_where_the_lab_rigs_is_not():
    """The diagnosis raises N up to 8x the nominal (two doublings and a check), so a truth at
    4x is about the grid it ends on and carries its own discretization error: at 84 points,
    2.7 um RMS off the continuum over a hold after unipolar pulses (sensor noise 1-3 um);
    lab_fine's truth at 31x N (651 points) is within 0.1 um of one at twice its points."""
    import numpy as np
    from dfa_model import preset
    from dfa_model.io.synthetic import TRUTH_RTOL
    from dfa_model.numerics.solver import simulate
    from dfa_model.waveforms import DC, Protocol, Stage, Unipolar
    from diagnosis.proofs import RIGS
    N = 21
    t = np.arange(0.0, 8.0, 1e-3)
    drive = Protocol([Stage(Unipolar(6000.0, 2.0, 0.5), 1.0, "reset"), Stage(DC(6000.0), 7.0, "hold")])
    x = {}
    for n in (RIGS["lab"]["truth_N"] * N, RIGS["lab_fine"]["truth_N"] * N, 2 * RIGS["lab_fine"]["truth_N"] * N):
        p = preset("vshape-table1").replace(N=n, rho_l=2e12)
        x[n] = simulate(p, drive, load=5.0, t_eval=t, warn=False, rtol=min(p.rtol, TRUTH_RTOL)).trace(t)
    lab, fine, ref = sorted(x)
    hold = t > 1.1
    rms = {n: float(np.sqrt(np.mean((x[n] - x[ref])[hold] ** 2))) for n in (lab, fine)}
    assert rms[lab] > 1e-6 and rms[fine] < 0.1e-6, rms
    assert RIGS["lab_fine"]["measurement"] == RIGS["lab"]["measurement"]
