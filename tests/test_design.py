"""Polarity-inversion design: the cycle-averaged surrogate (reduced/averaged.py) and the
frequency window (reduced/design.py), checked against the non-averaged surrogate and the
full model."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import reduced
from dfa_model import Protocol, Stage, preset, simulate
from reduced import averaged
from reduced.design import design_inversion

V, F = 6000.0, 5.0


@pytest.fixture(scope="module")
def params():
    return preset("vshape-table1")


@pytest.fixture(scope="module")
def surrogate(params):
    return reduced.build(params, "charge")


# ---------------------------------------------------------------- (a) averaged inputs
@pytest.mark.parametrize("f, share, t_ramp", [(5.0, 0.5, 0.0), (5.0, 0.5, 2e-3), (37.0, 0.3, 1e-3),
                                              (0.7, 0.7, 0.05), (100.0, 0.4, 4e-3)])
def test_averaged_inputs_match_the_waveform(f, share, t_ramp):
    vm, w = averaged.averaged_inputs(V, f, share, t_ramp)
    assert vm == pytest.approx((2 * share - 1) * V, abs=1e-9 * V)
    assert w == pytest.approx(V * V * (1 - 4 / 3 * t_ramp * f), rel=1e-12)
    # numerical integration of the waveform itself over 3 periods (dense trapezoid rule)
    T = 1 / f
    wave = averaged.drive(V, f, share, t_ramp, balanced=False)
    assert wave.duty == 1.0            # the design's drive: full-duty inversion (Bipolar's duty)
    t = np.linspace(0.0, 3 * T, 600_001)
    v = Protocol([Stage(wave, 3 * T)]).voltage(t)
    assert np.trapezoid(v, t) / (3 * T) == pytest.approx(vm, abs=2e-5 * V)
    assert np.trapezoid(v * v, t) / (3 * T) == pytest.approx(w, rel=2e-5)
    # the share of the period at V >= 0 is positive_share (ramps centred on the switching instants)
    assert np.mean(v[:-1] >= 0) == pytest.approx(share, abs=2e-4)
    assert np.max(v) == pytest.approx(V) and np.min(v) == pytest.approx(-V)


def test_ramp_time_and_limits():
    C = 4e-10
    assert averaged.ramp_time(V, slew_rate=1e8) == pytest.approx(1.2e-4)
    assert averaged.ramp_time(V, current_limit=1e-3, capacitance=C) == pytest.approx(2 * V * C / 1e-3)
    assert averaged.ramp_time(V, slew_rate=1e8, current_limit=1e-3, capacitance=C) == pytest.approx(4.8e-3)
    with pytest.raises(ValueError, match="^f:"):      # ramps longer than a polarity's share
        averaged.averaged_inputs(V, 300.0, 0.5, 2e-3)


# ---------------------------------------------------------------- (b) averaged vs real
def test_averaged_model_matches_the_real_waveform(surrogate, params):
    f, horizon, t_ramp = 5.0, 60.0, 2e-4
    avg = averaged.simulate_averaged(surrogate, V, F, f, 0.5, horizon, t_ramp)
    real = surrogate.simulate(Protocol([Stage(averaged.drive(V, f, 0.5, t_ramp), horizon, "hold")]), F,
                              rtol=1e-6)
    rip, xm = averaged.last_period(real, 1 / f)
    stroke = avg.x_static
    assert abs(avg.x_mean_end - xm) < 0.02 * stroke
    assert avg.ripple == pytest.approx(rip, rel=0.05)
    assert avg.drift == pytest.approx(avg.x_static - xm, abs=0.02 * stroke)
    # the slow run spans the horizon in few steps (the point of averaging)
    assert avg.slow.n_steps < 200


@pytest.mark.xfail(strict=True, reason="stated breakdown (README, 'Surrogates'): under an unequal share the full "
                                       "model's front element rectifies the mean voltage away (its conductance is "
                                       "higher in the polarity that zips further) and barely drifts; the surrogate "
                                       "and its averaged form charge under the mean")
def test_averaged_model_unequal_share_against_the_full_model(surrogate, params):
    f, horizon, t_ramp, share = 5.0, 60.0, 2e-4, 0.6
    avg = averaged.simulate_averaged(surrogate, V, F, f, share, horizon, t_ramp)
    full = simulate(params, Protocol([Stage(averaged.drive(V, f, share, t_ramp), horizon, "hold")]), load=F)
    rip, xm = averaged.last_period(full, 1 / f)
    assert abs(avg.x_mean_end - xm) < 0.02 * avg.x_static
    assert avg.ripple == pytest.approx(rip, rel=0.2)


# ---------------------------------------------------------------- (c), (d) design vs full
T_RAMP = 3e-4
LIMITS = {"max_ripple": 120e-6, "max_drift": 15e-6, "horizon": 10.0, "slew_rate": 2 * V / T_RAMP}


def _full_ok(params, f, x_static):
    _, rip, dr = averaged.simulate_full(params, V, F, f, 0.5, LIMITS["horizon"], T_RAMP, x_static=x_static)
    return rip <= LIMITS["max_ripple"] and abs(dr) <= LIMITS["max_drift"]


def _bisect(params, f_bad, f_good, x_static, rel=0.02):
    assert not _full_ok(params, f_bad, x_static) and _full_ok(params, f_good, x_static)
    while abs(math.log(f_good / f_bad)) > math.log1p(rel):
        fm = math.sqrt(f_bad * f_good)
        if _full_ok(params, fm, x_static):
            f_good = fm
        else:
            f_bad = fm
    return f_good


@pytest.fixture(scope="module")
def design(surrogate):
    return design_inversion(surrogate, V, F, **LIMITS)


def test_design_window_against_full_model_bisection(design, params):
    """f_max (drift-limited: sag at the zero crossings) within 10 % of the full model's
    bisection; f_min (ripple-limited: the front layer's charge following each polarity)
    conservative and within 60 % (measured with this unfitted surrogate: 0.43 vs 0.29 Hz;
    fitted, 0.38 Hz). The surrogate's front layer is renewed by the front's motion in
    either direction, so the sag at every zero crossing refreshes it with zipped charge;
    the full model's charge is carried by the material and comes back with the front."""
    d = design
    assert d.feasible, d.reason
    assert d.t_ramp == pytest.approx(T_RAMP)
    f_max_full = _bisect(params, 60.0, 20.0, d.x_static)
    f_min_full = _bisect(params, 0.15, 1.5, d.x_static)
    assert d.f_max == pytest.approx(f_max_full, rel=0.10)
    assert 0.95 * f_min_full <= d.f_min <= 1.6 * f_min_full
    assert d.f_min < d.frequency <= d.f_max
    assert d.frequency == pytest.approx(min(d.f_max, 1.25 * d.f_min))


def test_recommended_point_meets_spec_on_full_model(design):
    d = design
    assert d.verified is not None and d.verified["meets"]
    assert d.verified["ripple"] <= LIMITS["max_ripple"] and abs(d.verified["drift"]) <= LIMITS["max_drift"]
    assert d.ripple <= LIMITS["max_ripple"] and abs(d.drift) <= LIMITS["max_drift"]
    assert d.power["hard_switched_dissipation"] == pytest.approx(4 * d.frequency * d.capacitance * V * V)
    # the drive as designed returns most of each inversion's charge to the source: its input
    # power is far below what a hard-switched source dissipates, and positive
    assert 0 < d.power["input"] < 0.1 * d.power["hard_switched_dissipation"]
    assert d.power["input"] == d.verified["input_power"]
    assert 1e-10 < d.capacitance < 1e-8
    for k in ("f_min", "f_max", "frequency", "duty", "power", "ripple", "drift", "verified", "feasible", "reason"):
        assert d[k] is getattr(d, k)
    assert d.duty == 1.0 and d.positive_share == 0.5 and d.phase == pytest.approx(0.25)


def test_recommendation_the_full_model_rejects_moves_into_the_window(params):
    """A tight drift limit at slow inversion, on a surrogate whose period-mean stroke
    sits a few um off the full model's there (the charge family with its earlier
    constants: 11 points, c_ell 1.8, c_w 4, no material lag; the default's recommendation passes the full
    model's check here): the recommendation 1.25 f_min fails on the full model, so the
    design walks up the window until the full model meets the limits, and says so."""
    surrogate = reduced.charge(params, n_points=11, c_ell=1.8, c_w=4.0, c_m=0.0)
    lim = dict(max_ripple=120e-6, max_drift=1.5e-6, horizon=60.0, slew_rate=700e6, current_limit=20e-3)
    d = design_inversion(surrogate, V, F, **lim)
    assert d.feasible and d.verified["meets"], d.reason
    assert "moved from" in d.reason
    assert d.frequency > 1.25 * d.f_min * 1.01 and d.frequency <= d.f_max
    assert d.verified["frequency"] == d.frequency
    # the reported check is the full model's at the moved frequency
    _, rf, df = averaged.simulate_full(params, V, F, d.frequency, d.positive_share, lim["horizon"], d.t_ramp,
                                       x_static=d.x_static)
    assert (rf, df) == pytest.approx((d.verified["ripple"], d.verified["drift"]), rel=1e-9)
    assert rf <= lim["max_ripple"] and abs(df) <= lim["max_drift"]
    _, rf0, df0 = averaged.simulate_full(params, V, F, 1.25 * d.f_min, d.positive_share, lim["horizon"], d.t_ramp,
                                         x_static=d.x_static)
    assert rf0 > lim["max_ripple"] or abs(df0) > lim["max_drift"]


def test_infeasible_spec_says_why(surrogate):
    d = design_inversion(surrogate, V, F, max_ripple=20e-6, max_drift=15e-6, horizon=10.0, slew_rate=2 * V / T_RAMP,
                         verify=False)
    assert not d.feasible and d.frequency is None
    assert "ripple" in d.reason and "zero crossing" in d.reason


# ---------------------------------------------------------------- (e) arguments
@pytest.mark.parametrize("kw, name", [
    ({"V": 0.0}, "V"), ({"V": 2e6}, "V"), ({"V": float("nan")}, "V"), ({"F": float("inf")}, "F"),
    ({"F": "x"}, "F"), ({"max_ripple": 0.0}, "max_ripple"), ({"max_ripple": -1e-6}, "max_ripple"),
    ({"max_drift": 0.0}, "max_drift"), ({"horizon": 0.0}, "horizon"), ({"horizon": float("inf")}, "horizon"),
    ({"slew_rate": 0.0}, "slew_rate"), ({"slew_rate": -5.0}, "slew_rate"), ({"current_limit": 0.0}, "current_limit"),
    ({"positive_share": 0.2}, "positive_share"), ({"positive_share": 0.75}, "positive_share"),
    ({"f_range": (10.0, 1.0)}, "f_range")])
def test_bad_arguments_name_the_argument(surrogate, kw, name):
    args = {"V": V, "F": F, "max_ripple": 1e-4, "max_drift": 1e-5, "horizon": 10.0}
    args.update(kw)
    with pytest.raises(ValueError, match=rf"^{name}: "):
        design_inversion(surrogate, verify=False, **args)


# ---------------------------------------------------------------- dfa design
def test_design_command_prints_json_last(capsys):
    from dfa_model import cli as base
    from reduced.design_cli import add_design_parser
    ap = base._Parser(prog="dfa")
    add_design_parser(ap.add_subparsers(dest="command", parser_class=base._Parser))
    args = ap.parse_args(["design", "--preset", "vshape-table1", "--voltage", "6000", "--force", "5",
                          "--max-ripple", "120e-6", "--max-drift", "15e-6", "--horizon", "10",
                          "--slew-rate", str(2 * V / T_RAMP), "--json", "--quiet"])
    assert args.func(args) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    out = json.loads(lines[-1])
    assert set(out) >= {"f_min", "f_max", "frequency", "duty", "power", "ripple", "drift", "verified"}
    assert out["verified"]["meets"] is True and out["f_min"] < out["frequency"] <= out["f_max"]
    with pytest.raises(base.CLIError, match="--max-ripple"):
        ap.parse_args(["design", "--preset", "vshape-table1", "--voltage", "6000", "--force", "5",
                       "--max-ripple", "0", "--max-drift", "1e-5", "--horizon", "10"])
