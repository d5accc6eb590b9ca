"""The full model at frozen strokes: its electrical subsystem and its static maps.

At a fixed stroke x and a constant resistivity law, the full model's interface-charge
equations are linear in (q, V) and its electrostatic force is a quadratic form in (V, q).
Everything here is read off the full model (`DFAModel.rhs`, `.electrostatic_force`,
`.diagnostics`) by evaluating it at chosen states - never from a copy of its equations -
so a surrogate follows whatever physics the model carries.
"""
from __future__ import annotations

import numpy as np

from dfa_model import DFAModel, Parameters
from dfa_model.equations import R_I, U0

from .kernel import A_F, A_Q, B_F, B_V, C0, C1, C2, DLZ, I0, I1, J0, J1, NTAB, W_F

V_REF = 1000.0     # V: evaluation amplitude (the maps are exact quadratic/affine forms)
N_FRONT = 41       # grid points of the front layer's rates (about 25 ms each)
W_F_MIN = 0.5      # the front layer's least width, in u0


def as_model(params) -> DFAModel:
    if isinstance(params, DFAModel):
        model = params
    elif isinstance(params, Parameters):
        model = DFAModel(params)
    else:
        raise TypeError("expected Parameters or DFAModel")
    if not model.law.is_constant:
        raise ValueError(f"law: the surrogates need the constant resistivity law (linear charge dynamics), got "
                         f"{model.params.law!r}")
    if model.params.scheme == "paper":
        raise ValueError("scheme: the surrogates are fitted to the 'continuum' or 'continuum-p0' schemes, "
                         "not 'paper'")
    # one line naming the key, not a shape error from deep inside the maps
    if model.polarized:
        raise ValueError(f"chi_p: the surrogates do not carry the polarization branch (chi_p = {model.params.chi_p:g}): "
                         "its second state per material point has no reduced form here yet")
    if model.series:
        raise ValueError(f"R_s: the surrogates do not carry a series resistance (R_s = {model.params.R_s:g} ohm): the "
                         "device voltage behind it has no reduced state here yet")
    return model


def u0(model: DFAModel) -> float:
    """The zipped liquid's effective thickness t_lz + 2 eps_l t_f / eps_f (m)."""
    return float(model.mat[U0])


def q_scale(model: DFAModel) -> float:
    """Interface-charge scale (C/m^2): the zipped liquid's surface charge at 1 kV."""
    return float(model.scales(V_REF)[model.nbord])


def state(model: DFAModel, x: float, q=None, v: float = 0.0) -> np.ndarray:
    y = model.initial_state(x)
    if model.nbord == 2:
        y[1] = v
    if q is not None:
        y[model.nbord:] = q
    return y


def electrical_lti(model: DFAModel, x: float):
    """(A, B) of dq/dt = A q + B V at frozen stroke x (q: the model's element states)."""
    nb, n = model.nbord, model.n_states
    qs = q_scale(model)
    y = state(model, x)
    f0 = model.rhs(y, 0.0, 0.0)[nb:]
    A = np.empty((n, n))
    for j in range(n):
        yy = y.copy()
        yy[nb + j] = qs
        A[:, j] = (model.rhs(yy, 0.0, 0.0)[nb:] - f0) / qs
    B = (model.rhs(y, V_REF, 0.0)[nb:] - f0) / V_REF
    return A, B


def force_sensitivity(model: DFAModel, x: float) -> np.ndarray:
    """dF_e/dq_j per volt at q = 0 (the force's bilinear V q term): where along the
    electrode the interface charge acts on the force."""
    n = model.n_states
    qs = q_scale(model)
    Fv = model.electrostatic_force(state(model, x), V_REF)
    h = np.empty(n)
    for j in range(n):
        q = np.zeros(n)
        q[j] = qs
        y = state(model, x, q)
        h[j] = (model.electrostatic_force(y, V_REF) - Fv - model.electrostatic_force(y, 0.0)) / (qs * V_REF)
    return h


def zipped_rates(model: DFAModel):
    """(a, b) of dq/dt = a q + b V for zipped material: every fully zipped element has
    the same dynamics, read at the middle of an all-zipped electrode (x = x_e)."""
    nb, n = model.nbord, model.n_states
    qs = q_scale(model)
    x_e = model.kin.x_e
    j = nb + n // 2
    f0 = model.rhs(state(model, x_e), 0.0, 0.0)[j]
    a = (model.rhs(state(model, x_e, np.full(n, qs)), 0.0, 0.0)[j] - f0) / qs
    b = (model.rhs(state(model, x_e), V_REF, 0.0)[j] - f0) / V_REF
    return float(a), float(b)


