"""What a fit varies: free parameters of the one model (dfa_model.Parameters keys), each
with its transform and bounds, and the physics pieces of the catalog that add some.

A `Spec` is a list of FreeParameter: the baseline's (the liquid's resistivity level, plus
any nominal value the data correct) or the baseline's plus a catalog entry's.
`apply(p, spec, z)` returns the Parameters the full model runs with: every piece is a key
of the one model, so the CLI, the FMU and the surrogates run the fitted physics as they are.

Most free parameters are a model key itself. A resistivity law is fitted in coordinates
of its own (`Coordinate`): its level is rho_l at a reference field E_ref (the zipped
liquid's field at the dataset's middle voltage) and its shape parameters move at a fixed
level there. In the law's own keys the level at the fields the recordings probe depends
on every key at once (Eq. 21's intercept q_rho and slope m_rho cancel there), so a step in
one key alone swings rho_l by tens of percent, through the linear law's floor: the search
stalled (m_rho = -330 against a true -6e4) in that long, curved valley.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dfa_model.physics.dielectrics import from_parameters
from dfa_model.io.parameters import Parameters
from dfa_model.io.synthetic import scaled_resistivity


@dataclass(frozen=True)
class Coordinate:
    """A fit coordinate that is not one model key: `get(p)` reads it, `put(p, v)` returns p
    with it set to v (keeping the spec's other coordinates where they were)."""
    kind: str            # 'level' (rho_l at E_ref), 'slope' (Eq. 21: d rho/rho per dE/E at E_ref), 'floor'
    #                      (Eq. 21: rho_min as a share of the unclipped law at E_ref), 'drop' (spline)
    E_ref: float         # reference field (V/m)
    key: str = ""        # the spline drop's model key

    def get(self, p: Parameters) -> float:
        if self.kind == "level":
            return rho_at(p, self.E_ref)
        if self.kind == "slope":
            return p.m_rho * self.E_ref / (p.q_rho + p.m_rho * self.E_ref)
        if self.kind == "floor":
            return p.rho_min / (p.q_rho + p.m_rho * self.E_ref)
        return getattr(p, self.key)

    def put(self, p: Parameters, v: float) -> Parameters:
        if self.kind == "level":
            return scaled_resistivity(p, v / rho_at(p, self.E_ref))
        if self.kind == "slope":
            r = p.q_rho + p.m_rho * self.E_ref      # the unclipped law at E_ref stays
            return p.replace(m_rho=r * v / self.E_ref, q_rho=r * (1.0 - v))
        if self.kind == "floor":
            return p.replace(rho_min=v * (p.q_rho + p.m_rho * self.E_ref))
        level = rho_at(p, self.E_ref)
        q = p.replace(**{self.key: v})
        return scaled_resistivity(q, level / rho_at(q, self.E_ref))


@dataclass(frozen=True)
class FreeParameter:
    key: str             # a Parameters key, or the coordinate's name
    log: bool = True     # fitted as log(value) (positive quantities spanning decades)
    lo: float = 0.0      # bounds in the parameter's own units
    hi: float = math.inf
    scale: float = 1.0   # typical size, for a parameter fitted linearly (and starts at 0)
    coord: Coordinate | None = None   # None: the model key itself

    def to_z(self, value: float) -> float:
        return math.log(value) if self.log else value / self.scale

    def from_z(self, z: float) -> float:
        return math.exp(z) if self.log else z * self.scale

    def z_bounds(self) -> tuple[float, float]:
        if self.log:
            return (math.log(self.lo) if self.lo > 0 else -math.inf, math.log(self.hi) if self.hi < math.inf
                    else math.inf)
        return (self.lo / self.scale, self.hi / self.scale)

    def get(self, p: Parameters) -> float:
        return self.coord.get(p) if self.coord else getattr(p, self.key)

    @property
    def is_level(self) -> bool:
        """Whether this is the liquid's resistivity level in log coordinates: a step in it
        scales the whole law, as a recording's resistivity factor does."""
        return self.log and (self.key == "rho_l" if self.coord is None else self.coord.kind == "level")


def zipped_field(p: Parameters, V: float) -> float:
    """The liquid's field in the zipped region of an uncharged actuator at voltage V (V/m)."""
    return abs(V) / (p.t_lz + 2.0 * p.t_f * p.eps_r_l / p.eps_r_f)


def rho_at(p: Parameters, E: float) -> float:
    """The liquid's resistivity at field E under p's law (ohm m)."""
    if p.law == "constant":
        return p.rho_l
    return float(np.asarray(from_parameters(p).rho(np.array([E])))[0])


def apply(p: Parameters, spec, z) -> Parameters:
    plain = {}
    for f, v in zip(spec, z):
        if f.coord is None:
            plain[f.key] = f.from_z(float(v))
    if plain:
        p = p.replace(**plain)
    for f, v in zip(spec, z):    # coordinates last: each keeps the others' values
        if f.coord is not None:
            p = f.coord.put(p, f.from_z(float(v)))
    return p


def start(p: Parameters, spec) -> np.ndarray:
    return np.array([f.to_z(f.get(p)) for f in spec])
