"""Surrogates (reduced/): accuracy on held-out conditions, python-control objects,
linearization against the full model, physics limits, files and the CLI."""
import json
import sys
import warnings

import numpy as np
import pytest

import reduced
from dfa_model import PhysicsWarning, Protocol, preset, simulate
from dfa_model.waveforms import DC, Bipolar, Stage, Unipolar
from dfa_model.numerics import surrogate_kernel as sk
from reduced import frozen
from reduced.compare import KEYS, hold_speed
from reduced.fitting import Condition, Envelope

warnings.simplefilter("ignore", PhysicsWarning)

SMALL = Envelope(training=[Condition(5000, 2), Condition(8000, 6, reset=3.0), Condition(7000, 4, "bipolar", 0.5, 0.5),
                           Condition(10000, 8)],
                 heldout=[Condition(6000, 5, reset=3.0), Condition(9000, 3), Condition(7500, 5, "bipolar", 1.0, 0.6)])


@pytest.fixture(scope="module")
def fitted():
    """The default envelope's fit for the V-shaped baseline (held-out rows in info)."""
    return reduced.fit(preset("vshape-table1"), family="charge", progress=False)


def _check_heldout(rows, states_max=4 + reduced.families.N_POINTS):
    # the charge family's structure: the stroke, the layer, its two wakes and the points
    rows = [r for r in rows if r["stroke_range"] >= 20e-6]     # runs that zip at all
    assert rows
    for r in rows:
        assert r["states"] <= states_max
        assert r["relative_rms_error"] <= 0.02, r
        # the DC unzipping speed (the goal); held on the electrode end, the speed
        # hinges on the release time, and a pulse train's per-period peak decay is a stated
        # breakdown (README, 'Surrogates': the re-zip's memory): both checked for RMS only
        dc = ", dc" in r["condition"]
        if dc and r["speed_error"] is not None and r["unzipping_speed_full"] > 1e-6 and not r["front_at_end"]:
            assert r["speed_error"] <= 0.05, r
        if r["ripple_full"] is not None and abs(r["drift_full"]) > 20e-6:
            assert abs(r["drift_reduced"] / r["drift_full"] - 1) <= 0.10, r


def test_heldout_accuracy_vshape(fitted):
    rows = fitted.info["heldout"]
    assert {r["condition"] for r in rows}.isdisjoint(fitted.info["fitted"]["training"])
    _check_heldout(rows)
    # the fit never ends worse than the family's default it starts from
    assert fitted.info["fitted"]["cost_after"] <= fitted.info["fitted"]["cost_before"]


@pytest.mark.parametrize("case", ["peano-fig10", "theta15", "theta45"])
def test_heldout_accuracy_other_actuators(case):
    p = preset(case) if case.startswith("peano") else preset("vshape-table1").with_theta0(float(case[5:]))
    s = reduced.fit(p, family="charge", envelope=SMALL, progress=False)
    _check_heldout(s.info["heldout"])


def test_lumped_circuit_is_the_baseline(fitted):
    """From geometry alone the circuit's time constant is the full model's zipped one;
    its force (Eq. 10, zipped region only) is what makes it worse than the reduced
    charge model on held-out runs."""
    p = preset("vshape-table1")
    lump = reduced.lumped(p)
    a_full, b_full = frozen.zipped_rates(frozen.as_model(p))
    assert lump.info["tau"] == pytest.approx(-1 / a_full, rel=1e-9)
    gains = lump.input_gains(0.5 * lump.x_e)
    assert gains["q_f"] == pytest.approx(b_full, rel=1e-9)
    rows = reduced.evaluate(lump, [Condition(6000, 5, reset=3.0)], progress=False)
    ours = [r for r in fitted.info["heldout"] if r["condition"] == rows[0]["condition"]][0]
    assert rows[0]["speed_error"] > ours["speed_error"]


def test_python_control_system_matches_fast_path(fitted):
    import control
    sys_ = fitted.system()
    assert isinstance(sys_, control.NonlinearIOSystem)
    assert sys_.input_labels == ["voltage", "force"] and sys_.output_labels == ["stroke", "current_no_ramp", "capacitance"]
    t = np.linspace(0, 2, 401)
    r = control.input_output_response(sys_, t, [np.full_like(t, 6000.0), np.full_like(t, 5.0)],
                                      X0=np.zeros(fitted.n_states), solve_ivp_method="LSODA")
    fast = fitted.simulate(Protocol.dc(6000.0, 2.0), 5.0)
    assert r.outputs[0][-1] == pytest.approx(fast.final_stroke, rel=5e-3)


