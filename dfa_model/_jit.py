"""Where the compiled kernels come from: compiled ahead of time, or just in time.

`pip install` compiles the kernels once into the extension `dfa_model._kernels_aot`
(dfa_model/aot.py, run by setup.py). A process that finds it, built from the current
kernel sources, never imports numba: the kernel modules' `njit` (this module's) then
returns a stand-in whose Python calls go to the compiled export. Importing numba and
loading its cache took most of a warm `dfa simulate` (0.4-0.6 s of 1 s); the extension
loads in about 5 ms.

Without it (no C compiler at install, a kernel source edited in a development checkout,
another Python version) `njit` is numba's own, and the kernels are compiled on first use
and cached on disk, as before. A call whose arguments are not of the compiled types (an
array of another dtype, layout or rank) also goes through numba: the compiled export
does not check them itself. So there is one implementation: the same Python functions,
compiled by numba either way.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from ._jitcache import installed

HERE = Path(__file__).parent
# modules whose njit functions go into the compiled code, under the package (also: what
# _jitcache hashes); EXPORTS and Kernel name them by their last part
KERNEL_MODULES = ("physics.equations", "physics.nodal", "physics.kinematics", "numerics.stepping", "numerics.kernels",
                  "numerics.stops", "numerics.records", "numerics.integrator", "numerics.surrogate_kernel")
# everything compiled into the kernels: their modules and the constants-only modules they
# import (the integrator's state slots), whose values numba freezes into the compiled code
KERNEL_SOURCES = (*KERNEL_MODULES, "numerics.trbdf2")
AOT_MODULE = "_kernels_aot"

# The compiled exports: "module.function" -> argument codes, result code. Codes:
# i int64, f float64, b bool, F1/F2/F3 float64 C-contiguous array of that rank, I1 int64
# array, W the integrator's workspace (integrator.make_workspace), R integrate's result,
# n None, T2/T6 tuples of floats, S the surrogate integrator's result. aot.py turns them into
# numba signatures.
EXPORTS = {
    "integrator.integrate": ("I1 F1 F1 i F1 F1 F1 F1 F1 F1 F1 f f F1 F1 b b i F1 W F1 b b i I1", "R"),
    "kernels.rhs": ("I1 F1 F1 i F1 f f F1 F1 F1 F1 F2 F1", "f"),
    "kernels.diagnostics": ("I1 F1 F1 i F1 f f f F1 F1 F1 F1 F1 F1", "n"),
    "equations.rho_of": ("i F1 f", "f"),
    "kinematics.kin_eval": ("i F1 f F1", "n"),
    "kinematics.zipping_angle": ("i F1 F1", "f"),
    "kinematics.profile": ("i F1 F1 f", "T2"),
    "kinematics.peano_state": ("f f f", "T6"),
    "kinematics.peano_theta_of_lz": ("f f f", "f"),
    "surrogate_kernel.integrate": ("F1 F1 F1 F1 F1 F1 F2 F1 F2 F1 i F1 F1 f f F2 i", "S"),
    "surrogate_kernel.evaluate": ("F1 f f F2 F1 i F1 F1 i", "T2"),
    "surrogate_kernel.pi_loop": ("F1 F2 F1 i F1 F1 f F1 i i i F2", "S"),
}
# ranks of the workspace's arrays (integrator.make_workspace)
WORKSPACE_RANKS = (3, 2, 2, 2, 3, 2, 2, 1, 1, 1, 2, 1)


def export_name(qualname: str) -> str:
    return qualname.replace(".", "__")


def source_digest() -> str:
    """Hash of everything compiled into the extension: the kernel sources, this table
    and the builder."""
    h = hashlib.sha256()
    for name in (*KERNEL_SOURCES, "_jit", "aot"):
        h.update((HERE / f"{name.replace('.', '/')}.py").read_bytes())
    return h.hexdigest()


def _installed_extension():
    """The extension of an installed dfa-toolkit, for a process that imports the package
    from a source checkout (tests run from a clone after `pip install .`): used only if
    built from the same sources (the caller checks the hash)."""
    import importlib.util
    import sysconfig
    from importlib import metadata
    name = f"dfa_model/{AOT_MODULE}{sysconfig.get_config_var('EXT_SUFFIX')}"
    # every dfa-toolkit on the path: the checkout's own build metadata comes first
    for f in (f for d in metadata.distributions(name="dfa-toolkit") for f in d.files or ()):
        if str(f) == name:
            path = Path(f.locate())
            if path.exists() and path.parent.resolve() != HERE.resolve():
                spec = importlib.util.spec_from_file_location(f"{__package__}.{AOT_MODULE}", path)
                mod = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(mod)
                return mod
    return None


def host_cpu() -> str:
    """This machine's CPU (the target of an extension built here: aot.py): a hash of its
    model and instruction-set flags - from /proc/cpuinfo where there is one (read in
    0.1 ms: llvmlite's names cost `import dfa_model` 18 ms), else LLVM's."""
    try:
        with open("/proc/cpuinfo") as fh:
            head = fh.read().split("\n\n", 1)[0]      # the first processor's block
        keep = [ln for ln in head.splitlines() if ln.split(":")[0].strip() in ("vendor_id", "model name", "flags")]
        if len(keep) == 3:
            return "cpuinfo:" + hashlib.sha256("\n".join(keep).encode()).hexdigest()[:32]
    except OSError:
        pass
    from llvmlite import binding as ll
    text = f"{ll.get_host_cpu_name()} {ll.get_host_cpu_features().flatten()}"
    return "llvm:" + hashlib.sha256(text.encode()).hexdigest()[:32]


def _runs_here(mod) -> bool:
    """Whether the extension's code runs on this CPU: built for any of the architecture
    (no target_cpu, or ""), or for this CPU model with these features."""
    target = mod.target_cpu() if hasattr(mod, "target_cpu") else ""
    return target == "" or target == host_cpu()


def _load_aot():
    if os.environ.get("DFA_JIT"):          # force numba (development, comparisons)
        return None
    try:
        try:
            from . import _kernels_aot as mod
        except ImportError:
            mod = _installed_extension()
        return mod if mod is not None and mod.source_digest() == source_digest() and _runs_here(mod) else None
    except Exception:                      # absent, another Python or NumPy ABI, unreadable sources
        return None


AOT = _load_aot()
MODE = "aot" if AOT is not None else "jit"


# ------------------------------------------------------------------ argument checks
def _array_check(char, ndim):
    def ok(a):
        # flags.carray: C-contiguous, aligned and writeable in one flags object (a third of the
        # check's time went into building three)
        return type(a) is np.ndarray and a.dtype.char == char and a.ndim == ndim and a.flags.carray
    return ok


def _is_int(v):
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _is_float(v):
    return isinstance(v, (float, int, np.floating, np.integer)) and not isinstance(v, (bool, np.bool_))


def _is_bool(v):
    return isinstance(v, (bool, np.bool_))


_WS_CHECKS = tuple(_array_check("d", r) for r in WORKSPACE_RANKS)


def _is_workspace(w):
    return type(w) is tuple and len(w) == len(_WS_CHECKS) and all(c(a) for c, a in zip(_WS_CHECKS, w))


_CHECKS = {"i": _is_int, "f": _is_float, "b": _is_bool, "F1": _array_check("d", 1), "F2": _array_check("d", 2),
           "F3": _array_check("d", 3), "I1": _array_check("l", 1), "W": _is_workspace}


# ------------------------------------------------------------------ the stand-in
_KERNELS: list["Kernel"] = []


class Kernel:
    """A kernel while the compiled extension serves it: calls with the compiled types go
    to the export; anything else (another type, a function not exported) compiles it
    with numba first (jit_all)."""

    def __init__(self, fn, options):
        self.py_func = fn
        self.options = options
        self.qualname = f"{fn.__module__.rsplit('.', 1)[-1]}.{fn.__name__}"
        self.dispatcher = None
        spec = EXPORTS.get(self.qualname)
        self._export = getattr(AOT, export_name(self.qualname), None) if spec else None
        self._checks = tuple(_CHECKS[c] for c in spec[0].split()) if spec else ()
        self.__name__, self.__doc__ = fn.__name__, fn.__doc__
        _KERNELS.append(self)

    def serves(self, args) -> bool:
        """Whether the compiled export takes these arguments (it exists, and they have
        its types)."""
        if self._export is None or len(args) != len(self._checks):
            return False
        for check, a in zip(self._checks, args):    # a loop, not all() over a generator: 3.0 -> 2.2 us
            if not check(a):
                return False
        return True

    def __call__(self, *args):
        if self.serves(args):
            return self._export(*args)
        if self.dispatcher is None:
            jit_all()
        return self.dispatcher(*args)


_LOCATOR_SET = False


def _cache_outside_installed_package() -> None:
    """Send numba's on-disk cache of an installed copy's kernels to the user's cache folder
    instead of the package's own __pycache__. pip's uninstall removes only the files it
    installed: cache files left in site-packages/dfa_model/ made an empty namespace package
    there, which shadowed a later editable install. The folder is keyed by the kernel
    sources' hash, so another version never loads these (numba keys a cache on its own
    file only; _jitcache does the same job in a checkout). NUMBA_CACHE_DIR still wins."""
    global _LOCATOR_SET
    if _LOCATOR_SET or not installed():
        return
    _LOCATOR_SET = True
    try:
        from numba.core import caching
        from numba.misc.appdirs import AppDirs
        classes = getattr(caching, "CacheImpl", None) or caching._CacheImpl   # _CacheImpl in older numba
        classes = classes._locator_classes
        base = caching.UserWideCacheLocator
    except (ImportError, AttributeError):   # another numba's internals: its default place
        return
    package = str(HERE.resolve())
    root = os.path.join(AppDirs(appname="dfa-toolkit", appauthor=False).user_cache_dir, "numba", source_digest()[:16])

    class InstalledPackageLocator(base):
        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = os.path.join(root, os.path.relpath(os.path.dirname(os.path.realpath(py_file)), package))

        @classmethod
        def from_function(cls, py_func, py_file):
            if not os.path.realpath(py_file).startswith(package + os.sep):
                return None
            return super().from_function(py_func, py_file)

    # after the user's own NUMBA_CACHE_DIR, before the in-tree __pycache__
    at = next((i + 1 for i, c in enumerate(classes) if c.__name__ == "UserProvidedCacheLocator"), 0)
    classes.insert(at, InstalledPackageLocator)


def jit_all():
    """Replace every stand-in by numba's dispatcher, in the kernel modules' namespaces
    too, so that kernels compiled now call their callees' dispatchers."""
    import importlib
    import sys

    from numba import njit as numba_njit
    _cache_outside_installed_package()
    pkg = __package__
    # every kernel module first: one imported below would keep stand-ins without dispatchers
    # (its names set to None: the AOT build crashed so when an older build served it)
    modules = [sys.modules.get(f"{pkg}.{name}") or importlib.import_module(f".{name}", pkg) for name in KERNEL_MODULES]
    for k in _KERNELS:
        if k.dispatcher is None:
            k.dispatcher = numba_njit(**k.options)(k.py_func)
    for mod in modules:
        for attr, value in list(vars(mod).items()):
            if isinstance(value, Kernel):
                setattr(mod, attr, value.dispatcher)


def njit(*args, **options):
    """numba.njit when the kernels are compiled just in time, else the stand-in."""
    if AOT is None:
        from numba import njit as numba_njit
        _cache_outside_installed_package()
        return numba_njit(*args, **options)
    if args and callable(args[0]):
        return Kernel(args[0], options)
    return lambda fn: Kernel(fn, options)


def prepare(kernel, *args) -> None:
    """Compile or load `kernel` for these arguments now (numba), so that a timed call
    that follows measures the computation only. Nothing to do for compiled exports."""
    disp = kernel.dispatcher if isinstance(kernel, Kernel) else kernel
    if isinstance(kernel, Kernel) and kernel.serves(args):
        return
    if disp is None:
        jit_all()
        disp = kernel.dispatcher
    disp.compile(tuple(disp.typeof_pyval(a) for a in args))
