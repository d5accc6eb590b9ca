"""reduced: low-order surrogates of the full DFA model (python-control objects), their
fitting against the full model, full-vs-reduced comparison, and the design of
polarity-inversion drive schemes.

    import reduced
    s = reduced.fit(preset("vshape-table1"))      # the default family: lattice (families.default_family)
    s.system()                       # control.NonlinearIOSystem
    s.simulate(Protocol.reset_then_hold(6000, 20), load=5.0).unzipping_speed
    s.save("act.surrogate.json"); reduced.load("act.surrogate.json")
"""
from .compare import compare
from .families import FAMILIES, build, charge, lattice, lumped
from .fitting import Condition, Envelope, evaluate, fit
from .files import load
from .surrogate import Surrogate, SurrogateError, SurrogateResult

__all__ = ["FAMILIES", "build", "charge", "lattice", "lumped", "compare", "Condition", "Envelope", "evaluate", "fit",
           "Surrogate", "SurrogateError", "SurrogateResult", "load"]
