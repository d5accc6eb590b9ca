"""The surrogate families: where each one's maps come from.

lumped   The literature's control-oriented circuit: the zipped region as a film capacitor
         (C_f, leakage R_f) in series with a liquid capacitor (C_l(x), R_l(x)), both
         proportional to the zipped length l_z(x); the interface charge per zipped area
         is the state; the force is Eq. (10)'s lumped co-energy with the liquid layer's
         field reduced by that charge:  F_e = (w/2) dl_z/dx c_f c_l/(c_f+c_l) (V - q/c_f)^2.
         Every number from geometry and materials: no fitting (refine with fit()).
charge   Reduced charge dynamics of the full model. At a frozen stroke the full model's
         charge equations are linear and every zipped element has the same pole, so the
         charge of material the front has crossed reduces exactly to one state q_z;
         the force and current are the full model's own static maps with that charge
         (frozen.uniform_charge_tables). But the force acts through the few elements
         at the front, not through zipped material, and they charge at their own
         rates: a front-layer state q_d = q_z - q_f whose rates (a_f, b_f) match the
         full model's force-weighted charge at s = 0 and s = infinity
         (frozen.front_layer). The moving front renews the layer over a length
         ell(x) = c_ell w_f(x), w_f the layer's width read off the full model's force
         sensitivity (frozen.front_layer): retreating, with zipped material; advancing,
         with the material beyond, which still carries a share beta_f of the layer's
         deficit (a front that comes back finds much of its old layer). c_ell and
         beta_f are fit()'s two numbers.
"""
from __future__ import annotations

import numpy as np

from dfa_model import DFAModel

from . import frozen
from .kernel import A_F, A_Q, B_F, B_V, C0, C1, C2, DLZ, I0, I1, J0, J1, NTAB, W_F
from .surrogate import Surrogate

FAMILIES = ("lumped", "charge")


def lumped(params, n_grid: int = 161) -> Surrogate:
    """The lumped equivalent circuit from geometry and materials (no fitting)."""
    model = frozen.as_model(params)
    p = model.params
    c_f, c_l = p.eps_f / (2.0 * p.t_f), p.eps_l / p.t_lz           # F/m^2 of zipped area
    g_f, g_l = 1.0 / (2.0 * p.t_f * p.rho_f), 1.0 / (p.rho_l * p.t_lz)  # S/m^2
    cs = c_f + c_l
    xg = np.linspace(0.0, model.kin.x_e, n_grid)
    lz, dlz = model.kin.lz(xg), model.kin.dlz_dx(xg)
    tab = np.zeros((n_grid, NTAB))
    c0 = 0.5 * p.w * dlz * c_f * c_l / cs
    tab[:, C0], tab[:, C1], tab[:, C2] = c0, -2.0 * c0 / c_f, c0 / c_f ** 2
    a, b = -(g_f + g_l) / cs, (c_f * g_l - c_l * g_f) / cs
    tab[:, A_Q], tab[:, B_V] = a, b
    tab[:, A_F], tab[:, B_F] = a, b     # no front layer of its own: no deficit state
    # source current: the film's charge c_f (V - v_l) on the zipped area, its change
    # (motion and charging), and the film's leakage g_f (V - v_l); V - v_l = (c_l V + q)/cs
    area, darea = p.w * lz, p.w * dlz
    tab[:, I0] = area * (c_f / cs * b + g_f * c_l / cs)
    tab[:, I1] = area * (c_f / cs * a + g_f / cs)
    tab[:, J0], tab[:, J1] = darea * c_f * c_l / cs, darea * c_f / cs
    tab[:, DLZ] = dlz
    tab[:, W_F] = 1.0       # no front layer: never read
    info = {"source": "geometry and materials (lumped circuit)", "tau": -1.0 / a}
    return Surrogate("lumped", p, xg, tab, info=info)


def charge(params, n_grid: int = 161, c_ell: float = 1.0, beta_f: float = 1.0) -> Surrogate:
    """Reduced charge dynamics read off the full model (c_ell, beta_f: the front layer's
    renewal, Surrogate; until fitted, ell = w_f and a returning front finds its layer)."""
    model = frozen.as_model(params)
    xg, tab = frozen.uniform_charge_tables(model, n_grid)
    info = {"source": "full model's frozen-stroke maps (reduced charge dynamics)", "tau": -1.0 / tab[0, A_Q]}
    return Surrogate("charge", model.params, xg, tab, c_ell, beta_f, info)


def build(params, family: str, **kw) -> Surrogate:
    if family not in FAMILIES:
        raise ValueError(f"family: got {family!r}, expected one of {', '.join(FAMILIES)}")
    return lumped(params, **kw) if family == "lumped" else charge(params, **kw)
