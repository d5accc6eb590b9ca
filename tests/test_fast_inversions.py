"""Fast polarity inversion integrated cycle-averaged inside a surrogate run
(reduced.fast_inversions): which stages qualify, the kernel's per-segment averaged mode
and phase offsets, and the averaged run against the stepped one and the full model."""
import math

import numpy as np
import pytest

import reduced
from dfa_model import Protocol, preset, simulate
from dfa_model.numerics import surrogate_kernel as sk
from dfa_model.waveforms import DC, Bipolar, Load, Sampled, Stage, Unipolar, period_means, segments
from reduced import fast_inversions
from reduced.compare import rms_difference


@pytest.fixture(scope="module")
def table1():
    return reduced.charge(preset("vshape-table1"))


def test_standard_protocol_reset_is_averaged_but_its_last_periods(table1):
    proto = Protocol.reset_then_hold(6000.0, 20.0)
    avg = table1.simulate(proto, 5.0)
    step = table1.simulate(proto, 5.0, inversions="step")
    T = 1.0 / 30.0
    assert len(avg.averaged_windows) == 1
    t0, t1 = avg.averaged_windows[0]
    assert t0 == 0.0 and t1 == pytest.approx(3.0 - fast_inversions.N_TAIL * T)
    assert step.averaged_windows == []
    # the 180 inversions were the most of the steps
    assert avg.n_steps < 0.4 * step.n_steps
    full = simulate(preset("vshape-table1"), proto, load=5.0)
    rng = full.trace.max() - full.trace.min()
    # averaged against stepped: within 0.2 % of the stroke range; against the full model
    # no worse than the stepped run by more than that
    assert rms_difference(avg.trace, step.trace) <= 0.002 * rng
    assert rms_difference(avg.trace, full.trace) <= rms_difference(step.trace, full.trace) + 0.002 * rng
    assert avg.unzipping_speed == pytest.approx(step.unzipping_speed, rel=0.01)
    # the tail is the real waveform: the voltage is +-V there and the period mean (0) before
    tail = avg.t > t1 + 1e-9
    assert np.all(np.abs(avg.V[(avg.t > t1 + 1e-6) & (avg.t < 3.0 - 1e-6)]) == pytest.approx(6000.0))
    assert np.all(avg.V[(avg.t > 1e-6) & (avg.t < t1 - 1e-6)] == 0.0)
    assert tail.any()


@pytest.mark.parametrize("stage", [
    Stage(Bipolar(6000.0, 30.0, 0.8), 3.0, "dead time"),          # a dead time: the stroke sags every period
    Stage(Unipolar(6000.0, 30.0, 0.5), 3.0, "pulses"),
    Stage(Bipolar(6000.0, 30.0, 1.0), 7.5 / 30.0, "short"),       # fewer than N_TAIL + MIN_AVERAGED periods
    Stage(Bipolar(6000.0, 0.3, 1.0), 60.0, "slow"),               # the period is 4.5 % of the charge's tau
    Stage(Bipolar(6000.0, 30.0, 1.0, slew_rate=6000.0 / 2e-3), 3.0, "ramps"),   # ramps 12 % of the period
    Stage(DC(6000.0), 3.0, "dc"),
    Stage(Bipolar(6000.0, 30.0, 1.0, positive_share=0.6), 3.0, "unequal share"),   # its mean charges the interface
])
def test_stages_that_are_stepped_as_they_are(table1, stage):
    assert fast_inversions.plan(table1, Protocol([stage]), Load(4.0)) is None


@pytest.mark.parametrize("kw", [{"chi_p": 0.03, "tau_p": 0.3}, {"R_s": 2e6}])
def test_fast_electrical_states_keep_the_inversions_stepped(kw):
    # a branch of 0.3 s is 33 ms x 9: its P moves by a tenth within a period; behind 2
    # Mohm the device voltage takes ~1 ms to follow a switch (the fastest rates, not the
    # charge's)
    s = reduced.charge(preset("vshape-table1").replace(**kw))
    r_q, r_P = fast_inversions.rates(s, 36e6)
    assert r_q / 30.0 > fast_inversions.RATE_SHARE or r_P / 30.0 > fast_inversions.P_RATE_SHARE
    assert s.simulate(Protocol.reset_then_hold(6000.0, 1.0), 4.0).averaged_windows == []


