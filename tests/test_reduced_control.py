"""The surrogate where control engineers take it: python-control at default settings,
the compiled closed loop against the full model's, the hold's control step, the CLI's
executor, the lumped family's own statics."""
import copy
import dataclasses
import subprocess
import sys
import warnings

import control
import numpy as np
import pytest

import reduced
from dfa_model import PhysicsWarning, Protocol, preset
from reduced import holding


@pytest.fixture(scope="module")
def s():
    return reduced.charge(preset("vshape-table1"))


def _io_errors(s, n, method=None, **kw):
    """Max stroke error (m) of control.input_output_response on 6 kV DC at 4 N over 10 s,
    sampled at n points, against the surrogate's own run at rtol 1e-8: (scaled, unscaled)
    at python-control's defaults (solve_ivp_method `method`, default RK45), and scaled with
    solve_ivp's keyword arguments kw."""
    T = np.linspace(0, 10, n)
    U = np.vstack([np.full_like(T, 6000.0), np.full_like(T, 4.0)])
    # the system renews the layer without the material lag (its play is renewed between
    # the compiled stepper's steps: Surrogate.par), 0.2 um off the compiled path here
    plain = copy.copy(s)
    plain.c_m = 0.0
    ref = plain.simulate(Protocol.dc(6000.0, 10.0), 4.0, rtol=1e-8)
    out = []
    for scaled, opts in ((True, {}), (False, {}), (True, kw)):
        how = {"solve_ivp_method": method} if method else {}
        r = control.input_output_response(s.system(scaled=scaled), T, U, X0=np.zeros(s.n_states),
                                          solve_ivp_kwargs=opts or None, **how)
        out.append(float(np.max(np.abs(r.outputs[0] - ref.trace(T)))))
    return out, float(ref.trace.max() - ref.trace.min())


GRIDS = (251, 401, 501, 1001)


def test_scaled_system_is_more_accurate_and_tight_tolerances_are_exact(s):
    """Scaling the states beats the SI states at python-control's defaults on every
    sampling grid (11-45 um against 54-69 um of a 1.12 mm range, 2026-11-27), and the
    documented remedy, solve_ivp_kwargs={'rtol': 1e-6}, is within 0.1 um."""
    for n in GRIDS:
        (scaled, unscaled, tight), rng = _io_errors(s, n, rtol=1e-6)
        assert scaled < unscaled, (n, scaled, unscaled)
        assert tight < 1e-7, (n, tight)


def test_stiff_solver_is_accurate_at_default_tolerances(s):
    """The documented way: solve_ivp_method='LSODA' (stiff-aware) at python-control's
    default tolerances is within 0.05 % of the range on every grid, scaled or not
    (0.11 um scaled, 0.98 um unscaled, 2026-11-27), where RK45 is 1-4 % off."""
    for n in GRIDS:
        (scaled, unscaled, _), rng = _io_errors(s, n, method="LSODA")
        assert scaled < 5e-4 * rng, (n, scaled)
        assert unscaled < 2e-3 * rng, (n, unscaled)


def test_rk45_error_comes_from_the_front_renewal(s):
    """Why RK45 (explicit) is off: the stroke's pole (-345 1/s at 6 kV, 4 N) against the
    charges' (1e-4 to 0.1 1/s) makes the system stiff; RK45 steps at its stability limit,
    where the stroke chatters, and the renewal (upwind in the front's speed) rectifies
    that chatter's speed into mixing of the layer with its wakes. Without the renewal
    (c_ell = inf, the reference run likewise) RK45 at defaults is within 0.5 % on every
    grid (3.0 um)."""
    lin = s.linearize(6000.0, 4.0)
    poles = np.sort(np.linalg.eigvals(lin.A).real)
    assert poles[0] < -100.0 and poles[1] > -1.0          # one fast mechanical pole, slow charges
    s2 = reduced.charge(preset("vshape-table1"))
    s2.c_ell = np.inf
    for n in GRIDS:
        (scaled, _, _), rng = _io_errors(s2, n)
        assert scaled < 5e-3 * rng, (n, scaled)


