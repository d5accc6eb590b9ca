"""The catalog of physics the paper's model leaves out, and the nominal values a fit may
correct. Each entry is a piece of the one model (a Parameters key or law), so a fitted
entry runs unchanged in the CLI, the FMU and the surrogates.

Adding an entry: an `Entry(name, prepare, spec)` below - `prepare(p)` switches the
physics on at a neutral start (it must not change the model's output there), `spec(p)`
lists its free parameters (diagnosis.model.FreeParameter) - and, if it is new physics, its
key in dfa_model (parameters.py, and the model's equations).

Available now (existing model pieces): stiffness (k), inertia (m),
field_dependent_resistivity (Eq. (21), the linear law). Not yet in the model:
series_resistance, polarization_branch, and a flexible monotone resistivity law.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from dfa_model.kinematics import make
from dfa_model.parameters import Parameters

from .model import FreeParameter, resistivity_key

CATALOG_IDS = ("field_dependent_resistivity", "polarization_branch", "stiffness", "series_resistance", "inertia")


@dataclass(frozen=True)
class Entry:
    name: str
    prepare: Callable[[Parameters], Parameters]
    spec: Callable[[Parameters], list]
    description: str
    kind: str = "physics"          # 'physics' (missing physics) or 'nominal' (a corrected value)


def _force_scale(p: Parameters) -> float:
    """A stiffness that costs about 1 N over the full stroke: k's fitting scale."""
    return 1.0 / make(p).x_e


def _field_scale(p: Parameters) -> float:
    """Typical liquid field in the zipped region at 10 kV (V/m)."""
    return 1e4 / (p.t_lz + 2.0 * p.t_f * p.eps_r_l / p.eps_r_f)


def _linear_law(p: Parameters) -> Parameters:
    if p.law == "linear":
        return p
    return p.replace(law="linear", q_rho=p.rho_l, m_rho=0.0, rho_min=0.01 * p.rho_l)


PHYSICS = [
    Entry("stiffness", lambda p: p,
          lambda p: [FreeParameter("k", False, 0.0, 1e6, scale=_force_scale(p))],
          "an elastic restoring force k x (films, bonded edges, a compliant load)"),
    Entry("inertia", lambda p: p,
          lambda p: [FreeParameter("m", False, 0.0, 100.0, scale=0.01)],
          "a generalized mass m (the stroke's acceleration)"),
    Entry("field_dependent_resistivity", _linear_law,
          # q_rho, the level, is the baseline's resistivity key under this law
          lambda p: [FreeParameter("m_rho", False, -1e20, 1e20, scale=p.q_rho / _field_scale(p))],
          "the liquid's resistivity depends on its field: Eq. (21), rho_l = m_rho |E_l| + q_rho"),
]

NOMINAL = [
    Entry(f"nominal:{key}", lambda p: p, (lambda key: lambda p: [FreeParameter(key, True, getattr(p, key) / 5,
                                                                              getattr(p, key) * 5)])(key),
          f"the nominal {key} is off", kind="nominal")
    for key in ("t_lz", "rho_f", "eps_r_l", "b")
]


def baseline_spec(p: Parameters) -> list:
    return [FreeParameter(resistivity_key(p), True, 1e8, 1e16)]
