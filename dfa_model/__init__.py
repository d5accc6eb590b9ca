"""dfa_model: continuum model of dielectric fluid actuators (DFAs) with charge
retention at the film-liquid interface (Maxwell-Wagner-Sillars polarization).

    from dfa_model import preset, simulate, Protocol
    p = preset("vshape-table1")
    res = simulate(p, Protocol.reset_then_hold(6000, hold=20), load=5.0)
    res.unzipping_speed
"""
from ._jitcache import refresh as _refresh_jit_cache
from ._moved import install as _install_moved

_refresh_jit_cache()
_install_moved(__name__)

from .physics.dielectrics import ConstantResistivity, LinearResistivity, PhysicsWarning, ResistivityLaw  # noqa: E402
from .physics.model import DFAModel  # noqa: E402
from .io.parameters import ParameterError, Parameters, load, preset  # noqa: E402
from .io.results import Result  # noqa: E402
from .numerics.solver import SolverError, simulate  # noqa: E402
from .waveforms import DC, Bipolar, Load, Protocol, Sampled, Stage, Unipolar, WaveformError, from_function  # noqa: E402
from .io import protocol_file as _protocol_file  # noqa: E402,F401  (registers the protocol file format)

__all__ = ["ConstantResistivity", "LinearResistivity", "PhysicsWarning", "ResistivityLaw", "DFAModel",
           "ParameterError", "Parameters", "load", "preset", "Result", "SolverError", "simulate", "DC",
           "Bipolar", "Load", "Protocol", "Sampled", "Stage", "Unipolar", "WaveformError", "from_function"]
__version__ = "0.1.0"
