"""The DFA model as an FMI 2.0 co-simulation FMU (pythonfmu + fmu/c/fmi2_loader.c and
fmi2_python.c): see build.build_fmu; cosim runs it with the drive-electronics and load
companions, ssp.build_system packs the three as an SSP system."""
from .build import BuildError, build_companion_fmu, build_fmu
from .ssp import build_system

__all__ = ["BuildError", "build_companion_fmu", "build_fmu", "build_system"]
