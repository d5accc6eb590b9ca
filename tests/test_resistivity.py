"""Resistivity laws: Eq. (21) against the paper's reported front resistivity, the
floor, and user laws."""

import numpy as np
import pytest

from dfa_model import PhysicsWarning, Protocol, ResistivityLaw, DFAModel, simulate
from dfa_model.physics.dielectrics import LinearResistivity


def test_eq21_front_resistivity_matches_paper(vshape81):
    """Fig. 8d case (5 N, 6 kV, 25 deg, 20 s DC): the paper reports rho_l at the
    zipped portion next to the front as 2.91e12 +- 0.98e12 ohm m. We find 2.95e12 +-
    0.96e12 (N = 81 and 161 alike)."""
    p = vshape81.replace(law="linear", m_rho=-3.34e5, q_rho=20e12)
    t = np.linspace(0, 20, 2001)
    r = simulate(p, Protocol.dc(6000, 20.0), load=5.0, t_eval=t, charges=True)
    t0, _ = r.hold_window()
    rho = r.front_resistivity()[r.t >= t0]
    assert abs(rho.mean() / 2.91e12 - 1) < 0.03
    assert abs(rho.std() / 0.98e12 - 1) < 0.05
    # and it unzips like the paper's constant best fit, 2.5e12
    rc = simulate(vshape81.replace(rho_l=2.5e12), Protocol.dc(6000, 20.0), load=5.0)
    assert abs(r.unzipping_speed / rc.unzipping_speed - 1) < 0.05


def test_linear_law_is_clipped_with_a_warning(vshape81):
    p = vshape81.replace(law="linear", m_rho=-3.34e5, q_rho=20e12, rho_min=1e11)
    with pytest.warns(PhysicsWarning, match="clipped"):
        r = simulate(p, Protocol.dc(7000, 2.0), load=5.0)      # |E_l| ~ 6.8e7 V/m: law < 0
    assert np.all(np.isfinite(r.x)) and r.x.max() > 0
    law = LinearResistivity(-3.34e5, 20e12, 1e11)
    assert law.rho(7e7) == 1e11 and abs(law.rho(1e7) - (20e12 - 3.34e12)) < 1


def test_user_law_is_tabulated_and_used(vshape81):
    class Quadratic(ResistivityLaw):
        def rho(self, E):
            return 2e12 * (1 + (np.asarray(E) / 5e7) ** 2)

    law = Quadratic()
    assert abs(law.rho(5e7) / 4e12 - 1) < 1e-4          # table interpolation accuracy
    m = DFAModel(vshape81, law=law)
    r = simulate(m, Protocol.dc(6000, 5.0), load=5.0)
    r0 = simulate(vshape81, Protocol.dc(6000, 5.0), load=5.0)
    assert r.unzipping_speed < r0.unzipping_speed       # higher rho at high field: slower


def test_bad_user_law_is_reported():
    class Negative(ResistivityLaw):
        def rho(self, E):
            return -np.ones_like(E)

    with pytest.raises(ValueError, match="finite positive"):
        _ = Negative().params


def test_spline_law_neutral_monotone_and_through_its_knots(vshape81):
    """The monotone spline law: all drops 0 is the constant law; it passes through its
    knots, never increases with the field, and is flat outside [E_lo, E_hi]."""
    from dfa_model.physics.dielectrics import MonotoneSplineResistivity, from_parameters
    t = np.linspace(0, 23, 47)
    proto = Protocol.reset_then_hold(6000, 20.0)
    a = simulate(vshape81, proto, load=5.0, t_eval=t)
    b = simulate(vshape81.replace(law="spline"), proto, load=5.0, t_eval=t)
    assert np.max(np.abs(a.x - b.x)) < 1e-9 * np.max(a.x)
    law = from_parameters(vshape81.replace(law="spline", d_rho1=0.3, d_rho2=1.2, d_rho3=0.0))
    assert isinstance(law, MonotoneSplineResistivity)
    E_k, r_k = law.knots
    assert np.allclose(law.rho(E_k), r_k, rtol=1e-12)
    E = np.geomspace(1e4, 1e10, 2000)
    r = law.rho(E)
    assert np.all(np.diff(r) <= 1e-9 * r[:-1])
    assert r[0] == pytest.approx(vshape81.rho_l) and r[-1] == pytest.approx(r_k[-1])
    # what the solver sees (the tabulated law) is the same curve
    r_solver = ResistivityLaw.rho(law, E_k[1:3])
    assert np.allclose(r_solver, r_k[1:3], rtol=1e-3)


def test_spline_law_errors_name_the_key(vshape81):
    from dfa_model.io.parameters import ParameterError
    with pytest.raises(ParameterError, match="d_rho2"):
        vshape81.replace(law="spline", d_rho2=-0.1)
    with pytest.raises(ParameterError, match="E_hi"):
        vshape81.replace(law="spline", E_lo=1e8, E_hi=1e7)
    with pytest.raises(ParameterError, match="d_rho1: does not apply"):
        vshape81.replace(d_rho1=0.5)


@pytest.mark.parametrize("n_knots", [2, 3, 5, 6])
def test_spline_law_at_any_knot_count(vshape81, n_knots):
    """The spline carries 2-6 knots (n_knots), one drop fewer; two make a power law
    between its end knots. Resampled to one knot more (where the knot search starts), it
    passes through the law it came from at every new knot and stays monotone."""
    from dfa_model.physics.dielectrics import from_parameters
    from dfa_model.io.parameters import DROP_KEYS
    drops = [0.4, 1.1, 0.0, 0.7, 0.2][:n_knots - 1]
    p = vshape81.replace(law="spline", n_knots=n_knots, **dict(zip(DROP_KEYS, drops)))
    law = from_parameters(p)
    E_k, r_k = law.knots
    assert E_k.size == n_knots and np.allclose(law.rho(E_k), r_k, rtol=1e-12)
    if n_knots == 2:      # a power law: ln rho linear in ln E between the knots
        E = np.geomspace(p.E_lo, p.E_hi, 7)
        assert np.allclose(np.diff(np.log(law.rho(E)), 2), 0.0, atol=1e-12)
    if n_knots < 6:
        finer = law.resampled(n_knots + 1)
        assert finer.size == n_knots and np.all(finer >= 0)
        q = p.replace(n_knots=n_knots + 1, **dict(zip(DROP_KEYS, finer)))
        E_new, r_new = from_parameters(q).knots
        assert np.allclose(r_new, law.rho(E_new), rtol=1e-12)
    # and the model runs it, from a parameter file too
    assert parameters_roundtrip(p) == p


def parameters_roundtrip(p):
    import tomllib

    from dfa_model.io.parameters import from_dict
    return from_dict(tomllib.loads(p.to_toml()))


def test_spline_drops_beyond_the_knots_are_an_error(vshape81):
    from dfa_model.io.parameters import ParameterError
    with pytest.raises(ParameterError, match="d_rho4: must be 0 with n_knots = 4"):
        vshape81.replace(law="spline", d_rho4=0.5)
    with pytest.raises(ParameterError, match=r"n_knots: .*2 <= value <= 6"):
        vshape81.replace(law="spline", n_knots=7)
    assert vshape81.replace(law="spline", n_knots=5, d_rho4=0.5).n_knots == 5
