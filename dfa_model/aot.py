"""Compile the kernels ahead of time into the extension dfa_model._kernels_aot.

    python -m dfa_model.aot [--out DIR]

setup.py runs this when the package is built or installed (pip install ., pip install -e .),
so that a user's first `dfa simulate` does not compile anything (it took 25-35 s with
numba's just-in-time compiler, 105 s on a busy machine). The exports and their types are
listed in _jit.EXPORTS; the extension records the hash of the sources it was built from,
and _jit uses it only while that hash is current.

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
    for name, sig, py_func in exports():
        cc.export(name, sig)(py_func)
    # the sources this build is of (_jit compares it with the current ones)
    digest = _jit.source_digest()
    ns: dict = {}
    exec(f"def source_digest():\n    return {digest!r}\n", ns)
    cc.export("source_digest", "unicode_type()")(ns["source_digest"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cc.compile()
    return Path(out_dir) / (_jit.AOT_MODULE + _ext_suffix())


def _ext_suffix() -> str:
    import sysconfig
    return sysconfig.get_config_var("EXT_SUFFIX")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m dfa_model.aot", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).parent), help="output folder (default: the package)")
    args = ap.parse_args(argv)
    # numba compiles the callees on the way: keep their cache out of the package
    with tempfile.TemporaryDirectory(prefix="dfa_aot_") as tmp:
        os.environ.setdefault("NUMBA_CACHE_DIR", tmp)
        w = time.perf_counter()
        path = build(args.out)
    print(f"dfa_model: compiled the kernels ahead of time into {path} ({time.perf_counter() - w:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
