"""Compile the kernels ahead of time into the extension dfa_model._kernels_aot.

    python -m dfa_model.aot [--out DIR]

setup.py runs this when the package is built or installed (pip install ., pip install -e .),
so that a user's first `dfa simulate` does not compile anything (it took 25-35 s with
numba's just-in-time compiler, 105 s on a busy machine). The exports and their types are
listed in _jit.EXPORTS; the extension records the hash of the sources it was built from,
and _jit uses it only while that hash is current.

The code is generated for the machine that builds it (its CPU model and features, as
numba's just-in-time compiler does): for pycc's generic x86-64 the surrogate's kernel ran
the standard protocol in 228 us against 184 us just in time (its loops are written to be
vectorized). The extension records that target (target_cpu) and _jit uses it only on a CPU
that has it; DFA_AOT_CPU=generic builds a portable one (e.g. for a wheel to share).

numba's AOT compiler (numba.pycc) is pending deprecation in numba 0.57-0.68 with no
replacement yet. When it goes, or fails here, the package still works: _jit falls back
to numba's just-in-time compilation with its disk cache.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path


def _types():
    from numba import types
    f64, i64 = types.float64, types.int64
    arr = {f"F{r}": types.Array(f64, r, "C") for r in (1, 2, 3)}
    from ._jit import WORKSPACE_RANKS
    codes = {"i": i64, "f": f64, "b": types.boolean, "I1": types.Array(i64, 1, "C"), **arr,
             "W": types.Tuple(tuple(arr[f"F{r}"] for r in WORKSPACE_RANKS)),
             "n": types.none, "T2": types.UniTuple(f64, 2), "T6": types.UniTuple(f64, 6)}
    # integrate: (record, states, stats, y_end, trace)
    codes["R"] = types.Tuple((arr["F2"], arr["F2"], arr["F1"], arr["F1"], arr["F2"]))
    # the surrogate's integrate: (status, rows, steps, y_end)
    codes["S"] = types.Tuple((i64, i64, i64, arr["F1"]))
    return codes


def exports() -> list:
    """(export name, numba signature, Python function) of every kernel in _jit.EXPORTS."""
    import importlib

    from . import _jit
    if _jit.AOT is not None:             # an older build serves this process: compile numba's
        _jit.jit_all()
    codes = _types()
    where = {m.rpartition(".")[2]: m for m in _jit.KERNEL_MODULES}
    out = []
    for qualname, (args, result) in _jit.EXPORTS.items():
        module, name = qualname.split(".")
        fn = getattr(importlib.import_module(f".{where[module]}", __package__), name)
        out.append((_jit.export_name(qualname), codes[result](*(codes[c] for c in args.split())), fn.py_func))
    return out


def build(out_dir: str | os.PathLike) -> Path:
    """Compile the extension into out_dir; returns its path."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")    # pycc's pending-deprecation notice
        from numba.pycc import CC
    from . import _jit
    cc = CC(_jit.AOT_MODULE)
    cc.output_dir = str(out_dir)
    cc.verbose = False
    target = _target()
    if target:
        cc.target_cpu = "host"
    for name, sig, py_func in exports():
        cc.export(name, sig)(py_func)
    # the sources this build is of (_jit compares it with the current ones), and the CPU
    # it was generated for ("": any of the architecture)
    digest = _jit.source_digest()
    ns: dict = {}
    exec(f"def source_digest():\n    return {digest!r}\n\ndef target_cpu():\n    return {target!r}\n", ns)
    cc.export("source_digest", "unicode_type()")(ns["source_digest"])
    cc.export("target_cpu", "unicode_type()")(ns["target_cpu"])
    with warnings.catch_warnings(), _host_features(bool(target)):
        warnings.simplefilter("ignore")
        cc.compile()
    return Path(out_dir) / (_jit.AOT_MODULE + _ext_suffix())


def _target() -> str:
    """The CPU the build is for: this machine's (_host_target) unless DFA_AOT_CPU=generic
    (pycc's generic model of the architecture: "")."""
    want = os.environ.get("DFA_AOT_CPU", "host")
    if want not in ("host", "generic"):
        raise ValueError(f"DFA_AOT_CPU: got {want!r}, expected 'host' (the default) or 'generic'")
    return _host_target() if want == "host" else ""


def _host_target() -> str:
    """The host's CPU model and features (_jit.host_cpu), or "" where numba's AOT code
    generator cannot be given them (then the build is the generic one)."""
    from numba.core import codegen
    from . import _jit
    ok = hasattr(codegen.AOTCPUCodegen, "_customize_tm_features") and \
        hasattr(codegen.AOTCPUCodegen, "_get_host_cpu_features")
    return _jit.host_cpu() if ok else ""


class _host_features:
    """While on: numba's AOT code generator emits the host's CPU features (it names the
    host's model but leaves the features empty, and a virtual machine may mask some of
    the model's: the features are what the code may use)."""

    def __init__(self, on: bool):
        self.on = on

    def __enter__(self):
        if self.on:
            from numba.core import codegen
            self.cls, self.old = codegen.AOTCPUCodegen, codegen.AOTCPUCodegen._customize_tm_features
            self.cls._customize_tm_features = lambda cg: cg._get_host_cpu_features()
        return self

    def __exit__(self, *exc):
        if self.on:
            self.cls._customize_tm_features = self.old
        return False


def _ext_suffix() -> str:
    import sysconfig
    return sysconfig.get_config_var("EXT_SUFFIX")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dfa_model.aot", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).parent), help="output folder (default: the package)")
    args = ap.parse_args(argv)
    # numba compiles the callees on the way: keep their cache out of the package
    try:
        _target()
    except ValueError as exc:
        print(f"python -m dfa_model.aot: {exc}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="dfa_aot_") as tmp:
        os.environ.setdefault("NUMBA_CACHE_DIR", tmp)
        w = time.perf_counter()
        path = build(args.out)
    print(f"dfa_model: compiled the kernels ahead of time into {path} ({time.perf_counter() - w:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