def test_linearization_dc_gain_matches_full_model(fitted):
    import control
    V, F, dV = 6000.0, 5.0, 20.0
    lin = fitted.linearize(V, F, freeze_charge=True)
    assert isinstance(lin, control.StateSpace)
    assert isinstance(fitted.linearize(V, F), control.StateSpace)
    x = [simulate(fitted.params, Protocol.dc(v, 0.2), load=F).final_stroke for v in (V, V + dV)]
    assert control.dcgain(lin)[0, 0] == pytest.approx((x[1] - x[0]) / dV, rel=0.03)


def test_matched_dielectrics_hold_the_stroke():
    """tau_l = tau_f: no interface charge builds up, the stroke does not decay."""
    p = preset("vshape-table1")
    p = p.replace(rho_l=p.rho_f * p.eps_f / p.eps_l)
    s = reduced.charge(p)
    r = s.simulate(Protocol.dc(6000.0, 30.0), 5.0)
    charges = [i for name, i in s._names if name[0] in "qP"]
    assert abs(r.q_f).max() < 1e-12 and np.all(np.abs(r.y_end[charges]) < 1e-12)
    assert r.final_stroke == pytest.approx(r.trace(1.0), rel=1e-6)


def test_polarity_symmetry():
    s = reduced.charge(preset("vshape-table1"), c_ell=3.0)
    # the physics is odd in (V, q); the forward-difference Jacobian is not mirrored, so
    # the two runs agree to the integration tolerance (tight here: the difference falls
    # with rtol, 2e-6 of the stroke at 1e-8, 5e-7 at 1e-9, 6e-8 at 1e-10)
    a = s.simulate(Protocol.dc(7000.0, 10.0), 4.0, rtol=1e-9)
    b = s.simulate(Protocol.dc(-7000.0, 10.0), 4.0, rtol=1e-9)
    t = np.linspace(0, 10, 101)
    assert np.allclose(a.trace(t), b.trace(t), rtol=1e-6, atol=1e-12)
    assert np.allclose(a.q_f[-1], -b.q_f[-1], rtol=1e-6)
    odd = [i for name, i in s._names if name[0] in "qP"]      # the charges; the stroke and
    assert np.allclose(a.y_end[odd], -b.y_end[odd], rtol=1e-5, atol=1e-12)     # the lag's anchor are even
    assert a.y_end[sk.SM] == pytest.approx(b.y_end[sk.SM], rel=1e-6)


@pytest.mark.parametrize("frequency", [30.0, 0.3])
def test_square_waves_integrate_to_tolerance_with_the_mirrored_jacobian(frequency):
    """After each inversion the integrator reuses the previous half period's Jacobian,
    mirrored (surrogate_kernel: JAC_TOL). The stroke at the default tolerance stays
    within 0.5 % of range of a run at rtol 1e-7 (four to ten times the steps):
    the reuse costs no accuracy the error control does not see. Within a stage a kept
    Jacobian did cost 5 % here, which is why it is not kept there."""
    from dfa_model.waveforms import Stage
    s = reduced.charge(preset("vshape-table1"))
    pr = Protocol([Stage(Bipolar(6000.0, frequency, 1.0), 20.0 if frequency > 1 else 60.0, "hold")])
    a, ref = s.simulate(pr, 5.0), s.simulate(pr, 5.0, rtol=1e-7)
    t = np.linspace(0.0, ref.trace.t1, 20001)
    d = np.abs(a.trace(t) - ref.trace(t))
    assert d.max() < 5e-3 * (ref.trace.max() - ref.trace.min()), d.max()
    assert ref.n_steps > 3 * a.n_steps