@pytest.mark.parametrize("family", ["charge", "lattice"])
def test_a_slow_polarization_branch_is_averaged_like_the_charges(family):
    # tau_p = 1 s: a 30 Hz reset is T / tau_p = 0.033, over the charges' RATE_SHARE but
    # under P_RATE_SHARE; its period mean is exact to O((T / tau_p)^2) like theirs: the
    # averaged reset within 0.05 % of range of the stepped one, in a fraction of the steps
    s = reduced.build(preset("vshape-table1").replace(chi_p=0.03, tau_p=1.0), family)
    r_q, r_P = fast_inversions.rates(s, 36e6)
    assert r_q / 30.0 <= fast_inversions.RATE_SHARE < r_P / 30.0 <= fast_inversions.P_RATE_SHARE
    proto = Protocol.reset_then_hold(6000.0, 5.0)
    a, b = s.simulate(proto, 4.0), s.simulate(proto, 4.0, inversions="step")
    assert len(a.averaged_windows) == 1 and a.n_steps < b.n_steps / 2
    t = np.linspace(0.0, 8.0, 8001)
    assert np.sqrt(np.mean((a.trace(t) - b.trace(t)) ** 2)) <= 5e-4 * np.ptp(b.trace(t))


def test_period_means_of_a_ramped_unbalanced_inversion():
    V, f, share, t_ramp = 5000.0, 20.0, 0.6, 1e-3
    w = Bipolar(V, f, 1.0, slew_rate=2 * V / t_ramp, positive_share=share)
    vm, W, _ = period_means(w)
    assert vm == pytest.approx((2 * share - 1) * V, rel=1e-9)
    assert W == pytest.approx(V * V * (1 - 4.0 / 3.0 * t_ramp * f), rel=1e-9)     # averaged.averaged_inputs


def test_averaged_mode_with_every_segment_stepped_is_the_plain_run(table1):
    # the kernel's averaged mode takes a segment as it is where its mean square is < 0:
    # the records are those of the plain run, bit for bit
    proto = Protocol([Stage(Bipolar(6000.0, 30.0, 1.0), 0.5, "reset"), Stage(DC(6000.0), 2.0, "hold")])
    load = Load(4.0)
    tb, v0, vs, f0, fs = segments(proto, load)
    y = np.zeros(table1.ny)
    plain, _, _ = table1._run(tb, v0, vs, f0, fs, v0 * v0, y, 1e-4, 10 ** 6, False, 0.0, 6000.0)
    mixed, _, _ = table1._run(tb, v0, vs, f0, fs, np.full(len(v0), -1.0), y, 1e-4, 10 ** 6, True, 0.0, 6000.0)
    assert np.array_equal(plain, mixed)


def test_phase_offsets_keep_a_phase_zero_start_on_the_stepped_charge(table1):
    # a long inversion from phase 0 (as Bipolar starts): the charge oscillates about
    # b <g> (V T / 4 of DC charging) until leakage takes it, tau ~ 75 s; the kernel moves
    # the averaged window's charge by b g0 at its start and back at its end
    proto = Protocol.single(Bipolar(6000.0, 2.0, 1.0), 60.0)
    assert 0.5 * fast_inversions.fastest_rate(table1, 36e6) <= fast_inversions.RATE_SHARE     # T / tau
    step = table1.simulate(proto, 4.0, inversions="step")
    avg = table1.simulate(proto, 4.0)
    assert len(avg.averaged_windows) == 1
    plan = fast_inversions.plan(table1, proto, Load(4.0))
    tb, v0, vs, f0, fs, w2, gof, _ = plan
    g0 = gof[np.flatnonzero(gof[:, 0])[0], 0]
    assert g0 == pytest.approx(6000.0 * 0.5 / 4.0)          # V T / 4 at phase 0
    rec, _, _ = table1._run(tb, v0, vs, f0, fs, w2, np.zeros(table1.ny), 1e-4, 10 ** 6, True, 0.0, 6000.0,
                            np.zeros_like(gof))
    # the layer's charge at the end: with the offsets on the stepped run's, without them not
    err_with = abs(avg.q_f[-1] - step.q_f[-1])
    err_without = abs(rec[-1, sk.R_QF] - step.q_f[-1])
    assert err_with < 0.3 * err_without
    assert rms_difference(avg.trace, step.trace) <= 0.002 * (step.trace.max() - step.trace.min())