def front_layer(model: DFAModel, x: float, zipped=None):
    """(a_f, b_f, w_f) of the front layer at stroke x.

    (a_f, b_f): the one-pole model b_f / (s - a_f) of the force-weighted charge
    h^T q / h^T 1 (h: force_sensitivity; zipped material has h = 0, the force acts
    through the material just beyond the front) whose Markov parameter (h^T B / h^T 1:
    the charging rate, which sets the ripple under fast inversion) and DC gain
    (-h^T A^-1 B / h^T 1: the steady charge) are the full model's (moment matching at
    s = infinity and s = 0).
    w_f: the layer's width, the force-weighted mean distance of that material beyond
    the front, sum h_j (s_j - l_z) / sum h_j (m). It sets how far the front must move to
    replace the layer with zipped material; it shrinks from 5-8 u0 with the front near the hinge
    to nothing at the electrode end, as the gap opens ever faster beyond the front.
    Where no material is at the front (h = 0), zipped rates (`zipped`: zipped_rates(model),
    if the caller has them) and w_f = NaN."""
    A, B = electrical_lti(model, x)
    h = force_sensitivity(model, x)
    H = h.sum()
    a, b = zipped if zipped is not None else zipped_rates(model)
    if not abs(H) > 1e-9 * np.abs(h).sum() or not np.isfinite(H):
        return a, b, float("nan")
    s = model.element_edges()[: len(h)]      # the charge states sit at the element edges
    w_f = float(h @ (s - float(model.kin.lz(x)))) / H
    m0 = float(h @ B) / H
    g0 = float(h @ np.linalg.solve(A, -B)) / H
    if not (m0 * b > 0 and g0 * b > 0):     # a front that does not charge like a layer
        return a, b, w_f
    return -m0 / g0, m0, w_f


def _current(model: DFAModel, x, V, q, xdot):
    """Device current at stroke x, voltage V, uniform charge q and stroke velocity xdot:
    the load is chosen so the mechanics give that velocity."""
    p = model.params
    y = state(model, x, q, xdot)
    Fe = model.electrostatic_force(y, V)
    F = Fe - p.k * x - p.b * xdot     # with a mass the velocity is the state y[1]; F then only sets dv/dt
    return model.diagnostics(y, V, F)[0][R_I]


def uniform_charge_tables(model: DFAModel, n_grid: int = 161) -> tuple[np.ndarray, np.ndarray]:
    """Tables over x in [0, x_e] of the full model with a uniform interface charge q:
    F_e = c0 V^2 + c1 V q + c2 q^2, current = i0 V + i1 q + xdot (j0 V + j1 q),
    dl_z/dx; the charge columns hold the zipped material's rates (a, b) and the front
    layer's (a_f, b_f) and its width w_f (front_layer)."""
    x_e = model.kin.x_e
    xg = np.linspace(0.0, x_e, n_grid)
    n = model.n_states
    qs = q_scale(model)
    one = np.full(n, qs)
    a, b = zipped_rates(model)
    tab = np.zeros((n_grid, NTAB))
    dv = 1e-3 * x_e   # m/s: a probe velocity (the current is linear in it)
    for i, x in enumerate(xg):
        fv = model.electrostatic_force(state(model, x), V_REF)
        fq = model.electrostatic_force(state(model, x, one), 0.0)
        fvq = model.electrostatic_force(state(model, x, one), V_REF)
        tab[i, C0] = fv / V_REF ** 2
        tab[i, C2] = fq / qs ** 2
        tab[i, C1] = (fvq - fv - fq) / (V_REF * qs)
        iv = _current(model, x, V_REF, None, 0.0)
        iq = _current(model, x, 0.0, one, 0.0)
        tab[i, I0], tab[i, I1] = iv / V_REF, iq / qs
        tab[i, J0] = (_current(model, x, V_REF, None, dv) - iv) / (dv * V_REF)
        tab[i, J1] = (_current(model, x, 0.0, one, dv) - iq) / (dv * qs)
    tab[:, A_Q], tab[:, B_V] = a, b
    # the front layer's rates on a coarser grid (each point solves the charge system)
    xf = np.linspace(0.0, x_e, N_FRONT)
    af, bf, wf = np.array([front_layer(model, x, (a, b)) for x in xf]).T
    tab[:, A_F], tab[:, B_F] = np.interp(xg, xf, af), np.interp(xg, xf, bf)
    # no layer at the ends (nothing zipped, or all of it): the neighbours' width; at least
    # W_F_MIN u0, where the layer ends (the front on the electrode end, a stated breakdown)
    # and the renewal rate |dl_z/dt| / ell would otherwise grow without bound
    ok = np.isfinite(wf) & (wf > 0)
    wf = np.interp(xf, xf[ok], wf[ok]) if ok.any() else np.ones_like(xf)
    tab[:, W_F] = np.maximum(np.interp(xg, xf, wf), W_F_MIN * u0(model))
    tab[:, DLZ] = model.kin.dlz_dx(xg)
    return xg, tab
