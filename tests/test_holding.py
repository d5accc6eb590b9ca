"""Stroke holding (reduced/holding.py): the PI amplitude loop tuned on the surrogate,
closed on the full model (Stepper) and around the FMU (fmpy, in its own process as in
tests/test_fmu.py)."""
import dataclasses
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import reduced
from dfa_model import preset
from reduced.holding import compare_hold, simulate_hold, tune_hold_controller

X_REF, F0 = 0.8e-3, 5.0
BAND = 10e-6          # the hold band: +-10 um (1.25 % of x_ref) after the 2 s transient
T_STEP = 40.0         # load step 5 N -> 6 N


def load(t):
    return F0 if t < T_STEP else F0 + 1.0


@pytest.fixture(scope="module")
def params():
    return preset("vshape-table1")


@pytest.fixture(scope="module")
def controller(params):
    return tune_hold_controller(reduced.build(params, "charge"), X_REF, F0)


@pytest.fixture(scope="module")
def comparison(params, controller):
    return compare_hold(params, controller, 60.0, F=load)


def test_tuned_loop_margins(controller):
    c = controller
    assert c.phase_margin > 30.0
    assert c.gain_margin > 2.0
    assert c.gain_crossover == pytest.approx(c.crossover, rel=0.05)
    assert c.crossover < c.plant_pole / 5 and c.crossover < 2 * np.pi * c.frequency / 5
    assert 5000.0 < c.v_ff < 6500.0 and c.plant_gain > 0


@pytest.mark.parametrize("mode,frequency", [("bipolar", 30.0), ("bipolar", 1.0), ("dc", 10.0)])
def test_the_gain_margin_is_where_the_sampled_loop_goes_unstable(params, mode, frequency):
    """The margins are the loop's: scaled by 0.9 x the gain margin the closed loop is
    stable, by 1.1 x unstable (the integrator's pole at z = 1 once gave a gain margin of
    1e-16 for a stable loop, and a 15-state plant as a transfer function gave nonsense)."""
    import control
    from reduced.holding import _pi_tf
    s = reduced.build(params, "charge")
    c = tune_hold_controller(s, X_REF, F0, frequency=frequency, mode=mode)
    lin = s.linearize(c.v_ff, F0, freeze_charge=mode != "dc")
    G = control.ss(lin.A, lin.B[:, :1], lin.C[:1, :], lin.D[:1, :1])
    L = control.ss(_pi_tf(c.kp, c.ki, c.dt)) * control.c2d(G, c.dt, "zoh")
    radius = lambda k: np.max(np.abs(control.poles(control.feedback(k * L))))   # noqa: E731
    assert radius(1.0) < 1.0 and 30.0 < c.phase_margin <= 90.0
    assert np.isfinite(c.gain_margin) and c.gain_margin > 2.0
    assert radius(0.9 * c.gain_margin) < 1.0 < radius(1.1 * c.gain_margin)


def test_closed_loop_holds_where_open_loop_drifts(comparison):
    runs = comparison["runs"]
    before = (runs["closed loop"].t >= 2.0) & (runs["closed loop"].t < T_STEP)
    after = runs["closed loop"].t >= T_STEP + 2.0

    def dev(name, window):
        return np.max(np.abs(runs[name].x[window] - X_REF))

    # closed loop: inside the band over the whole hold, before and after the load step
    assert dev("closed loop", before) < BAND
    assert dev("closed loop", after) < BAND
    assert abs(comparison["metrics"]["closed loop"]["final_error"]) < 1e-6
    amp = runs["closed loop"].A
    assert np.all((amp >= 0.0) & (amp <= 10_000.0))
    # open-loop DC at the same initial stroke leaves the band (charge retention) ...
    assert dev("open-loop DC", before) > 30 * BAND
    dc = runs["open-loop DC"]
    assert np.all(np.abs(dc.x[(dc.t > 0.3) & (dc.t < 1.0)] - X_REF) < 0.05 * X_REF)    # it did start at x_ref
    # ... inversion holds it until the load changes, then sits off by ~0.18 mm
    assert dev("inversion", before) < BAND
    assert dev("inversion", after) > 10 * BAND


