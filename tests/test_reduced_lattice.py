"""The lattice family (reduced.lattice): a material point at every node of the full model's
lattice, the force and current read off the full model. Checked against the full model on
devices that are not presets, where the charge family breaks down (its breakdowns 3, 4, 6
in docs/guide/surrogates.md), and against the physics' limits."""
import warnings

import numpy as np
import pytest

import reduced
from dfa_model import Bipolar, PhysicsWarning, Protocol, preset, simulate
from dfa_model.physics.statics import equilibrium_stroke
from dfa_model.waveforms import DC, Load, Sampled, Stage
from reduced.compare import compare

warnings.simplefilter("ignore", PhysicsWarning)


def _device():
    """A V-shaped pouch no preset has (other geometry, films, liquid and damping)."""
    v = preset("vshape-table1")
    return v.replace(l=v.l * 1.12, a=v.a * 0.85, w=v.w * 0.9, t_f=v.t_f * 1.15, eps_r_l=v.eps_r_l * 0.9,
                     rho_l=v.rho_l * 1.3, b=v.b * 0.8)


@pytest.fixture(scope="module")
def lat():
    return reduced.lattice(_device())


def _speed_error(c):
    return c["unzipping_speed_reduced"] / c["unzipping_speed_full"] - 1.0


def _drift_ok(c):
    f, r = c["drift_full"], c["drift_reduced"]
    return abs(r - f) <= max(1e-6, 0.2 * abs(f)) and (abs(f) < 1e-6 or np.sign(r) == np.sign(f))


def _telegraph(n, seed, V=6000.0):
    """Random polarity: n holds of 0.1 s at +-V, signs drawn from seed."""
    rng = np.random.default_rng(seed)
    signs = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    t = np.repeat(np.arange(n) * 0.1, 2)[1:]
    v = np.repeat(signs * V, 2)[:-1]
    return Protocol([Stage(Sampled(np.append(t, n * 0.1), np.append(v, v[-1]), hold=True), n * 0.1, "hold")])


def test_statics_are_the_full_models(lat):
    """Uncharged, the lattice's force is the full model's quadratic map at every node:
    the equilibrium stroke is the full model's (the maps' cubic interpolation in x)."""
    for V, F in ((4000.0, 2.0), (6000.0, 4.0), (8000.0, 8.0)):
        x_full = equilibrium_stroke(lat.params, V, F, warn=False)
        assert float(lat.equilibrium(V, F)[0]) == pytest.approx(x_full, rel=2e-3, abs=1e-7)


def test_a_staircase_with_a_load_step_keeps_its_dc_speed(lat):
    """The charge family's breakdown 4: the front snaps millimetres into material charged
    under DC and the last hold's DC speed was 5-9 % off on random devices."""
    proto = Protocol([Stage(DC(3000.0), 10, "s1"), Stage(DC(4000.0), 10, "s2"), Stage(DC(5000.0), 10, "s3"),
                      Stage(DC(6000.0), 10, "hold")])
    load = Load(Sampled([0, 20, 20.0001, 40], [2.4, 2.4, 4.0, 4.0], name="force"))
    c = compare(lat, proto, load)
    assert c["relative_rms_error"] <= 0.005
    assert abs(_speed_error(c)) <= 0.02


def test_random_polarity_and_slow_inversion_drift(lat):
    """Breakdowns 3 and 6: the drift of a telegraph signal (the overshoot after its last
    switch) and of 0.3 Hz inversion, set by how far the front sweeps into material it
    released a moment before - 20-100 % off or of the wrong sign in the charge family."""
    telegraph = _telegraph(100, 11)
    slow = Protocol([Stage(Bipolar(6000.0, 0.3, phase="balanced"), 60, "hold")])
    for proto in (telegraph, slow):
        c = compare(lat, proto, 4.0)
        assert c["relative_rms_error"] <= 0.005
        assert _drift_ok(c), (c["drift_full"], c["drift_reduced"])