def test_front_layer_width_is_a_continuum_property():
    """w_f, the force-weighted distance of the material beyond the front, is the same at
    any resolution (the element hat functions reproduce linear functions, so the first
    moment of the force sensitivity is exact) and shrinks toward the electrode end, where
    the gap opens ever faster beyond the front."""
    p = preset("vshape-table1")
    xs = np.array([0.2, 1.0, 2.0, 3.0, 4.0]) * 1e-3
    w = {N: np.array([frozen.front_layer(frozen.as_model(p.replace(N=N)), x)[2] for x in xs]) for N in (41, 161)}
    assert np.allclose(w[41], w[161], rtol=1e-6)
    assert np.all(np.diff(w[161]) < 0) and w[161][0] > 5 * frozen.u0(frozen.as_model(p))


def test_a_front_advancing_into_charged_material_finds_its_history():
    """After 10 s of DC the voltage steps up: the front advances millimetres into material
    that was never zipped (little charge), then creeps back through material zipped at
    the step. The material points keep that history; the uniform zipped charge of the
    previous surrogates did not (11.8 % RMS, the stroke 0.2 mm short)."""
    from reduced.compare import rms_difference
    p = preset("vshape-table1")
    proto = Protocol([Protocol.dc(5000.0, 10.0).stages[0], Protocol.dc(6500.0, 10.0).stages[0]])
    f = simulate(p, proto, load=4.0)
    r = reduced.charge(p).simulate(proto, 4.0)
    assert rms_difference(r.trace, f.trace) / (f.trace.max() - f.trace.min()) < 0.01
    # the uniform zipped history (no material points) misses it by an order more
    r0 = reduced.charge(p, n_points=0).simulate(proto, 4.0)
    assert rms_difference(r0.trace, f.trace) > 5 * rms_difference(r.trace, f.trace)


def test_the_layer_carries_the_full_models_force_weighted_charge():
    """The front layer stands for the charge the force sees, h^T q / h^T 1 (h: the full
    model's force sensitivity at the stroke): under DC, where the front creeps back
    over material charged while zipped, the layer's charge stays the full model's."""
    from reduced import frozen
    p = preset("vshape-table1")
    model = frozen.as_model(p)
    s = reduced.charge(p)
    for T in (1.0, 5.0):
        proto = Protocol.dc(6000.0, T)
        f = simulate(p, proto, load=4.0, charges=True, t_eval=[0.0, T])
        y = f.states[-1]
        h = frozen.force_sensitivity(model, y[0])
        qh = h @ y[model.nbord:model.nbord + p.N] / h.sum()
        r = s.simulate(proto, 4.0)
        assert r.q_f[-1] == pytest.approx(qh, rel=0.02), T
        assert r.final_stroke == pytest.approx(y[0], abs=2e-6)


@pytest.mark.xfail(strict=True, reason="breakdown 6 (docs/guide/surrogates.md): a front advancing into the "
                   "material it uncovered re-zips it too charged - the renewal chain's lag; the overshoot is "
                   "1.2-1.5x the full model's")
def test_overshoot_after_a_polarity_switch():
    """After T s of DC the polarity switches: the interface charge now adds to the field and
    the front re-zips the material it uncovered while creeping back, past the uncharged
    static stroke. That overshoot 30 ms after the switch (full model 10.5, 15.5 and 21.6 um
    at T = 1, 2 and 5 s on Table 1) within 20 % - the telegraph's drift is this overshoot
    after its last switch."""
    from dfa_model.physics.statics import equilibrium_stroke
    p = preset("vshape-table1")
    s = reduced.charge(p)
    x_static = equilibrium_stroke(p, 6000.0, 4.0, warn=False)
    for T in (1.0, 2.0, 5.0):
        proto = Protocol([Stage(DC(6000.0), T, "a"), Stage(DC(-6000.0), 0.3, "b")])
        f, r = simulate(p, proto, load=4.0), s.simulate(proto, 4.0)
        over_f, over_r = f.trace(T + 0.03) - x_static, r.trace(T + 0.03) - x_static
        assert over_f > 5e-6, T        # the full model does overshoot
        assert over_r == pytest.approx(over_f, rel=0.2), T


@pytest.mark.xfail(strict=True, reason="breakdown 4 (docs/guide/surrogates.md): near the pull-in threshold, after "
                   "zipping into open material charged from the hinge, the layer holds twice the full model's "
                   "charge and the last of the stroke snaps off seconds early")
