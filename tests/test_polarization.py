"""The liquid's fast relaxation (polarization branch, chi_p and tau_p) against limits with
known answers: a blocked stack (a 2x2 linear ODE, solved independently), the slow and fast
limits (no branch; a liquid of static permittivity eps_l (1 + chi_p)), the energy balance,
V -> -V symmetry and convergence in N."""
import numpy as np
import pytest
from scipy.linalg import expm

from dfa_model import DFAModel, Protocol, Stage, DC, Bipolar, simulate
from dfa_model.io.parameters import ParameterError

CHI, TAU_P = 0.2, 0.5


def test_blocked_stack_two_time_constants(vshape81):
    """Stroke held zipped: sigma_l follows the exact solution of the stack's linear ODE in
    (q, P): q' = sigma_l/tau_l - sigma_f/tau_f, P' = (chi sigma_l - P)/tau_p with
    sigma_l = (eps_l V - T0 (q + P))/u0, sigma_f = sigma_l + q + P."""
    p = vshape81.replace(b=1e15, chi_p=CHI, tau_p=TAU_P)
    V = 6000.0
    t = np.linspace(0, 60, 121)
    res = simulate(p, Protocol.dc(V, 60.0), load=0.0, x0=8.7e-4, t_eval=t, charges=True, rtol=1e-10)
    assert np.ptp(res.x) < 1e-8 * res.x[0]
    sig = np.array([res.charge_profile(i)[1][0] for i in range(len(t))])
    T0 = 2 * p.eps_l * p.t_f / p.eps_f
    u0 = p.t_lz + T0
    # sigma_l = c0 - c1 (q + P); rates linear in y = (q, P)
    c0, c1 = p.eps_l * V / u0, T0 / u0
    A = np.array([[-c1 / p.tau_l - (1 - c1) / p.tau_f, -c1 / p.tau_l - (1 - c1) / p.tau_f],
                  [-CHI * c1 / TAU_P, -(CHI * c1 + 1) / TAU_P]])
    bvec = np.array([c0 / p.tau_l - c0 / p.tau_f, CHI * c0 / TAU_P])
    # y(t) = A^-1 (expm(A t) - I) b from y(0) = 0
    Ainv = np.linalg.inv(A)
    y = np.array([Ainv @ (expm(A * tk) - np.eye(2)) @ bvec for tk in t])
    expected = c0 - c1 * y.sum(axis=1)
    assert np.max(np.abs(sig - expected)) < 1e-6 * c0
    # the fast drop is real: sigma_l loses chi c1/(1 + chi c1) of its value in a few tau_p
    k = np.searchsorted(t, 5 * TAU_P)
    assert sig[k] < sig[0] * (1 - 0.5 * CHI * c1 / (1 + CHI * c1))


def test_slow_branch_is_no_branch(vshape81):
    t = np.linspace(0, 23, 47)
    proto = Protocol.reset_then_hold(6000, 20.0)
    a = simulate(vshape81.replace(chi_p=CHI, tau_p=1e6), proto, load=5.0, t_eval=t)
    b = simulate(vshape81, proto, load=5.0, t_eval=t)
    assert np.max(np.abs(a.x - b.x)) < 1e-4 * np.max(b.x)


def test_fast_branch_is_a_static_permittivity_at_every_N(vshape):
    """tau_p -> 0: the liquid has the static permittivity eps_l (1 + chi_p). The branch
    is rebuilt between its material points with P (u + chi_p T0) linear in s, which holds
    exactly where P follows the field, so the limit holds at every N, not only as N grows
    (a P linear between the points had been 22 % off at N = 21, 4 % at 81 here). The
    fully zipped elements' closed form must not be used where a point's weight is not u0."""
    t = np.linspace(0, 10, 101)
    proto = Protocol.dc(6000, 10.0)
    for N in (21, 81):
        a = simulate(vshape.replace(N=N, chi_p=CHI, tau_p=1e-6), proto, load=5.0, t_eval=t, rtol=1e-9)
        b = simulate(vshape.replace(N=N, eps_r_l=vshape.eps_r_l * (1 + CHI)), proto, load=5.0, t_eval=t, rtol=1e-9)
        assert np.max(np.abs(a.x - b.x)) < 1e-5 * np.max(b.x)


def test_strong_fast_branch_converges_in_N_like_the_plain_model(vshape):
    """A strong, fast branch against its own solution at N = 321 under a reset and a hold:
    the error falls with N, and at N = 21 it is no larger than the plain model's own
    (with a P linear between the points it was 16x larger), and the integrator takes
    about as many steps as without the branch (weights with a kink in time as the front
    crossed a point had cost 3x the steps)."""
    t = np.linspace(0, 12, 601)
    proto = Protocol.reset_then_hold(6000, 10.0)

    def err(**kw):
        ref = simulate(vshape.replace(N=321, **kw), proto, load=5.0, t_eval=t, rtol=1e-8).x
        return [np.sqrt(np.mean((simulate(vshape.replace(N=N, **kw), proto, load=5.0, t_eval=t).x - ref) ** 2))
                for N in (21, 81)]
    branch = err(chi_p=0.448, tau_p=0.116)
    plain = err()
    assert branch[1] < 0.5 * branch[0]
    assert branch[0] < 1.5 * plain[0]
    steps = [simulate(vshape.replace(N=81, **kw), Protocol.dc(6000, 23.0), load=5.0).n_steps
             for kw in ({}, {"chi_p": 0.05, "tau_p": 0.5})]
    assert steps[1] < 2 * steps[0]


