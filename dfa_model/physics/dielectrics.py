"""Resistivity laws of the liquid and dielectric time constants (Eq. 20).

A law maps the magnitude of the liquid field |E_l| (V/m) to rho_l (ohm m). Inside the
compiled solver a law is an id and a parameter array (`law_id`, `params`): 0 constant,
1 linear with floor (Eq. 21), 2 table (log rho linear in log |E|; the monotone spline law
is one). Any other law is a
subclass of `ResistivityLaw` that implements the NumPy method `rho(E_abs)`: it is
tabulated on a fine log grid (`TABLE_POINTS` points over `TABLE_RANGE` V/m), so new
physics never touches the solver (and the compiled code stays cached).
"""
from __future__ import annotations

import warnings

import numpy as np

from .equations import rho_of

TABLE_RANGE = (1e2, 1e10)
TABLE_POINTS = 4001

class PhysicsWarning(UserWarning):
    """The model ran outside its comfort zone but returned a valid result."""


class ResistivityLaw:
    """Base class. Subclasses either set `law_id` and `params` (built-in kernels) or
    implement `rho(E_abs)` in NumPy and inherit the tabulated kernel."""

    law_id = 2
    is_constant = False

    @property
    def params(self) -> np.ndarray:
        """Table of log rho on a uniform log-|E| grid: [n, log E_0, d log E, log rho...]."""
        if getattr(self, "_table", None) is None:
            lo, hi = np.log(TABLE_RANGE[0]), np.log(TABLE_RANGE[1])
            lE = np.linspace(lo, hi, TABLE_POINTS)
            r = np.asarray(self.rho(np.exp(lE)), float)
            if r.shape != lE.shape or not np.all(np.isfinite(r)) or np.any(r <= 0):
                raise ValueError(f"{type(self).__name__}.rho: must return finite positive resistivities "
                                 f"for |E| in {TABLE_RANGE} V/m")
            self._table = np.concatenate([[TABLE_POINTS, lo, lE[1] - lE[0]], np.log(r)])
        return self._table

    def rho(self, E):
        """rho_l (ohm m) at field magnitudes E (V/m), as the solver sees it."""
        E = np.abs(np.asarray(E, float))
        params = self.params
        return np.vectorize(lambda e: rho_of(self.law_id, params, e))(E)

    def clipped(self, E_abs_max: float) -> bool:
        """Whether the law was clipped at its floor for some |E| <= E_abs_max."""
        return False


class ConstantResistivity(ResistivityLaw):
    law_id = 0
    is_constant = True

    def __init__(self, rho_l: float):
        self.rho_l = float(rho_l)

    @property
    def params(self):
        return np.array([self.rho_l])

    def __repr__(self):
        return f"ConstantResistivity(rho_l={self.rho_l:g})"


class LinearResistivity(ResistivityLaw):
    """Eq. (21): rho_l = m_rho |E_l| + q_rho, clipped below at rho_min.

    With m_rho < 0 (the paper's fit, -3.34e5 m^2/A) the law goes negative above
    |E_l| = q_rho/|m_rho| (about 6e7 V/m): the floor keeps it physical."""

    law_id = 1

    def __init__(self, m_rho: float = -3.34e5, q_rho: float = 20e12, rho_min: float = 1e11):
        self.m_rho, self.q_rho, self.rho_min = float(m_rho), float(q_rho), float(rho_min)

    @property
    def params(self):
        return np.array([self.m_rho, self.q_rho, self.rho_min])

    @property
    def E_clip(self) -> float:
        """|E_l| above which the floor is active: inf if never, 0 if at every field
        (q_rho <= rho_min)."""
        if self.q_rho <= self.rho_min:
            return 0.0
        if self.m_rho >= 0:
            return np.inf
        return (self.rho_min - self.q_rho) / self.m_rho

    def clipped(self, E_abs_max):
        return E_abs_max > self.E_clip

    def __repr__(self):
        return f"LinearResistivity(m_rho={self.m_rho:g}, q_rho={self.q_rho:g}, rho_min={self.rho_min:g})"