def test_collapse_near_the_pull_in_threshold():
    """10 s at 2 kV charge the open actuator (it stays at rest), then 2.75 kV at 2.4 N zips
    it about 140 um, close to its pull-in threshold; it creeps back to 0 by 17 s in the full
    model (58 um at 15 s). The surrogate within 20 um of it at 14 and 15 s."""
    p = preset("vshape-table1")
    proto = Protocol([Stage(DC(2000.0), 10.0, "a"), Stage(DC(2750.0), 10.0, "b")])
    f, r = simulate(p, proto, load=2.4), reduced.charge(p).simulate(proto, 2.4)
    assert f.trace(15.0) > 30e-6                       # the full model still holds part of the stroke
    for t in (14.0, 15.0):
        assert abs(r.trace(t) - f.trace(t)) < 20e-6, t


def test_hold_speed_of_a_square_wave_is_the_peaks_drift():
    """A drive with dead time drops the stroke to 0 and re-zips it to the same peak every
    period: it does not unzip, though Sec. 3.1's peak-to-end drop over the run says
    tens of um/s."""
    proto = Protocol.single(Bipolar(4000.0, 10.0, 0.6), 20.0)
    r = reduced.charge(preset("vshape-table1")).simulate(proto, 1.0)
    assert r.unzipping_speed > 50e-6
    assert hold_speed(r, proto) < 0.1e-6
    dc = Protocol.dc(6000.0, 20.0)
    r = reduced.charge(preset("vshape-table1")).simulate(dc, 5.0)
    assert hold_speed(r, dc) == r.unzipping_speed


def test_stops_are_events():
    """A bipolar drive with dead time drops the stroke to 0 and re-zips: the trace stays
    in [0, x_e] and lands on 0 where the full model does."""
    p = preset("vshape-table1")
    s = reduced.charge(p)
    proto = Protocol.single(Bipolar(5000, 1.0, 0.5), 4.0)
    r = s.simulate(proto, 3.0)
    f = simulate(p, proto, load=3.0)
    assert r.x.min() >= 0 and r.x.max() <= s.x_e
    t = np.array([0.375, 0.875, 1.375])     # in the dead time, after the fall
    assert np.all(f.trace(t) == 0) and np.all(r.trace(t) == 0)
    assert r.n_steps < 5000


def test_repeated_runs_keep_only_their_inputs():
    """The merged input segments of a protocol are kept between runs (keyed on its fields,
    so a changed protocol is rebuilt; shared with the full model's runs), and so is the
    surrogate's plan of them with the fast inversions averaged (fast_inversions); the
    final state is on the result, not the model."""
    s = reduced.charge(preset("vshape-table1"))
    proto = Protocol.reset_then_hold(6000.0, 2.0)
    from dfa_model import Load
    from dfa_model import waveforms
    waveforms._SEGMENTS.clear()
    a, b = s.simulate(proto, 5.0), s.simulate(proto, 5.0)
    assert len(s._plans) == 1 and np.array_equal(a.rec, b.rec)
    assert s._plan(proto, Load(5.0)) is s._plan(proto, Load(5.0))
    s.simulate(proto, 5.0, inversions="step")
    assert len(waveforms._SEGMENTS) == 1
    assert waveforms.segments(proto, Load(5.0)) is waveforms.segments(proto, Load(5.0))
    assert a.unzipping_speed == b.unzipping_speed
    from dfa_model.numerics import surrogate_kernel as sk
    assert a.y_end[sk.X] == a.rec[-1, sk.R_X] and a.y_end[sk.QF] == a.rec[-1, sk.R_QF] and not hasattr(s, "y_end")
    proto.stages[0].waveform.frequency = 20.0      # mutated in place: a new key
    proto.stages[1].duration = 3.0
    c = s.simulate(proto, 5.0)
    fresh = reduced.charge(preset("vshape-table1")).simulate(Protocol.reset_then_hold(6000.0, 3.0,
                                                                                     reset_frequency=20.0), 5.0)
    assert np.array_equal(c.rec, fresh.rec) and c.trace.t1 == 6.0
    # continuing from y_end is one run split in two
    d = s.simulate(Protocol.dc(6000.0, 1.0), 5.0, y0=c.y_end)
    assert d.x[0] == c.x[-1] and d.q_f[0] == c.q_f[-1]


