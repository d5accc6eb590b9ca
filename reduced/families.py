"""The surrogate families: where each one's maps come from.

lumped   The literature's control-oriented circuit: the zipped region as a film capacitor
         (C_f, leakage R_f) in series with a liquid capacitor (C_l(x), R_l(x)), both
         proportional to the zipped length l_z(x); the interface charge per zipped area
         is the state; the force is Eq. (10)'s lumped co-energy with the liquid layer's
         field reduced by that charge:  F_e = (w/2) dl_z/dx c_f c_l/(c_f+c_l) (V - q/c_f)^2.
         Every number from geometry and materials: no fitting (refine with fit()).
charge   The full model reduced in material terms (dfa_model/numerics/surrogate_kernel.py has the
         states and their physics): the front layer, an effective material point whose
         rates match the full model's force-weighted charge at s = 0 and s = infinity
         at each frozen stroke (frozen.front_layer, frozen.front_point) and through
         which the force acts (the full model's quadratic map, exact in statics); its
         two wakes (c_w layer widths of zipped material behind it and unzipped material
         ahead, frozen.wake_gap); and N_POINTS material points that keep the charge
         history along the electrode (frozen.material_tables). With the polarization
         branch each state carries its P, and the branch's force over the unzipped
         length is quadratic in the points' P (frozen.polarization_weights). The moving
         front renews the layer over ell = c_ell w_f(x): fit()'s one number.
lattice  A material point at every node of the full model's lattice (no layer, no wakes,
         no renewal, nothing fitted; frozen.lattice_tables): each point has the full
         model's pointwise physics at its hat-weighted inverse gap (the nodal scheme with
         its Galerkin coupling lumped), the force is the full model's quadratic map in
         (V, q_i, P_i) and the current its affine map, read off at each stroke. N (2N with
         the branch) charge states: the most faithful family (every fidelity goal of
         issue 23 on the development panel and on three held-out draws) and the default
         (default_family); 9-15x faster than the full model in-process, the charge
         family 20-26x.
"""
from __future__ import annotations

import numpy as np

from dfa_model.numerics import surrogate_kernel as sk

from . import frozen
from .surrogate import Surrogate

FAMILIES = ("lumped", "charge", "lattice")
# the default family: the lattice wherever it applies (its fidelity held out: 112 of 112
# cells on three draws, against the charge family's 96), else the charge family
DEFAULT_FAMILY = "lattice"
N_POINTS = 15          # material points of the charge family (2.9 mm apart on Table 1's 40 mm electrode)
# the unfitted charge family's constants, chosen on development devices only (Table 1,
# Fig. 10a and a third V-shape; 8 physics x 7 drives, docs/guide/surrogates.md): the
# previous 11 points, c_ell 1.8 and c_w 4 (the behind wake renewed from the last zipped
# point) met every goal in 111 of 168 cells (mean stroke RMS 0.85 %, max 4.4 %), these
# in 133 (0.47 %, max 1.6 %)
C_ELL = 1.2            # the layer's renewal length over its width (fit()'s one number)
C_W = 2.0              # the wakes' width over the layer's
# the layer's material lag over its width (a play: surrogate_kernel's SM): within it the
# front's jitter does not mix the wakes into the layer and moves the layer's charge along
# the material at C_ADV of the renewal's advection. Chosen on the development devices
# (four 10 Hz PI holds, the same gains on a DC amplitude, the 168 cells): c_m 0.03 with
# c_adv 0.5 tracks the holds at 1.05-1.17x the full model's RMS (1.16-1.26x without the
# lag) and loses every DC hold the full model loses; c_adv 0 (the layer frozen within the
# lag) tracked at 1.00-1.13x but held 2 of those 4 DC loops and 4 of 4 on a random draw
# (0.5-2.8 um RMS against the full model's 78-283 um), c_adv 0.25 one of them; c_adv 0.75
# tracked at 1.10-1.19x; 134 of 168 cells (135 without the lag: +-2 cells is the
# floating point's noise there)
C_M = 0.03
C_ADV = 0.5


def effective_point(params, a: float, b: float) -> tuple[float, float]:
    """(1/u, T0') of the material point whose pointwise rates are dq/dt = a q + b V."""
    c = 1.0 / (params.rho_l * params.eps_l) - 1.0 / params.tau_f
    iu = b / (c * params.eps_l)
    return iu, -(a + 1.0 / params.tau_f) / (c * iu)


