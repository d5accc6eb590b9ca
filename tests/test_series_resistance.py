"""A resistance between the source and the device (R_s) against limits with known answers:
a blocked, loss-free actuator charges as one RC circuit with the model's own capacitance,
a small R_s is the ideal source, the energy balance books R_s I^2 as the source's loss,
and V -> -V symmetry."""
import numpy as np
import pytest

from dfa_model import DFAModel, Protocol, Stage, DC, Bipolar, simulate
from dfa_model.physics.equations import R_C
from dfa_model.io.parameters import ParameterError


def test_blocked_lossless_actuator_is_an_rc_circuit(vshape81):
    """Stroke held, no conduction in film or liquid: I(t) = V/R_s exp(-t/(R_s C)) with C
    the device's capacitance at that stroke (Result.C, independent of the voltage)."""
    R_s = 1e8
    p = vshape81.replace(b=1e15, rho_l=1e25, rho_f=1e25, R_s=R_s)
    V = 6000.0
    x0 = 5e-4
    C = DFAModel(p).diagnostics(DFAModel(p).initial_state(x0), V)[0][R_C]
    tau = R_s * C
    assert 0.01 < tau < 1.0
    t = np.linspace(0, 5 * tau, 101)
    res = simulate(p, Protocol.dc(V, 5 * tau), load=0.0, x0=x0, t_eval=t, rtol=1e-10)
    assert np.ptp(res.x) < 1e-8 * x0
    expected = V / R_s * np.exp(-t / tau)
    assert np.max(np.abs(res.I - expected)) < 1e-5 * V / R_s
    assert np.allclose(res.C, C, rtol=1e-12)


def test_small_series_resistance_is_the_ideal_source(vshape81):
    t = np.linspace(0, 23, 231)
    proto = Protocol.reset_then_hold(6000, 20.0)
    # tight tolerances: what is compared is the physics (a 1 us charging time), not step control
    a = simulate(vshape81.replace(R_s=1e3), proto, load=5.0, t_eval=t, rtol=1e-7)
    b = simulate(vshape81, proto, load=5.0, t_eval=t, rtol=1e-7)
    assert np.max(np.abs(a.x - b.x)) < 1e-5 * np.max(b.x)


@pytest.mark.parametrize("mass", [0.0, 2e-3])
def test_energy_balance_books_the_resistor(vshape81, mass):
    """The books close: R_s I^2 is 'source' (it replaces the ideal steps' loss, of the
    same size for the same charge moved: C V^2/2 per step whatever R_s)."""
    proto = Protocol([Stage(Bipolar(6000, 30), 0.5, "reset"), Stage(DC(6000), 2.0, "hold"),
                      Stage(DC(4500), 0.5, "drop")])
    p = vshape81.replace(N=21, m=mass, R_s=1e8)
    eb = simulate(p, proto, load=5.0, energy=True, rtol=1e-10).energy_balance()
    resid = eb["E_in"] - sum(eb[k] for k in ("dU", "dKE", "joule", "intra", "source", "damping", "load", "impact"))
    assert abs(resid) < 1e-5 * (eb["damping"] + abs(eb["load"]) + eb["joule"])
    assert eb["source"] > 0


def test_resistor_loss_of_a_step_is_that_of_the_ideal_step(vshape81):
    """Charging a fixed capacitor through any resistance loses C V^2/2: a blocked actuator
    and steps long against R_s C lose in R_s what the ideal source loses in its jumps."""
    proto = Protocol([Stage(DC(6000), 1.0, "on"), Stage(DC(-6000), 1.0, "inverted")])
    kw = dict(load=0.0, x0=5e-4, energy=True, rtol=1e-10)
    p = vshape81.replace(N=21, b=1e15)
    eb = simulate(p.replace(R_s=1e7), proto, **kw).energy_balance()
    ideal = simulate(p, proto, **kw).energy_balance()
    assert eb["source"] == pytest.approx(ideal["source"], rel=1e-3)


def test_symmetry_under_voltage_reversal(vshape81):
    p = vshape81.replace(R_s=1e8)
    t = np.linspace(0, 10, 201)
    a = simulate(p, Protocol.reset_then_hold(6000, 7.0), load=5.0, t_eval=t)
    b = simulate(p, Protocol.reset_then_hold(-6000, 7.0), load=5.0, t_eval=t)
    assert np.max(np.abs(a.x - b.x)) < 1e-9 * np.max(a.x)
    assert np.allclose(a.I, -b.I, rtol=1e-6, atol=1e-12 * np.max(np.abs(a.I)))


def test_signature_slower_zipping_and_deeper_inversion_dips(vshape81):
    """What the diagnosis looks for: the zipping transient is slower (the device charges
    through R_s C ~ 0.1 s) and each inversion of the reset costs stroke."""
    t = np.linspace(0, 3.5, 701)
    proto = Protocol.reset_then_hold(6000, 0.5)
    a = simulate(vshape81.replace(R_s=1e8), proto, load=5.0, t_eval=t)
    b = simulate(vshape81, proto, load=5.0, t_eval=t)
    i = np.searchsorted(t, 0.02)
    assert a.x[i] < 0.5 * b.x[i]
    reset = t < 3.0
    assert a.x[reset][200:].min() < b.x[reset][200:].min() - 50e-6


def test_combined_with_polarization_and_errors(vshape81):
    p = vshape81.replace(R_s=1e8, chi_p=0.1, tau_p=1.0)
    m = DFAModel(p)
    assert m.n == 1 + 2 * p.N + 1 and m.series and m.polarized
    r = simulate(p, Protocol.reset_then_hold(6000, 5.0), load=5.0)
    assert np.all(np.isfinite(r.x)) and r.x.max() > 0
    with pytest.raises(ParameterError, match="R_s"):
        vshape81.replace(R_s=-1.0)
    with pytest.raises(ParameterError, match="R_s: does not apply"):
        vshape81.replace(scheme="continuum-p0", R_s=1e8)