def test_kept_kernel_inputs_and_buffer_never_go_stale():
    """The kernel's parameter vectors are kept between runs and the output buffer is
    reused: a changed public attribute must reach the next run, and a later run must not
    overwrite an earlier result's arrays."""
    p = preset("vshape-table1")
    s = reduced.charge(p)
    proto = Protocol.reset_then_hold(6000.0, 2.0)
    a = s.simulate(proto, 5.0)
    x_a = a.x.copy()
    s.c_ell = 3.0
    b = s.simulate(proto, 5.0)
    assert np.array_equal(b.rec, reduced.charge(p, c_ell=3.0).simulate(proto, 5.0).rec)
    assert not np.array_equal(a.x, b.x)
    s.params = p.replace(rho_l=3e12)
    c = s.simulate(Protocol.dc(6000.0, 30.0), 5.0)        # in a reused buffer larger than it asks for
    fresh = reduced.charge(p, c_ell=3.0)
    fresh.params = p.replace(rho_l=3e12)
    assert np.array_equal(c.rec, fresh.simulate(Protocol.dc(6000.0, 30.0), 5.0).rec)
    assert np.array_equal(a.x, x_a)


def test_compare_times_each_model_the_same_way():
    from reduced.compare import REPEAT_BUDGET, _timed
    calls = []
    out, t = _timed(lambda: calls.append(1) or len(calls), 5)
    assert out == 1 and len(calls) == 5 and t >= 0.0
    import time
    calls.clear()
    _timed(lambda: calls.append(time.sleep(REPEAT_BUDGET * 0.6)), 5)
    assert len(calls) == 2          # stops once the runs took REPEAT_BUDGET


def test_save_load_roundtrip(fitted, tmp_path):
    path = tmp_path / "m.json"
    fitted.save(path)
    back = reduced.load(path)
    assert back.state_names == fitted.state_names
    proto = Protocol.reset_then_hold(6000, 5)
    assert back.simulate(proto, 5.0).final_stroke == fitted.simulate(proto, 5.0).final_stroke
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="not JSON"):
        reduced.load(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"format": "x"}')
    with pytest.raises(ValueError, match="not a surrogate file"):
        reduced.load(tmp_path / "other.json")


def test_version_7_files_still_read(fitted, tmp_path):
    """A version-7 file had one more map column (the fixed material's gap slope, at index
    15): read, that column dropped, it runs as the version-8 file of the same surrogate;
    a version-6 file (the layer frozen within the lag) is refused."""
    from reduced.surrogate import GIU_V7, VERSION
    d = fitted.to_dict()
    assert d["version"] == VERSION == 8
    old = json.loads(json.dumps(d))
    old["version"] = 7
    old["tables"] = [row[:GIU_V7] + [123.0] + row[GIU_V7:] for row in d["tables"]]
    (tmp_path / "v7.json").write_text(json.dumps(old))
    back = reduced.load(tmp_path / "v7.json")
    assert np.array_equal(back.tables, fitted.tables)
    proto = Protocol.reset_then_hold(6000, 5)
    assert np.array_equal(back.simulate(proto, 5.0).rec, fitted.simulate(proto, 5.0).rec)
    old["version"] = 6
    (tmp_path / "v6.json").write_text(json.dumps(old))
    with pytest.raises(ValueError, match="version: got 6, expected 7 or 8"):
        reduced.load(tmp_path / "v6.json")


def test_bad_input_errors():
    s = reduced.charge(preset("vshape-table1"))
    with pytest.raises(ValueError, match="rtol"):
        s.simulate(Protocol.dc(6000, 1), 5.0, rtol=1.0)
    with pytest.raises(ValueError, match="y0"):
        s.simulate(Protocol.dc(6000, 1), 5.0, y0={"x": 1.0})
    with pytest.raises(ValueError, match="family"):
        reduced.build(preset("vshape-table1"), "pod")
    with pytest.raises(ValueError, match="scheme"):
        reduced.charge(preset("vshape-table1").replace(scheme="paper"))


def test_works_without_slycot(monkeypatch):
    monkeypatch.setitem(sys.modules, "slycot", None)
    from reduced.balance import balanced_truncation
    A, B = frozen.electrical_lti(frozen.as_model(preset("vshape-table1")), 0.001)
    C = frozen.force_sensitivity(frozen.as_model(preset("vshape-table1")), 0.001)
    bt = balanced_truncation(A, B, C, order=3)
    assert bt.method == "scipy" and bt.A.shape == (3, 3)
    assert bt.hsv[3] / bt.hsv[0] < 0.05     # three balanced states carry the frozen-stroke response