def test_the_default_tolerance_stays_near_a_converged_run(lat):
    """The lattice's default tolerance (RTOL_LATTICE, five times the charge family's)
    spends some of its margin on speed, not on the goals: on a DC creep, a telegraph signal
    (the most sensitive drive of the development panel) and a 10 Hz train, within 0.5 % of
    range (a quarter of the goal) of the same lattice at rtol 1e-7."""
    from reduced.surrogate import RTOL, RTOL_LATTICE
    assert lat.rtol == RTOL_LATTICE > RTOL
    telegraph = _telegraph(60, 5)
    for proto in (Protocol.reset_then_hold(6000.0, 10.0), telegraph, Protocol.single(Bipolar(6000.0, 10.0, 0.4), 4.0)):
        a, b = lat.simulate(proto, 4.0), lat.simulate(proto, 4.0, rtol=1e-7)
        tt = np.linspace(0.0, b.t[-1], 20001)
        assert a.n_steps < b.n_steps / 3
        rms = np.sqrt(np.mean((a.trace(tt) - b.trace(tt)) ** 2))
        assert rms <= 0.005 * np.ptp(b.trace(tt))


def test_a_creep_without_a_mass_is_stepped_without_a_train_of_rejections(lat):
    """A long massless step ends off the stroke's balance by a share of the tolerance that
    grows as about its length to the fourth (surrogate_kernel.OFF_ORDER), which the error
    estimate does not see. Sized from it, a 40 s creep after a reset takes few rejected
    tries (before: about one in three, each followed by a step grown back past it), and
    stays within 0.1 % of range of the converged run."""
    proto = Protocol.reset_then_hold(6000.0, 40.0)
    a, b = lat.simulate(proto, 4.0), lat.simulate(proto, 4.0, rtol=1e-7)
    rejected = a.n_steps - (len(a.t) - 1)
    assert rejected <= 0.15 * a.n_steps, (rejected, a.n_steps)
    tt = np.linspace(0.0, b.t[-1], 20001)
    rms = np.sqrt(np.mean((a.trace(tt) - b.trace(tt)) ** 2))
    assert rms <= 0.001 * np.ptp(b.trace(tt))


def test_the_compiled_hold_tracks_like_the_full_model(lat):
    """The compiled 10 Hz PI hold (surrogate_kernel.pi_loop) keeps the lattice's Jacobian
    across samples at a nearby voltage: its tracking RMS stays within 10 % of the full
    model's Python loop (1.03x here; 1.00-1.02x on the held-out draws)."""
    import dataclasses

    from reduced import holding
    c = holding.tune_hold_controller(lat, 0.8e-3, 4.0, frequency=10.0)
    cc = dataclasses.replace(c, mode="bipolar")
    rs = holding.simulate_hold_surrogate(lat, cc, duration=20.0)
    rf = holding.simulate_hold(lat.params, cc, duration=20.0)
    ms, mf = rs.metrics(c.x_ref, period=0.1), rf.metrics(c.x_ref, period=0.1)
    assert ms["rms_dev"] == pytest.approx(mf["rms_dev"], rel=0.1)


def test_collapse_near_the_pull_in_threshold():
    """The charge family's strict xfail (test_reduced.py): after 10 s at 2 kV, 2.75 kV at
    2.4 N zips Table 1 about 140 um and the stroke creeps back to 0 by 17 s. The lattice
    follows it within 10 um at 14 and 15 s."""
    p = preset("vshape-table1")
    proto = Protocol([Stage(DC(2000.0), 10.0, "a"), Stage(DC(2750.0), 10.0, "b")])
    f, r = simulate(p, proto, load=2.4), reduced.lattice(p).simulate(proto, 2.4)
    assert f.trace(15.0) > 30e-6
    for t in (14.0, 15.0):
        assert abs(r.trace(t) - f.trace(t)) < 10e-6, t


def test_every_physics_at_once():
    """Mass, stiffness, the polarization branch, a series resistance and Eq. (21)'s law
    together (the points' pointwise law at their hat-weighted gaps; the device voltage a
    state): reset + DC within the goals."""
    p = _device().replace(m=0.03, k=100.0, chi_p=0.02, tau_p=0.5, R_s=1e6, law="linear", q_rho=2e12 + 4e4 * 1e6,
                          m_rho=-4e4, rho_min=1e11)
    s = reduced.lattice(p)
    c = compare(s, Protocol.reset_then_hold(6000.0, 20.0), 4.0)
    assert c["relative_rms_error"] <= 0.01
    assert abs(_speed_error(c)) <= 0.05
    assert s.state_names[:3] == ["x", "v", "V_d"] and "q_f" not in s.state_names
    assert len(s.state_names) == 3 + 2 * p.N


