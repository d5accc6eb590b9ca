"""The DFA model as an FMI 2.0 co-simulation FMU (pythonfmu + fmu/c/fmi2_loader.c and
fmi2_python.c) or, with fmi=3, an FMI 3.0 one (pythonfmu3 + fmu/c/fmi3_loader.c and
fmi3_python.c), both on one slave implementation (actuator_core.py): see
build.build_fmu; cosim runs the FMI 2.0 FMU with the drive-electronics and load
companions, ssp.build_system packs the three as an SSP system."""
from .build import BuildError, build_companion_fmu, build_fmu
from .ssp import build_system

__all__ = ["BuildError", "build_companion_fmu", "build_fmu", "build_system"]