class MonotoneSplineResistivity(ResistivityLaw):
    """A law of a shape nobody has to guess: ln rho a monotone (PCHIP) spline in ln |E|
    through 2 to SPLINE_KNOTS_MAX knots spaced evenly in ln |E| from E_lo to E_hi (one knot
    more than drops); rho_l below E_lo, constant above E_hi. The knot values are
    rho_l exp(-(d_1 + ... + d_k)) with drops d_k >= 0: non-increasing in the field
    (field-enhanced dissociation and charge injection lower the resistivity), and the
    constant law when every drop is 0. Two knots make a power law between E_lo and E_hi."""

    def __init__(self, rho_l: float, E_lo: float = 1e6, E_hi: float = 1e8, drops=(0.0, 0.0, 0.0)):
        self.rho_l, self.E_lo, self.E_hi = float(rho_l), float(E_lo), float(E_hi)
        self.drops = np.asarray(drops, float)
        if (self.drops.ndim != 1 or not 1 <= self.drops.size <= SPLINE_KNOTS_MAX - 1 or np.any(self.drops < 0)
                or not 0 < self.E_lo < self.E_hi):
            raise ValueError(f"MonotoneSplineResistivity: need 1 to {SPLINE_KNOTS_MAX - 1} drops >= 0 and "
                             f"0 < E_lo < E_hi")
        self._table = None

    @property
    def knots(self):
        """(E_k, rho_k): the knots (V/m, ohm m)."""
        E = np.geomspace(self.E_lo, self.E_hi, self.drops.size + 1)
        return E, self.rho_l * np.exp(-np.concatenate([[0.0], np.cumsum(self.drops)]))

    def resampled(self, n_knots: int) -> np.ndarray:
        """The drops of the law through n_knots knots that passes through this one at them
        (same E_lo, E_hi and level below E_lo): where a fit with more knots starts, so that
        the finer law starts as close to this one as its knots allow."""
        E = np.geomspace(self.E_lo, self.E_hi, n_knots)
        return np.maximum(-np.diff(np.log(self.rho(E))), 0.0)

    def rho(self, E):
        from scipy.interpolate import PchipInterpolator
        E_k, r_k = self.knots
        lE = np.log(np.clip(np.abs(np.asarray(E, float)), self.E_lo, self.E_hi))
        return np.exp(PchipInterpolator(np.log(E_k), np.log(r_k))(lE))

    def __repr__(self):
        return (f"MonotoneSplineResistivity(rho_l={self.rho_l:g}, E_lo={self.E_lo:g}, E_hi={self.E_hi:g}, "
                f"drops={self.drops.tolist()})")


SPLINE_KNOTS_MAX = 6    # parameters.n_knots' range: a law with more shape than this is not resolved by an
#                         actuator's stroke (each knot's drop moves the stroke through the charge in its field band)


def from_parameters(p) -> ResistivityLaw:
    if p.law == "constant":
        return ConstantResistivity(p.rho_l)
    if p.law == "spline":
        return MonotoneSplineResistivity(p.rho_l, p.E_lo, p.E_hi, spline_drops(p))
    return LinearResistivity(p.m_rho, p.q_rho, p.rho_min)


def spline_drops(p) -> tuple:
    """The spline law's drops in p (d_rho1 ... d_rho{n_knots - 1})."""
    from ..io.parameters import DROP_KEYS
    return tuple(getattr(p, k) for k in DROP_KEYS[:p.n_knots - 1])


def warn_if_clipped(law: ResistivityLaw, E_abs_max: float) -> bool:
    if law.clipped(E_abs_max):
        where = (f"at every field (q_rho = {law.q_rho:g} <= rho_min = {law.rho_min:g})" if law.E_clip == 0 else
                 f"above |E_l| = {law.E_clip:.3g} V/m")
        warnings.warn(f"resistivity law clipped: {law!r} is at its floor rho_min {where}, and |E_l| reached "
                      f"{E_abs_max:.3g} V/m; results use rho_l = rho_min there", PhysicsWarning, stacklevel=3)
        return True
    return False


def stack_time_constant(p, t_l):
    """Eq. (20): time constant of a film-liquid-film stack with liquid thickness t_l (s)."""
    t_l = np.asarray(t_l, float)
    num = 2 * p.tau_l * p.rho_f * p.t_f + p.tau_f * p.rho_l * t_l
    return num / (2 * p.rho_f * p.t_f + p.rho_l * t_l)


def blocked_end_state(p, V, t_l):
    """Closed-form DC steady state of a blocked stack (liquid gap t_l): the current is
    continuous and equal in both layers, J = V/(rho_l t_l + 2 rho_f t_f), so
    sigma_l = tau_l J and sigma_f = tau_f J. Returns (sigma_l, sigma_f)."""
    J = V / (p.rho_l * t_l + 2 * p.rho_f * p.t_f)
    return p.tau_l * J, p.tau_f * J
