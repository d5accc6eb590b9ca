"""Static force maps and equilibrium stroke (no interface charge: an actuator just
switched on, or driven by fast polarity inversion)."""
from __future__ import annotations

import warnings

import numpy as np

from .dielectrics import PhysicsWarning
from .model import DFAModel


def _model(p):
    return p if isinstance(p, DFAModel) else DFAModel(p)


def static_state(model: DFAModel, x: float, V: float) -> np.ndarray:
    """State at stroke x with no interface charge (sigma_f = sigma_l, Eq. 11)."""
    y = model.initial_state(x)
    if model.params.scheme == "paper":   # paper scheme: capacitive divider at each element midpoint
        s = model.element_edges()
        mid = 0.5 * (s[:-1] + s[1:])
        t_l = model.kin.t_l(mid, x)
        sig = model.params.eps_l * model.params.eps_f * V / (model.params.eps_f * t_l + 2 * model.params.eps_l * model.params.t_f)
        e = y[model.nbord:].reshape(model.M, 2)
        e[:, 0] = sig
        e[:, 1] = sig
    return y


def static_force(params, x, V):
    """Zipping force (N) at strokes x and voltage V from the model's own force
    (Eq. 8 integrated per element; Eq. 9 midpoint rule with the paper scheme)."""
    m = _model(params)
    return np.vectorize(lambda xx: m.electrostatic_force(static_state(m, xx, V), V))(x)


def force_eq10(params, x, V):
    """Eq. (10): -V^2/2 dC_z/dx with C_z the zipped-region capacitance (approximate)."""
    m = _model(params)
    p = m.params
    cz = p.eps_l * p.eps_f * p.w / (p.eps_f * p.t_lz + 2 * p.eps_l * p.t_f)
    return 0.5 * V ** 2 * cz * m.kin.dlz_dx(x)


def equilibrium_stroke(params, V, F, warn=True, k_load=0.0):
    """Stroke at which the static zipping force balances F + (k + k_load) x (k_load: a
    load spring), reached by zipping from x = 0 (the first crossing). Returns 0 (and
    warns) if the voltage cannot zip against F, and x_e if the front reaches the
    electrode end."""
    m = _model(params)
    k = m.params.k + k_load

    def net(x):
        return float(static_force(m, x, V)) - F - k * x

    x_e = m.kin.x_e
    if net(0.0) <= 0:
        if warn:
            warnings.warn(f"a voltage of {V:g} V cannot zip against {F:g} N (blocking force "
                          f"{float(static_force(m, 0.0, V)):.4g} N)", PhysicsWarning, stacklevel=2)
        return 0.0
    xs = np.linspace(0.0, x_e, 201)
    for a, b in zip(xs[:-1], xs[1:]):
        if net(b) <= 0:
            # bisection to 1e-15 m (~35 force evaluations): no SciPy import, which would
            # double a `dfa simulate --json` process's time (and the FMU never needs SciPy)
            while b - a > 1e-15 + 1e-13 * a:
                mid = 0.5 * (a + b)
                if mid <= a or mid >= b:
                    break
                a, b = (mid, b) if net(mid) > 0 else (a, mid)
            return 0.5 * (a + b)
    return x_e