@pytest.mark.xfail(strict=False, reason="at RK45's default rtol 1e-3 the scaled system's error on 6 kV DC is 11.4 um "
                                        "(1.0 % of the range) on 401 and 1001 sample points but 45 um (4.0 %) on 251 "
                                        "and 501 (one ulp of the input voltage flips between them): the stiff "
                                        "stroke's chatter at RK45's stability limit, rectified by the front's upwind "
                                        "renewal (test_rk45_error_comes_from_the_front_renewal); open in issue 23, "
                                        "the documented way is solve_ivp_method='LSODA'")
def test_scaled_system_is_accurate_at_default_tolerances(s):
    for n in GRIDS:
        (scaled, unscaled, _), rng = _io_errors(s, n)
        assert scaled < 0.015 * rng, (n, scaled)     # 1 % of the range at python-control's defaults
        assert scaled < 0.5 * unscaled, (n, scaled, unscaled)


def test_interconnected_loop_with_the_stiff_solver(s):
    """A continuous PI loop on the stroke (DC amplitude) built with control.interconnect,
    solved with LSODA at default tolerances, matches the same loop at rtol 1e-8 within
    1 um over its first 3 s. (The loop is unstable: at rtol 1e-8 the held stroke slips in
    bursts of a few um from 4.6 s on (5.8 s with the earlier 11 points and constants)
    that grow into an oscillation, and LSODA at defaults damps them away:
    stability is judged on the linearization or the compiled sampled loop,
    docs/guide/surrogates.md.)"""
    c = holding.tune_hold_controller(s, 0.8e-3, 5.0)
    V0 = holding.feedforward_voltage(s, 0.8e-3, 5.0)
    pi = control.ss([[0.0]], [[1.0]], [[c.ki]], [[c.kp]], inputs=["e"], outputs=["u"], states=["z"], name="pi")
    err = control.summing_junction(inputs=["r", "-stroke"], output="e")
    ff = control.summing_junction(inputs=["u", "v0"], output="voltage")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)          # the plant's unused outputs
        loop = control.interconnect([s.system(name="plant"), pi, err, ff], inplist=["r", "v0", "force"],
                                    outlist=["stroke", "voltage"])
    T = np.linspace(0, 3, 301)
    U = np.vstack([np.full_like(T, 0.8e-3), np.full_like(T, V0), np.full_like(T, 5.0)])
    r = control.input_output_response(loop, T, U, X0=0, solve_ivp_method="LSODA")
    ref = control.input_output_response(loop, T, U, X0=0, solve_ivp_method="LSODA",
                                        solve_ivp_kwargs={"rtol": 1e-8, "atol": 1e-10})
    assert np.max(np.abs(r.outputs[0] - ref.outputs[0])) < 1e-6
    assert np.max(np.abs(r.outputs[1] - ref.outputs[1])) < 10.0          # V
    assert abs(ref.outputs[0][-1] - 0.8e-3) < 3e-6                       # the loop holds its reference so far


def test_systems_carry_names_and_units(s):
    sys_ = s.system()
    assert sys_.output_labels == ["stroke", "current_no_ramp", "capacitance"]
    assert sys_.units["stroke"] == "m" and sys_.state_units["x"] == "m" and sys_.state_units["q_f"] == "C/m^2"
    lin = s.linearize(6000.0, 4.0)
    g = lin["stroke", "voltage"]                     # names survive the linearization
    assert float(np.real(control.dcgain(g))) != 0.0
    assert lin.state_labels == s.state_names and lin.units["voltage"] == "V"
    mech = s.linearize(6000.0, 4.0, freeze_charge=True)
    gx = float(np.real(control.dcgain(mech["stroke", "voltage"])))
    assert gx > 0                                    # more voltage, more stroke at fixed charge
    # the SI linearization's gain is the compiled path's finite difference
    dV = 20.0
    x1 = s.equilibrium(6000.0 + dV, 4.0)[0]
    x0 = s.equilibrium(6000.0 - dV, 4.0)[0]
    assert gx == pytest.approx((x1 - x0) / (2 * dV), rel=0.02)


