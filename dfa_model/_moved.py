"""The module paths before the package was grouped by role (issue 26): `dfa_model.parameters`
is `dfa_model.io.parameters`, and so on. Scripts written against the old paths keep
working: importing one gives the module at its new place (the same module object)."""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys

MOVED = {
    "physics": ("kinematics", "dielectrics", "equations", "nodal", "model", "statics"),
    "numerics": ("kernels", "integrator", "stepper", "solver", "trace", "surrogate_kernel"),
    "io": ("parameters", "protocol_file", "recordings", "results", "plotting", "fileio", "statecodec", "synthetic"),
}


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def __init__(self, package: str):
        self.package = package
        self.old = {f"{package}.{m}": f"{package}.{group}.{m}" for group, ms in MOVED.items() for m in ms}

    def find_spec(self, fullname, path=None, target=None):
        if fullname in self.old:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        module = importlib.import_module(self.old[spec.name])
        self.spec = module.__spec__
        return module

    def exec_module(self, module):
        module.__spec__ = self.spec      # importlib set the old name's spec on it: the module keeps its own


def install(package: str) -> None:
    """Resolve the old paths under `package` (dfa_model, or the FMU's bundled copy)."""
    if not any(isinstance(f, _Finder) and f.package == package for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder(package))     # before any path finder: the old names are ours