def test_inversions_argument_is_checked(table1):
    with pytest.raises(ValueError, match="inversions"):
        table1.simulate(Protocol.dc(6000.0, 1.0), 4.0, inversions="fast")
    assert math.isfinite(table1.simulate(Protocol.dc(6000.0, 1.0), 4.0, inversions="step").final_stroke)


def test_dfa_compare_reports_the_averaged_windows(table1, tmp_path, capsys):
    import json
    from dfa_model.cli import main
    path = tmp_path / "m.json"
    table1.save(path)
    args = ["compare", str(path), "--voltage", "6000", "--force", "5", "--reset", "3", "--duration", "5", "--json"]
    assert main(args) == 0
    avg = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert avg["averaged_windows"] == [[0.0, pytest.approx(3.0 - fast_inversions.N_TAIL / 30.0)]]
    assert main(args + ["--inversions", "step"]) == 0
    step = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert step["averaged_windows"] == []
    # the same comparison either way: the averaged reset moves the error by < 0.2 % of range
    assert abs(avg["relative_rms_error"] - step["relative_rms_error"]) < 0.002
    assert main(args[:-1]) == 0
    assert "cycle-averaged     0-2.86667 s" in capsys.readouterr().out


def test_an_unequal_share_near_pull_in_is_stepped_and_zips_when_the_full_model_does():
    # found by a fuzz run: 1.66 kV at share 0.61 against 0.84 N zips within 4 s in the full
    # model and the stepped surrogate (the interface charges under the mean, and the
    # polarity whose force it raises pulls in), while the averaged force stayed below
    # the threshold until the load fell at 5 s: 252 um RMS apart
    p = preset("vshape-table1")
    s = reduced.charge(p)
    proto = Protocol([Stage(Bipolar(1662.55, 23.829, 1.0, phase=0.0309, positive_share=0.6067), 8.3367, "b")])
    load = Load(Sampled([0, 4.013, 5.042, 5.910], [0.844, 1.951, 0.032, 0.508], name="force"))
    r = s.simulate(proto, load)
    assert r.averaged_windows == []
    full = simulate(p, proto, load=load)
    assert full.trace(5.0) > 1e-3 and r.trace(5.0) > 1e-3           # zipped before the load falls


def test_a_reset_that_starts_charged_is_stepped_and_one_that_starts_clean_is_averaged(table1):
    # after 20 s of DC the interface carries ~1e-4 C/m^2: under the reset the V q force
    # swings with the polarity and the stroke follows it; a reset after 50 ms of DC starts
    # nearly clean. The run is split at each window's start, where its charge is known.
    charged = Protocol([Stage(DC(6000.0), 20.0, "hold"), Stage(Bipolar(6000.0, 30.0, 1.0), 3.0, "reset"),
                        Stage(DC(6000.0), 5.0, "hold")])
    a, b = table1.simulate(charged, 4.0), table1.simulate(charged, 4.0, inversions="step")
    assert a.averaged_windows == []
    assert rms_difference(a.trace, b.trace) < 1e-9
    clean = Protocol([Stage(Bipolar(6000.0, 30.0, 1.0), 3.0, "r1"), Stage(DC(6000.0), 0.05, "d"),
                      Stage(Bipolar(6000.0, 30.0, 1.0), 3.0, "r2"), Stage(DC(6000.0), 5.0, "hold")])
    a, b = table1.simulate(clean, 4.0), table1.simulate(clean, 4.0, inversions="step")
    assert [w[0] for w in a.averaged_windows] == [0.0, pytest.approx(3.05)]
    assert np.all(np.diff(a.t) >= 0) and a.t[-1] == pytest.approx(11.05) and a.n_steps < 0.2 * b.n_steps
    assert rms_difference(a.trace, b.trace) <= 0.002 * (b.trace.max() - b.trace.min())
    # the limit: RIPPLE_SHARE of the charge whose V q force is the V^2 force
    assert 0 < fast_inversions.charge_limit(table1, 6000.0) < 1e-5
