"""The DFA model as an FMI 2.0 co-simulation FMU (pythonfmu): see build.build_fmu."""
from .build import BuildError, build_fmu

__all__ = ["BuildError", "build_fmu"]