def test_polarity_symmetry(lat):
    a = lat.simulate(Protocol.dc(7000.0, 5.0), 4.0, rtol=1e-8)
    b = lat.simulate(Protocol.dc(-7000.0, 5.0), 4.0, rtol=1e-8)
    t = np.linspace(0, 5, 51)
    assert np.allclose(a.trace(t), b.trace(t), rtol=1e-6, atol=1e-12)
    q = [i for name, i in lat._names if name[0] == "q"]
    assert np.allclose(a.y_end[q], -b.y_end[q], rtol=1e-5, atol=1e-12)


def test_files_python_control_and_errors(lat, tmp_path):
    import control
    path = tmp_path / "lat.json"
    lat.save(path)
    back = reduced.load(path)
    assert back.family == "lattice" and back.state_names == lat.state_names
    proto = Protocol.reset_then_hold(6000.0, 5.0)
    assert np.allclose(back.simulate(proto, 4.0).x, lat.simulate(proto, 4.0).x)
    sys_ = lat.system()
    assert sys_.nstates == lat.n_states and sys_.input_labels == ["voltage", "force"]
    lin = lat.linearize(6000.0, 4.0, freeze_charge=True)
    x = [simulate(lat.params, Protocol.dc(v, 0.2), load=4.0).final_stroke for v in (6000.0, 6020.0)]
    assert control.dcgain(lin)[0, 0] == pytest.approx((x[1] - x[0]) / 20.0, rel=0.03)
    with pytest.raises(ValueError, match="scheme"):
        reduced.lattice(preset("vshape-table1").replace(scheme="continuum-p0"))


