"""Keep numba's on-disk cache consistent with the kernel sources.

numba keys a cached function on its own file only: a kernel that inlines a callee from
another module keeps the old compiled code after that module changes. We hash all kernel
sources and drop the package's cache files when the hash changes (before anything is
compiled or loaded). Only in a source checkout: an installed copy writes nothing into
its own folder (_jit keys its numba cache on the hash in the user's cache folder).
"""
from __future__ import annotations

import hashlib
from pathlib import Path

# _jit.KERNEL_SOURCES (a test checks they agree): the kernels' modules and the constants they compile in
KERNEL_MODULES = ("physics/equations", "physics/nodal", "physics/kinematics", "numerics/stepping", "numerics/kernels",
                  "numerics/stops", "numerics/records", "numerics/integrator", "numerics/surrogate_kernel",
                  "numerics/trbdf2")


def installed() -> bool:
    """Whether this package is an installed copy (a wheel's files in site-packages), not a
    source checkout (which has its pyproject.toml beside the package)."""
    return not (Path(__file__).parent.parent / "pyproject.toml").exists()


def refresh() -> None:
    here = Path(__file__).parent
    if installed():
        return
    try:
        digest = hashlib.sha256(b"".join((here / f"{m}.py").read_bytes() for m in KERNEL_MODULES)).hexdigest()
        cache = here / "__pycache__"
        stamp = cache / "dfa_kernels.sha256"
        if stamp.exists() and stamp.read_text() == digest:
            return
        # each module's cache sits in its own folder's __pycache__ (physics/, numerics/)
        for f in list(here.rglob("__pycache__/*.nbi")) + list(here.rglob("__pycache__/*.nbc")):
            f.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:
        pass