@pytest.mark.parametrize("mass", [0.0, 2e-3])
def test_energy_balance_with_polarization(vshape81, mass):
    """E_in = dU (field + branch) + Joule (conduction + branch) + intra + source + mech,
    exactly; 'intra' (the nodal projection's bookkeeping) shrinks with N."""
    proto = Protocol([Stage(Bipolar(6000, 30), 0.5, "reset"), Stage(DC(6000), 2.0, "hold"),
                      Stage(DC(4500), 0.5, "drop")])
    intra = []
    for N in ((21, 81) if mass == 0.0 else (21,)):
        p = vshape81.replace(N=N, m=mass, chi_p=CHI, tau_p=0.3)
        eb = simulate(p, proto, load=5.0, energy=True, rtol=1e-9).energy_balance()
        resid = eb["E_in"] - sum(eb[k] for k in ("dU", "dKE", "joule", "intra", "source", "damping", "load"))
        assert abs(resid) < 1e-5 * (eb["damping"] + abs(eb["load"]) + eb["joule"])
        assert abs(eb["residual"]) < 1e-6
        intra.append(abs(eb["intra"]) / eb["joule"])
    if len(intra) == 2:
        assert intra[1] < 0.5 * intra[0]


def test_energy_balance_with_polarization_and_series_resistance(vshape81):
    """With R_s the device current, and so the source's loss, includes the rebuilt
    branch's share beyond a linear P (its rates and its motion with the front): the
    balance closes only if the device's voltage state carries the same current."""
    proto = Protocol([Stage(Bipolar(6000, 30), 0.5, "reset"), Stage(DC(6000), 2.0, "hold"),
                      Stage(DC(4500), 0.5, "drop")])
    p = vshape81.replace(N=21, chi_p=0.4, tau_p=0.1, R_s=1e7)
    eb = simulate(p, proto, load=5.0, energy=True, rtol=1e-9).energy_balance()
    resid = eb["E_in"] - sum(eb[k] for k in ("dU", "dKE", "joule", "intra", "source", "damping", "load"))
    assert eb["source"] > 1e-3 * eb["E_in"]
    assert abs(resid) < 1e-5 * (eb["damping"] + abs(eb["load"]) + eb["joule"])
    assert abs(eb["residual"]) < 1e-6


def test_symmetry_under_voltage_reversal(vshape81):
    p = vshape81.replace(chi_p=CHI, tau_p=TAU_P)
    t = np.linspace(0, 10, 201)
    a = simulate(p, Protocol.reset_then_hold(6000, 7.0), load=5.0, t_eval=t)
    b = simulate(p, Protocol.reset_then_hold(-6000, 7.0), load=5.0, t_eval=t)
    assert np.max(np.abs(a.x - b.x)) < 1e-9 * np.max(a.x)
    assert np.allclose(a.I, -b.I, rtol=1e-6, atol=1e-12 * np.max(np.abs(a.I)))


def test_branch_signature_fast_drop_then_slower_unzipping(vshape81):
    """What the diagnosis looks for: within a few tau_p of the voltage step the stroke
    drops below the model without the branch (the liquid's permittivity rises and takes
    field from the zipped region), later it unzips more slowly (the larger static
    permittivity keeps more sigma_l at the end of the MWS relaxation)."""
    t = np.linspace(0, 12, 241)
    proto = Protocol.dc(6000, 12.0)
    a = simulate(vshape81.replace(chi_p=0.1, tau_p=1.0), proto, load=5.0, t_eval=t)
    b = simulate(vshape81, proto, load=5.0, t_eval=t)
    d = a.x - b.x
    early = (t > 0.1) & (t < 1.0)
    assert d[early].min() < -10e-6
    i2, i12 = np.searchsorted(t, [2.0, 12.0 - 1e-9])
    speed = lambda r: (r.x[i2] - r.x[i12]) / (t[i12] - t[i2])
    assert speed(a) < 0.8 * speed(b)


def test_parameters_and_errors(vshape81):
    m = DFAModel(vshape81.replace(chi_p=0.1))
    assert m.n == 1 + 2 * vshape81.N and m.polarized
    assert not DFAModel(vshape81).polarized
    with pytest.raises(ParameterError, match="chi_p"):
        vshape81.replace(chi_p=-0.1)
    with pytest.raises(ParameterError, match="tau_p"):
        vshape81.replace(tau_p=0.0)
    with pytest.raises(ParameterError, match="chi_p: does not apply"):
        vshape81.replace(scheme="paper", chi_p=0.1)
    text = vshape81.replace(chi_p=0.1, tau_p=2.0).to_toml()
    assert "[polarization]" in text and "chi_p = 0.1" in text
