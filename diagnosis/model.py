"""What a fit varies: free parameters of the one model (dfa_model.Parameters keys), each
with its transform and bounds, and the physics pieces of the catalog that add some.

A `Spec` is a list of FreeParameter: the baseline's (rho_l, plus any nominal value the
data correct) or the baseline's plus a catalog entry's. `apply(p, spec, z)` returns the
Parameters the full model runs with: every piece is a key of the one model, so the CLI,
the FMU and the surrogates run the fitted physics as they are.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dfa_model.parameters import Parameters


@dataclass(frozen=True)
class FreeParameter:
    key: str             # a Parameters key
    log: bool = True     # fitted as log(value) (positive quantities spanning decades)
    lo: float = 0.0      # bounds in the parameter's own units
    hi: float = math.inf
    scale: float = 1.0   # typical size, for a parameter fitted linearly (and starts at 0)

    def to_z(self, value: float) -> float:
        return math.log(value) if self.log else value / self.scale

    def from_z(self, z: float) -> float:
        return math.exp(z) if self.log else z * self.scale

    def z_bounds(self) -> tuple[float, float]:
        if self.log:
            return (math.log(self.lo) if self.lo > 0 else -math.inf, math.log(self.hi) if self.hi < math.inf
                    else math.inf)
        return (self.lo / self.scale, self.hi / self.scale)


def resistivity_key(p: Parameters) -> str:
    """The key that sets the liquid's resistivity level: rho_l (constant law) or the
    linear law's intercept q_rho."""
    return "q_rho" if p.law == "linear" else "rho_l"


def apply(p: Parameters, spec, z) -> Parameters:
    changes = {f.key: f.from_z(float(v)) for f, v in zip(spec, z)}
    return p.replace(**changes) if changes else p


def start(p: Parameters, spec) -> np.ndarray:
    return np.array([f.to_z(getattr(p, f.key)) for f in spec])