def lumped(params, n_grid: int = 161, force_scale: float = 1.0, rate_scale: float = 1.0) -> Surrogate:
    """The lumped equivalent circuit from geometry and materials (no fitting): one charge,
    the zipped region's, as the layer (no material points, no renewal)."""
    model = frozen.as_model(params)
    pm = frozen.plain(model)
    p = pm.params
    c_f, c_l = p.eps_f / (2.0 * p.t_f), p.eps_l / p.t_lz           # F/m^2 of zipped area
    g_f, g_l = 1.0 / (2.0 * p.t_f * p.rho_f), 1.0 / (p.rho_l * p.t_lz)  # S/m^2
    cs = c_f + c_l
    xg = np.linspace(0.0, model.kin.x_e, n_grid)
    lz, dlz = model.kin.lz(xg), model.kin.dlz_dx(xg)
    tab = np.zeros((n_grid, sk.NFIX))
    c0 = 0.5 * p.w * dlz * c_f * c_l / cs * force_scale
    tab[:, sk.C0], tab[:, sk.C1], tab[:, sk.C2] = c0, -2.0 * c0 / c_f, c0 / c_f ** 2
    a, b = -(g_f + g_l) / cs * rate_scale, (c_f * g_l - c_l * g_f) / cs * rate_scale
    tab[:, sk.IUF], tab[:, sk.T0F] = effective_point(p, a, b)
    # source current: the film's charge c_f (V - v_l) on the zipped area, its change
    # (motion and charging), and the film's leakage g_f (V - v_l); V - v_l = (c_l V + q)/cs
    area, darea = p.w * lz, p.w * dlz
    tab[:, sk.I0] = area * (c_f / cs * b + g_f * c_l / cs)
    tab[:, sk.I1] = area * (c_f / cs * a + g_f / cs)
    tab[:, sk.J0], tab[:, sk.J1] = darea * c_f * c_l / cs, darea * c_f / cs
    # the circuit's capacitance, at least the full model's with nothing zipped (a series
    # resistance divides by it)
    cap0 = pm.diagnostics(frozen.state(pm, 0.0), 1000.0)[0][frozen.R_C]
    tab[:, sk.CAP] = np.maximum(area * c_f * c_l / cs, cap0)
    tab[:, sk.DLZ], tab[:, sk.LZ] = dlz, lz
    tab[:, sk.WF] = 1.0       # no renewal: never read
    info = {"source": "geometry and materials (lumped circuit)", "tau": -1.0 / a, "force_scale": force_scale,
            "rate_scale": rate_scale}
    return Surrogate("lumped", model.params, xg, tab, 0, float("inf"), info)


def charge(params, n_grid: int = 161, c_ell: float = C_ELL, n_points: int = N_POINTS, c_w: float = C_W,
           c_m: float = C_M, c_adv: float = C_ADV) -> Surrogate:
    """Material points, the front layer and its wakes read off the full model
    (frozen.material_tables; c_ell: the layer's renewal length over its width, fit's
    number; c_w: the wakes' width over the layer's)."""
    model = frozen.as_model(params)
    xg, tab = frozen.material_tables(model, n_grid, n_points, c_w)
    a, _ = frozen.zipped_rates(frozen.plain(model))
    info = {"source": "full model's frozen-stroke maps (material points and the front layer)", "tau": -1.0 / a}
    return Surrogate("charge", model.params, xg, tab, n_points, c_ell, info, c_w, c_m=c_m, c_adv=c_adv)


def lattice(params, n_grid: int | None = None) -> Surrogate:
    """A material point at every node of the full model's lattice with the full model's
    pointwise physics at its hat-weighted gap, the force and the current read off the
    full model at each stroke (frozen.lattice_tables): no layer, no renewal, nothing
    fitted. Above N = frozen.LATTICE_N_MAX (201: a state per node, tables ~ N^2) the
    points are the nodes of the same actuator's lattice at N = 201, read off the full
    model there; the surrogate stands for the actuator at its own N (compare and the
    fit's checks run the full model at it). The Peano-HASEL preset (N = 401) on 201 points:
    28 of 28 cells (4 physics x 7 drives) meet every goal, within 0.39 % of range of the
    full model at N = 401; Table 1 at N = 401, 14 of 14 (docs/guide/surrogates.md)."""
    model = frozen.as_model(params)
    n = min(model.params.N, frozen.LATTICE_N_MAX)
    on = model if n == model.params.N else frozen.as_model(model.params.replace(N=n))
    xg, tab = frozen.lattice_tables(on, n_grid)
    a, _ = frozen.zipped_rates(frozen.plain(model))
    src = "every lattice node" if on is model else f"the {n} nodes of its lattice at N = {n}"
    info = {"source": f"full model's frozen-stroke maps at {src}", "tau": -1.0 / a}
    return Surrogate("lattice", model.params, xg, tab, n, float("inf"), info)


def default_family(params) -> str:
    """The family a surrogate of `params` gets when none is named: DEFAULT_FAMILY (the
    lattice), but the charge family for the 'continuum-p0' scheme, whose nodes the
    lattice does not read (frozen.lattice_tables)."""
    scheme = getattr(params, "scheme", None) or getattr(getattr(params, "params", None), "scheme", None)
    return DEFAULT_FAMILY if scheme == "continuum" else "charge"


def build(params, family: str | None = None, **kw) -> Surrogate:
    """The surrogate of `family` (FAMILIES; None: default_family(params)) for `params`,
    unfitted (reduced.fit fits the charge and lumped families' free numbers)."""
    family = default_family(params) if family is None else family
    if family not in FAMILIES:
        raise ValueError(f"family: got {family!r}, expected one of {', '.join(FAMILIES)}")
    return {"lumped": lumped, "charge": charge, "lattice": lattice}[family](params, **kw)
