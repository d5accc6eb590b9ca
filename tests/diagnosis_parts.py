"""The diagnosis's modules as one namespace, for the tests that reach into them: the
selection (diagnosis.rounds), the resolution checks (diagnosis.resolution), the shared
thresholds and judgements (diagnosis.rules) and the verdict (diagnosis.diagnose). A stub
must stand wherever the name is used, so `patch` sets it in every one of those modules
that holds it (each imports the others' names into its own)."""
from __future__ import annotations

import importlib

MODULES = ("diagnosis.rules", "diagnosis.resolution", "diagnosis.rounds", "diagnosis.diagnose")


def _modules():
    return [importlib.import_module(m) for m in MODULES]


class _Parts:
    """Attribute access across MODULES (the first that holds the name)."""

    def __getattr__(self, name):
        for mod in _modules():
            if name in vars(mod):
                return vars(mod)[name]
        raise AttributeError(f"no diagnosis module holds {name!r}")


dg = _Parts()


def patch(monkeypatch, name, value) -> None:
    """monkeypatch.setattr(module, name, value) in every one of MODULES that holds name."""
    held = [mod for mod in _modules() if name in vars(mod)]
    if not held:
        raise AttributeError(f"no diagnosis module holds {name!r}")
    for mod in held:
        monkeypatch.setattr(mod, name, value)
