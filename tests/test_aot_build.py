"""The build of the kernels ahead of time (dfa_model/aot.py, run by setup.py at install).

A CI install once came without the extension, so every test process compiled the kernels
with numba: an editable install of the same sources was on the path, the builder loaded it,
and the kernel module it imported after `_jit.jit_all()` (the surrogate's) had its kernels
set to None - `build` then failed on `None.py_func` and setup.py fell back, as designed, to
just-in-time compilation. These tests run what `build` does before numba compiles (the
compilation itself takes minutes)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

LIST_EXPORTS = """
from dfa_model import _jit, aot
rows = aot.exports()
names = sorted(n for n, _, _ in rows)
assert names == sorted(_jit.export_name(q) for q in _jit.EXPORTS), names
bad = [n for n, _, f in rows if not callable(f) or getattr(f, "__module__", "").split(".")[0] != "dfa_model"]
assert not bad, bad
print(_jit.MODE, len(rows))
"""


def _run(code, **env):
    e = {k: v for k, v in os.environ.items() if k != "DFA_JIT"}
    e.update(env)
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=e, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.parametrize("jit", ["", "1"], ids=["an installed build serves", "numba only (the build hook)"])
def test_every_export_reaches_the_compiler_as_a_python_function(jit):
    """Whether or not a build of the same sources serves the builder's process (an editable
    install beside the one being built), every export is handed to numba.pycc as its Python
    function - none lost to None, none a compiled stand-in."""
    r = _run(LIST_EXPORTS, **({"DFA_JIT": jit} if jit else {}))
    assert r.returncode == 0, r.stderr[-3000:]
    mode, n = r.stdout.split()
    assert mode == ("jit" if jit else mode) and int(n) >= 10


def test_jit_all_gives_every_kernel_module_its_dispatchers():
    """jit_all in a process that has imported no kernel module yet: every kernel of every
    module is numba's dispatcher afterwards (it set the names of modules it imported itself
    to None)."""
    from dfa_model import _jit
    if _jit.MODE != "aot":
        pytest.skip("no compiled extension here: the kernels are numba's dispatchers from the start")
    code = """
import importlib
from dfa_model import _jit
_jit.jit_all()
where = {m.rpartition(".")[2]: m for m in _jit.KERNEL_MODULES}
for q in _jit.EXPORTS:
    module, name = q.split(".")
    fn = getattr(importlib.import_module("dfa_model." + where[module]), name)
    assert hasattr(fn, "py_func") and fn.py_func.__name__ == name, (q, fn)
print("ok")
"""
    r = _run(code)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-3000:]


def test_the_build_hook_compiles_its_own_sources():
    """setup.py runs the builder with DFA_JIT set, so an installed build is never loaded by it."""
    text = (ROOT / "setup.py").read_text()
    assert 'DFA_JIT="1"' in text


def test_an_extension_runs_only_on_the_cpu_it_was_built_for():
    """The extension is generated for the building machine's CPU (aot.py: its model and
    features); on another CPU its instructions may not exist, so _jit falls back to numba
    there rather than load it. A generic build ("", or one from before the target was
    recorded) runs anywhere."""
    from types import SimpleNamespace

    from dfa_model import _jit
    here = _jit.host_cpu()
    assert here.startswith(("cpuinfo:", "llvm:")) and here == _jit.host_cpu()
    assert _jit._runs_here(SimpleNamespace(target_cpu=lambda: here))
    assert _jit._runs_here(SimpleNamespace(target_cpu=lambda: ""))
    assert _jit._runs_here(SimpleNamespace())
    assert not _jit._runs_here(SimpleNamespace(target_cpu=lambda: "cpuinfo:" + "0" * 32))
    if _jit.AOT is not None:           # this build: for this machine (setup.py's default), or generic
        assert _jit.AOT.target_cpu() in (here, "")


def test_a_portable_build_is_asked_for_by_the_environment(monkeypatch):
    """DFA_AOT_CPU=generic builds for pycc's generic CPU model (no target recorded); the
    default is this machine; anything else is refused by name."""
    from dfa_model import _jit, aot
    monkeypatch.setenv("DFA_AOT_CPU", "generic")
    assert aot._target() == ""
    monkeypatch.setenv("DFA_AOT_CPU", "host")
    assert aot._target() in (_jit.host_cpu(), "")       # "": a numba whose AOT code generator cannot take it
    monkeypatch.delenv("DFA_AOT_CPU")
    assert aot._target() == aot._target() != "generic"
    monkeypatch.setenv("DFA_AOT_CPU", "skylake")
    with pytest.raises(ValueError, match="DFA_AOT_CPU: got 'skylake'"):
        aot._target()