def test_degenerate_linearization_warns(s):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        s.linearize(100.0, 4.0)                      # cannot zip: rests on x = 0
    assert any(issubclass(x.category, PhysicsWarning) and "stop" in str(x.message) for x in w)


def test_equilibrium_is_bounded_and_names_bad_states(s):
    xs = s.equilibrium(6000.0, 4.0)
    assert 0.0 < xs[0] < s.x_e
    with pytest.raises(ValueError, match="unknown state 'q_z'"):
        s.equilibrium(6000.0, 4.0, {"q_z": 1e-5})


def test_compiled_closed_loop_tracks_like_the_full_model(s):
    p = s.params
    c = holding.tune_hold_controller(s, 0.8e-3, 4.0, frequency=10.0)
    cc = dataclasses.replace(c, mode="bipolar")
    rs = holding.simulate_hold_surrogate(s, cc, duration=30.0)
    rf = holding.simulate_hold(p, cc, duration=30.0)
    ms, mf = rs.metrics(c.x_ref, period=0.1), rf.metrics(c.x_ref, period=0.1)
    assert len(rs.t) == len(rf.t) and np.allclose(rs.t, rf.t)
    # tracking error within 20 % of the full model's (the goal)
    assert ms["rms_dev"] == pytest.approx(mf["rms_dev"], rel=0.2)
    assert ms["mean_abs_V"] == pytest.approx(mf["mean_abs_V"], rel=0.01)
    # the same gains on a DC amplitude: the full model cannot hold (the charge under DC
    # turns the loop into a growing oscillation); the surrogate must predict that
    cd = dataclasses.replace(c, mode="dc")
    ds = holding.simulate_hold_surrogate(s, cd, duration=60.0).metrics(c.x_ref, period=1.0)
    df = holding.simulate_hold(p, cd, duration=60.0).metrics(c.x_ref, period=1.0)
    assert df["rms_dev"] > 100 * mf["rms_dev"] and ds["rms_dev"] > 100 * ms["rms_dev"]
    assert 0.5 < ds["rms_dev"] / df["rms_dev"] < 2.0
    with pytest.raises(ValueError, match="F: the compiled loop takes a constant load"):
        holding.simulate_hold_surrogate(s, c, F=lambda t: 4.0, duration=1.0)


def test_compiled_closed_loop_tracks_a_peano_hold():
    """The 10 Hz hold on Fig. 10a at 0.2 mm, 30 s: 1.26x the full model's tracking RMS
    without the layer's material lag (its well-mixed renewal mixed the front's jitter into
    the wakes), 1.05x with it (docs/guide/surrogates.md)."""
    p = preset("peano-fig10")
    sp = reduced.charge(p)
    c = dataclasses.replace(holding.tune_hold_controller(sp, 0.2e-3, 4.0, frequency=10.0), mode="bipolar")
    ms = holding.simulate_hold_surrogate(sp, c, duration=30.0).metrics(c.x_ref, period=0.1)
    mf = holding.simulate_hold(p, c, duration=30.0).metrics(c.x_ref, period=0.1)
    assert ms["rms_dev"] == pytest.approx(mf["rms_dev"], rel=0.2)


@pytest.mark.parametrize("name, x_ref", [("vshape-table1", 0.5e-3), ("peano-fig10", 0.3e-3)])
def test_the_surrogate_loses_a_dc_hold_where_the_full_model_does(name, x_ref):
    """The hold's gains on a DC amplitude: the full model's charge turns the loop into a
    growing oscillation, and the surrogate must show it (a surrogate that holds here
    would call an unstable plant stable). It does through the front's exchange of
    material under small motion, which the material lag keeps at c_adv of its advection:
    a layer frozen within the lag (c_adv = 0) held both (1-3 um RMS against 119-283 um)."""
    p = preset(name)
    s = reduced.charge(p)
    c = holding.tune_hold_controller(s, x_ref, 4.0, frequency=10.0)
    cd = dataclasses.replace(c, mode="dc")
    df = holding.simulate_hold(p, cd, duration=60.0).metrics(c.x_ref, period=1.0)["rms_dev"]
    ds = holding.simulate_hold_surrogate(s, cd, duration=60.0).metrics(c.x_ref, period=1.0)["rms_dev"]
    assert df > 50e-6 and ds > 0.5 * df, (df, ds)
    assert s.c_m > 0 and 0 < s.c_adv < 1
    frozen = reduced.charge(p, c_adv=0.0)
    dl = holding.simulate_hold_surrogate(frozen, cd, duration=60.0).metrics(c.x_ref, period=1.0)["rms_dev"]
    assert dl < 5e-6