def test_cli_compare_json(fitted, tmp_path, capsys):
    from dfa_model.cli import main
    path = tmp_path / "m.json"
    fitted.save(path)
    rc = main(["compare", str(path), "--voltage", "6000", "--force", "5", "--waveform", "bipolar", "--frequency",
               "2", "--duty", "0.5", "--duration", "10", "--json", "--plot", str(tmp_path / "c.png")])
    assert rc == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert list(out) == [*KEYS, "averaged_windows"]
    assert out["averaged_windows"] == []        # a duty of 0.5 is stepped (fast_inversions)
    assert out["relative_rms_error"] < 0.02 and out["speedup"] > 1 and out["ripple_full"] > 0
    assert (tmp_path / "c.png").stat().st_size > 1000
    rc = main(["compare", str(tmp_path / "missing.json"), "--voltage", "6000", "--duration", "1"])
    assert rc == 2
    assert "cannot read" in capsys.readouterr().err


def test_material_lag_leaves_the_dc_creep_alone():
    """The layer's material lag (c_m, a play renewed between steps) changes nothing
    where the front moves on: under the DC hold after a reset the stroke falls step by
    step (a kinked play made the integrator zig-zag there, 500 of 1074 steps upward and
    the unzipping 66 % slow at the default tolerance), at the lag-free speed and at the
    speed of a run at rtol 1e-7."""
    s = reduced.charge(preset("vshape-table1"))
    assert s.c_m > 0
    proto = Protocol.reset_then_hold(6000.0, 20.0)
    r = s.simulate(proto, 4.0)
    hold = r.t > 3.2
    assert np.all(np.diff(r.x[hold]) <= 0.0)
    tight = s.simulate(proto, 4.0, rtol=1e-7)
    s0 = reduced.charge(preset("vshape-table1"), c_m=0.0)
    free = s0.simulate(proto, 4.0)
    assert r.unzipping_speed == pytest.approx(tight.unzipping_speed, rel=0.01)
    assert r.unzipping_speed == pytest.approx(free.unzipping_speed, rel=0.01)



def test_the_branch_force_follows_the_released_polarization():
    """With the polarization branch (tau_p 1 s, about the creep's time scale) the front
    creeping back under DC releases material that still carries its zipped P, and the
    branch's force (the P^2 energy over the unzipped length) sits in that material just
    ahead of the front. The ahead wake filled from the layer instead (P already relaxed)
    made that force 30 % low on Table 1 and the DC creep 6 % (after a reset) and 11 %
    (after a voltage step) too fast. Both against the full model: the branch's force
    within 10 %, the unzipping speed within 5 %."""
    p = preset("vshape-table1").replace(chi_p=0.03, tau_p=1.0)
    model = frozen.as_model(p)
    s = reduced.charge(p)
    nq = model.nbord + p.N
    for proto in (Protocol.reset_then_hold(6000.0, 20.0),
                  Protocol([Stage(DC(4800.0), 10.0, "s1"), Stage(DC(6600.0), 10.0, "hold")])):
        T = proto.duration
        f = simulate(p, proto, load=4.0, charges=True, t_eval=[T])
        r = s.simulate(proto, 4.0)
        assert r.unzipping_speed == pytest.approx(f.unzipping_speed, rel=0.05)
        y = f.states[-1]
        V = float(f.V[-1])
        y0 = y.copy()
        y0[nq:] = 0.0
        fp_full = model.electrostatic_force(y, V) - model.electrostatic_force(y0, V)
        # the surrogate's: its electrostatic force less the layer's (V, q) map
        rw = np.empty(s.tables.shape[1])
        sk.table_row(s.tables, s.x_e, float(r.x[-1]), rw)
        q = float(r.q_f[-1])
        fp_red = float(r.rec[-1, sk.R_FE]) - (rw[sk.C0] * V * V + rw[sk.C1] * V * q + rw[sk.C2] * q * q)
        assert fp_full > 0.05                  # the branch carries a share of the 4 N worth testing
        assert fp_red == pytest.approx(fp_full, rel=0.10)