def test_anti_windup(params, controller):
    """Amplitude capped 2 % above the feedforward: a 6 N load saturates it; when the load
    goes back to 5 N the stroke is back in the band within a second (no wound-up
    integrator to unwind)."""
    c = dataclasses.replace(controller, v_max=1.02 * controller.v_ff)
    r = simulate_hold(params, c, F=lambda t: F0 + 1.0 if 2.0 <= t < 6.0 else F0, duration=9.0)
    sat = (r.t > 3.0) & (r.t < 6.0)
    assert np.all(r.A[sat] == c.v_max) and np.max(r.x[sat]) < X_REF - 50e-6
    assert np.max(np.abs(r.x[r.t >= 7.0] - X_REF)) < BAND


FMU_SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np
    import reduced
    from dfa_model import preset
    from fmu import build_fmu
    from reduced.holding import cosim_hold_fmu, tune_hold_controller
    out, x_ref, f0, t_step, duration = sys.argv[1], *map(float, sys.argv[2:6])
    p = preset("vshape-table1")
    c = tune_hold_controller(reduced.build(p, "charge"), x_ref, f0)
    path = build_fmu(p, out + "/DFAActuator.fmu")
    r = cosim_hold_fmu(path, c, F=lambda t: f0 if t < t_step else f0 + 1.0, duration=duration)
    np.savez(out + "/fmu.npz", t=r.t, x=r.x, A=r.A)
    print(json.dumps({"wall": r.wall_time}))
""")


def test_fmu_cosimulation_matches_full_model(params, controller, tmp_path):
    pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu")
    duration, t_step = 8.0, 4.0
    out = subprocess.run([sys.executable, "-c", FMU_SCRIPT, str(tmp_path), str(X_REF), str(F0), str(t_step),
                          str(duration)], capture_output=True, text=True, timeout=300, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    json.loads(out.stdout.strip().splitlines()[-1])
    fmu = np.load(tmp_path / "fmu.npz")
    ref = simulate_hold(params, controller, F=lambda t: F0 if t < t_step else F0 + 1.0, duration=duration)
    np.testing.assert_array_equal(fmu["t"], ref.t)
    assert np.max(np.abs(fmu["x"] - ref.x)) < 1e-9          # m: same Stepper, same clock
    assert np.max(np.abs(fmu["A"] - ref.A)) < 1e-3          # V
    held = (ref.t >= 2.0) & ((ref.t < t_step) | (ref.t >= t_step + 2.0))
    assert np.max(np.abs(fmu["x"][held] - X_REF)) < BAND


def test_hold_command(capsys, tmp_path):
    """`dfa hold`: tunes, compares on the full model, prints JSON alone on stdout, writes the plot;
    a stroke beyond the electrode is a clear error naming the flag."""
    from dfa_model import cli as base
    from reduced.hold_cli import add_hold_parser
    ap = base._Parser(prog="dfa")
    add_hold_parser(ap.add_subparsers(dest="command", parser_class=base._Parser))
    png = tmp_path / "hold.png"
    args = ap.parse_args(["hold", "--preset", "vshape-table1", "--stroke", "0.8e-3", "--force", "5",
                          "--duration", "45", "--plot", str(png), "--json"])
    assert args.func(args) == 0
    out = json.loads(capsys.readouterr().out)       # stdout is the JSON alone
    m = out["metrics"]
    assert set(m) == {"open-loop DC", "inversion", "closed loop"}
    assert m["closed loop"]["max_dev"] < BAND < m["open-loop DC"]["max_dev"]
    assert out["controller"]["phase_margin"] > 30 and png.stat().st_size > 10_000
    args = ap.parse_args(["hold", "--preset", "vshape-table1", "--stroke", "0.01", "--force", "5"])
    with pytest.raises(base.CLIError, match="^--stroke"):
        args.func(args)