def test_hold_control_step_fits_the_frequency(s):
    for f in (10.0, 30.0, 7.0, 0.5):
        dt = holding.control_step(f)
        half = 1.0 / (2 * f)
        assert dt <= holding.DT_MAX + 1e-15 and abs(half / dt - round(half / dt)) < 1e-9
    c = holding.tune_hold_controller(s, 0.8e-3, 4.0, frequency=30.0)      # failed after tuning before
    assert c.dt == pytest.approx(1 / 120)
    with pytest.raises(ValueError, match="whole number of control steps"):
        holding.tune_hold_controller(s, 0.8e-3, 4.0, frequency=30.0, dt_control=0.01)


def test_lumped_design_is_measured_against_its_own_statics():
    from reduced.design import _Scan
    lumped = reduced.build(preset("vshape-table1"), "lumped")
    scan = _Scan(lumped, 6000.0, 5.0, 0.5, 10.0, 3e-4, True, 1.0, 1e-4, 1e-5)
    assert scan.x_static_model == pytest.approx(float(lumped.equilibrium(6000.0, 5.0)[0]))
    assert scan.x_static_model != pytest.approx(1.0)


def test_reduce_with_workers_exits_cleanly(tmp_path):
    out = tmp_path / "act.json"
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", "reduce", "--preset", "vshape-table1", "--family",
                        "lumped", "--workers", "2", "--quiet", "--out", str(out)], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    assert "Exception ignored" not in r.stderr and "Traceback" not in r.stderr
    assert out.exists()
    # the summary judges periodic drives by ripple and drift (their hold's mean slope is
    # near zero, so a relative speed error there would be noise), DC holds by their speed
    lines = [ln for ln in r.stderr.splitlines() if "RMS error" in ln]
    assert lines and all(("ripple" in ln) == ("bipolar" in ln or "unipolar" in ln) for ln in lines), r.stderr
    assert all(("speed error" in ln) == (" dc" in ln) for ln in lines), r.stderr


def test_sampled_system_is_the_fast_path_at_python_controls_defaults(s):
    """system(dt=...): a discrete-time system whose update is the compiled stepper over
    one sample (inputs held): at python-control's defaults it is the fast path's answer,
    where the continuous system under the default RK45 is 11-45 um off (the xfail above)."""
    dt = 0.01
    sysd = s.system(dt=dt)
    assert sysd.dt == dt and sysd.state_labels[:-1] == s.state_names and sysd.state_labels[-1] == "s_m"
    assert sysd.state_units["s_m"] == "m" and sysd.units["stroke"] == "m"
    T = np.arange(0, 10 + dt / 2, dt)
    U = np.vstack([np.full_like(T, 6000.0), np.full_like(T, 4.0)])
    r = control.input_output_response(sysd, T, U)
    ref = s.simulate(Protocol.dc(6000.0, 10.0), 4.0)
    err = np.max(np.abs(r.outputs[0] - ref.trace(T)))
    assert err < 2e-6, err                       # 0.2 % of the 1.12 mm range
    rk = control.input_output_response(s.system(), T, U)
    assert err < 0.2 * np.max(np.abs(rk.outputs[0] - ref.trace(T)))
    for bad in (0.0, -1.0, float("nan"), 100.0):
        with pytest.raises(ValueError, match="dt"):
            s.system(dt=bad)
    # X0 is scaled: scaled_state turns SI values (an equilibrium's) into it; a stroke
    # outside the actuator or a non-finite state is refused by name, not run
    x0 = sysd.scaled_state(s.equilibrium(6000.0, 4.0))
    assert x0.size == len(sysd.state_labels) and x0[0] * sysd.state_scale["x"] == pytest.approx(
        s.equilibrium(6000.0, 4.0)[0])
    for X0, what in ((np.full(x0.size, np.nan), "finite"), (np.append([5.0], np.zeros(x0.size - 1)), "outside")):
        with pytest.raises(ValueError, match=what):
            control.input_output_response(sysd, T[:5], U[:, :5], X0=X0)


