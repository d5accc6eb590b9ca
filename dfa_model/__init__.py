"""dfa_model: continuum model of dielectric fluid actuators (DFAs) with charge
retention at the film-liquid interface (Maxwell-Wagner-Sillars polarization).

    from dfa_model import preset, simulate, Protocol
    p = preset("vshape-table1")
    res = simulate(p, Protocol.reset_then_hold(6000, hold=20), load=5.0)
    res.unzipping_speed
"""
from .dielectrics import ConstantResistivity, LinearResistivity, PhysicsWarning, ResistivityLaw
from .model import DFAModel
from .parameters import ParameterError, Parameters, load, preset
from .results import Result
from .solver import SolverError, simulate
from .waveforms import DC, Bipolar, Load, Protocol, Sampled, Stage, Unipolar, WaveformError, from_function

__all__ = ["ConstantResistivity", "LinearResistivity", "PhysicsWarning", "ResistivityLaw", "DFAModel",
           "ParameterError", "Parameters", "load", "preset", "Result", "SolverError", "simulate", "DC",
           "Bipolar", "Load", "Protocol", "Sampled", "Stage", "Unipolar", "WaveformError", "from_function"]
__version__ = "0.1.0"