def test_cli_reduce_compare_and_hold_chain(tmp_path, capsys):
    """As a newcomer chains them: dfa reduce --family lattice, then dfa compare and dfa
    hold on its file."""
    import json
    from dfa_model.cli import main
    path = tmp_path / "lat.json"
    assert main(["reduce", "--preset", "vshape-table1", "--family", "lattice", "--out", str(path), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["compare", str(path), "--voltage", "6000", "--force", "4", "--reset", "3", "--duration", "10",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["states"] == 82 and out["relative_rms_error"] < 0.005 and out["speedup"] > 1
    assert main(["hold", "--preset", "vshape-table1", "--model", str(path), "--stroke", "0.8e-3", "--force", "4",
                 "--duration", "5"]) == 0
    assert "lattice" in capsys.readouterr().out
    # dfa hold (and design) fit a lattice themselves when asked for the family
    assert main(["hold", "--preset", "vshape-table1", "--family", "lattice", "--stroke", "0.8e-3", "--force", "4",
                 "--duration", "5"]) == 0
    assert "tuned on the lattice surrogate" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["vshape-table1", "peano-fig10"])
def test_force_weights_are_the_full_models(name):
    """The force's node weights (hat integrals on a graded grid, scaled by the full
    model's own force) against the full model probed a node at a time: F(V, q e_i) and
    F(0, q (e_i + e_(i+1))) at three strokes."""
    from dfa_model.numerics import surrogate_kernel as sk
    from reduced import frozen
    p = preset(name).replace(N=41)
    m = frozen.as_model(p)
    xg, tab = frozen.lattice_tables(m, n_grid=161)
    n, nb, qs, V = p.N, m.nbord, frozen.q_scale(m), 1000.0
    o = sk.NFIX + 3 * n
    for k in (30, 80, 130):
        y0 = m.initial_state(xg[k])
        f0 = m.electrostatic_force(y0, V)
        assert tab[k, sk.C0] * V * V == pytest.approx(f0, rel=1e-9)
        for i in range(n - 1):
            y = y0.copy()
            y[nb + i] = qs
            c2 = tab[k, o + n + i] * qs * qs
            probe = m.electrostatic_force(y, V) - f0
            assert tab[k, o + i] * V * qs + c2 == pytest.approx(probe, rel=1e-3, abs=1e-7 * f0)
            y[nb + i + 1] = qs
            pair = c2 + tab[k, o + n + i + 1] * qs * qs + 2.0 * tab[k, o + 2 * n + i] * qs * qs
            assert pair == pytest.approx(m.electrostatic_force(y, 0.0), rel=1e-3, abs=1e-7 * f0)


def test_above_the_largest_lattice_the_points_are_a_coarser_lattice():
    """The Peano-HASEL preset runs at N = 401; a state per node stops at N = 201
    (frozen.LATTICE_N_MAX), so its points are the nodes of the same actuator at N = 201,
    while compare runs the full model at 401. A voltage step and a telegraph signal within
    0.5 % of range, the drift with its sign."""
    p = preset("peano-fig10")
    s = reduced.lattice(p)
    assert p.N == 401 and s.params.N == 401 and s.n_points == 201 and s.n_states == 202
    assert "N = 201" in s.info["source"]
    telegraph = _telegraph(40, 3)
    step = Protocol([Stage(DC(4800.0), 4, "s1"), Stage(DC(6600.0), 6, "hold")])
    for proto in (step, telegraph):
        c = compare(s, proto, 4.0)
        assert c["relative_rms_error"] <= 0.005
        assert _drift_ok(c), (c["drift_full"], c["drift_reduced"])


def test_a_loose_tolerance_does_not_overshoot_a_snap():
    """The last step of a staircase snaps the front over most of the stroke. At rtol 3e-4
    (then three times the default) the order-3 error estimate once passed a step of 14 ms
    across it that overshot the full model's peak by 390 um (Table 1, 4980 -> 6000 V after
    30 s of charging); a step now moves the stroke by at most a fifth of x_e
    (surrogate_kernel.DX_STEP). Also at the default tolerance (RTOL_LATTICE) and at 1e-3."""
    p = preset("vshape-table1")
    proto = Protocol([Stage(DC(3000.0), 10, "s1"), Stage(DC(4020.0), 10, "s2"), Stage(DC(4980.0), 10, "s3"),
                      Stage(DC(6000.0), 10, "hold")])
    load = Load(Sampled([0, 20, 20.0001, 40], [2.4, 2.4, 4.0, 4.0], name="force"))
    full = simulate(p, proto, load=load)
    s = reduced.lattice(p)
    for rtol in (3e-4, None, 1e-3):
        r = s.simulate(proto, load, rtol=rtol)
        assert r.trace.max() == pytest.approx(full.trace.max(), rel=0.01)
        # after the snap (within it, 10 ms, the loose tolerance's records are sparse)
        t = np.linspace(30.1, 40.0, 2001)
        assert np.max(np.abs(r.trace(t) - full.trace(t))) <= 0.01 * full.trace.max()


def test_a_snap_onto_a_spring_does_not_overshoot_its_balance():
    """Without a mass the stroke flows to the balance of the frozen charges and cannot pass
    it. A held-out draw (seed 755348143: a large V-shape, x_e 4.7 mm, with k = 300 N/m under
    10 Hz pulses with dead time) found one 7 ms step from 0 to 805 um at each pulse, the
    balance at 532 um, passed by the error estimate at half the tolerance (13.1 % of range
    RMS at the lattice's rtol 5e-4). The step that passes the balance is rejected now."""
    v = preset("vshape-table1")
    p = v.replace(l=0.046136, a=0.010527, l_e=0.033829, w=0.042465, t_f=2.6273e-5, eps_r_l=4.873, rho_l=2.2277e12,
                  b=7.4449, k=300.0)
    s = reduced.lattice(p)
    proto = Protocol.single(Bipolar(6000.0, 10.0, 0.4), 1.0)
    full = simulate(p, proto, load=4.0)
    red = s.simulate(proto, 4.0)
    x_top = float(full.trace.max())
    assert float(np.max(red.x)) <= x_top + 5e-6         # before: 805 against 533 um
    c = compare(s, proto, 4.0, full_result=full)
    assert c["relative_rms_error"] < 0.01


def test_the_lattice_is_the_default_family_where_it_applies():
    """reduced.fit/build and the commands build the lattice unless the scheme is one whose
    nodes it does not read ('continuum-p0': the charge family)."""
    from reduced.families import default_family
    p = preset("vshape-table1").replace(N=21)
    assert default_family(p) == "lattice" and reduced.build(p).family == "lattice"
    p0 = p.replace(scheme="continuum-p0")
    assert default_family(p0) == "charge" and reduced.build(p0).family == "charge"
    assert reduced.build(p, "charge").family == "charge"