def test_the_controller_as_a_python_control_system_is_the_compiled_loops(s):
    # HoldController.system: the same PI law and polarity as the compiled loop, so closed
    # around the sampled surrogate it is that loop (10 Hz inversion, 3 s)
    c = holding.tune_hold_controller(s, 0.5e-3, 4.0, frequency=10.0)
    loop = control.interconnect([s.system(dt=c.dt, name="plant"), c.system()], inputs=["force"],
                                outputs=["stroke", "voltage"], check_unused=False)
    T = np.arange(0, 3.0 + c.dt / 2, c.dt)
    r = control.input_output_response(loop, T, np.full_like(T, 4.0))
    ref = holding.simulate_hold_surrogate(s, c, duration=3.0)
    assert np.max(np.abs(r.outputs[0] - ref.x)) < 1e-9
    assert np.max(np.abs(r.outputs[1] - ref.V)) < 1e-3 and np.min(ref.V) < 0 < np.max(ref.V)


def test_a_python_control_loop_on_the_sampled_system_loses_the_dc_hold_as_the_compiled_loop_does(s):
    # the DC-amplitude loop the full model loses (test above): built with
    # control.interconnect at python-control's defaults, it grows as the compiled loop does
    c = dataclasses.replace(holding.tune_hold_controller(s, 0.5e-3, 4.0, frequency=10.0), mode="dc")
    loop = control.interconnect([s.system(dt=c.dt, name="plant"), c.system()], inputs=["force"],
                                outputs=["stroke", "voltage"], check_unused=False)
    D = 40.0
    T = np.arange(0, D + c.dt / 2, c.dt)
    x = control.input_output_response(loop, T, np.full_like(T, 4.0)).outputs[0]
    ref = holding.simulate_hold_surrogate(s, c, duration=D)
    early = T <= 5.0      # the same loop while it holds (0.0004 um apart; unstable, they part at 6 s)
    assert np.max(np.abs(x[early] - ref.x[:early.sum()])) < 1e-8
    dev = np.sqrt(np.mean((x[T > 2.0] - c.x_ref) ** 2))
    dev_ref = ref.metrics(c.x_ref, period=1.0)["rms_dev"]
    assert dev > 50e-6 and dev == pytest.approx(dev_ref, rel=0.5), (dev, dev_ref)


@pytest.mark.xfail(strict=True, reason="breakdown 9 (docs/guide/surrogates.md): the loop comes to rest where the "
                   "front crosses a material point, at which the wakes' renewal sources jump; a continuous source "
                   "removes the lock but costs the unipolar trains")
def test_a_dc_loop_does_not_rest_on_a_material_point():
    """Fig. 10a (N = 161) at half its static stroke under 6 kV and 4 N (309 um): the full
    model's DC loop grows into a limit cycle (537 um swing over the last 10 s), the
    surrogate's settles with its front 2.5 um from the material point at 8.5 mm."""
    p = preset("peano-fig10").replace(N=161)
    s = reduced.charge(p)
    x_ref = 0.5 * float(s.equilibrium(6000.0, 4.0)[0])
    cd = dataclasses.replace(holding.tune_hold_controller(s, x_ref, 4.0, frequency=10.0), mode="dc")
    swing = []
    for r in (holding.simulate_hold(p, cd, duration=60.0), holding.simulate_hold_surrogate(s, cd, duration=60.0)):
        swing.append(float(np.ptp(r.x[r.t >= 50.0])))
    assert swing[0] > 0.01 * x_ref         # the full model loses the hold
    assert swing[1] > 0.01 * x_ref, swing  # the surrogate must too
