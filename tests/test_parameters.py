import pathlib

import pytest

from dfa_model import ParameterError, Parameters, load, preset
from dfa_model.io.parameters import apply_sets, from_dict


def test_presets_load_and_round_trip(tmp_path):
    for name in ("vshape-table1", "peano-fig10"):
        p = preset(name)
        path = tmp_path / f"{name}.toml"
        p.save(path)
        assert load(path) == p


def test_table1_values(vshape):
    assert vshape.a == 0.0119 and vshape.l == 0.055 and vshape.rho_l == 2e12
    assert abs(vshape.theta0 - 0.4363) < 1e-3        # 25 degrees


@pytest.mark.parametrize("change,key", [
    (dict(a=0.06), "a"),
    (dict(l_e=0.05), "l_e"),
    (dict(t_f=-1e-6), "t_f"),
    (dict(N=1), "N"),
    (dict(N=2.5), "N"),
    (dict(rho_l=float("nan")), "rho_l"),
    (dict(scheme="euler"), "scheme"),
])
def test_invalid_values_name_the_key(vshape, change, key):
    with pytest.raises(ParameterError) as e:
        vshape.replace(**change)
    assert str(e.value).startswith(f"{key}:")
    assert "expected" in str(e.value) or "must" in str(e.value)


def test_unknown_and_missing_keys():
    d = preset("vshape-table1").to_dict()
    d["geometry"]["apex"] = 1.0
    with pytest.raises(ParameterError, match=r"geometry\.apex: unknown key"):
        from_dict(d)
    d = preset("vshape-table1").to_dict()
    del d["materials"]["rho_l"]
    with pytest.raises(ParameterError, match=r"materials\.rho_l: missing"):
        from_dict(d)
    with pytest.raises(ParameterError, match="layout"):
        from_dict({"geometry": {}})


def test_peano_volume_too_large(peano):
    with pytest.raises(ParameterError, match="volume"):
        peano.replace(volume=1e-3)


def test_set_assignments(vshape):
    p = apply_sets(vshape, ["rho_l=2.5e12", "N=100", "a=0.0119"])
    assert p.rho_l == 2.5e12 and p.N == 100 and isinstance(p.N, int)
    with pytest.raises(ParameterError, match="N:"):
        apply_sets(vshape, ["N=abc"])
    with pytest.raises(ParameterError, match="--set"):
        apply_sets(vshape, ["N"])


def test_bad_toml_file(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("layout = \n")
    with pytest.raises(ParameterError, match="not valid TOML"):
        load(f)
    with pytest.raises(ParameterError, match="cannot read"):
        load(tmp_path / "missing.toml")


def test_default_parameters_are_table1():
    assert Parameters() == preset("vshape-table1")


def test_jit_cache_is_dropped_when_kernel_sources_change(tmp_path, monkeypatch):
    """numba's cache ignores changes in inlined callees from other files; we hash them."""
    import shutil

    from dfa_model import _jitcache
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    for m in _jitcache.KERNEL_MODULES:
        (pkg / f"{m}.py").parent.mkdir(exist_ok=True)
        (pkg / f"{m}.py").write_text(f"# {m}\n")
    shutil.copy(_jitcache.__file__, pkg / "_jitcache.py")
    (tmp_path / "pyproject.toml").write_text("")     # a source checkout (installed copies write nothing)
    monkeypatch.syspath_prepend(str(tmp_path))
    import importlib
    jc = importlib.import_module("pkg._jitcache")
    jc.refresh()
    (pkg / "physics" / "__pycache__").mkdir()
    stale = pkg / "physics" / "__pycache__" / "nodal.rhs_p1-1.py311.nbi"
    stale.write_text("x")
    jc.refresh()
    assert stale.exists()                          # unchanged sources: cache kept
    (pkg / "physics" / "nodal.py").write_text("# changed\n")
    jc.refresh()
    assert not stale.exists()                      # a kernel source changed: cache dropped


def test_jit_cache_hashes_every_kernel_module():
    """_jitcache keeps its own list (it runs before anything is compiled or loaded): it
    must name every module whose kernels are compiled, or an edit there keeps stale code."""
    from dfa_model import _jit, _jitcache
    assert [m.replace("/", ".") for m in _jitcache.KERNEL_MODULES] == list(_jit.KERNEL_SOURCES)
    import pathlib
    import re
    pkg = pathlib.Path(_jit.__file__).parent
    compiled = sorted(str(f.relative_to(pkg).with_suffix("")).replace("/", ".") for f in pkg.rglob("*.py")
                      if re.search(r"^@njit", f.read_text(), re.M))
    assert compiled == sorted(_jit.KERNEL_MODULES)
    # what a kernel module imports from the package is compiled in (numba freezes a
    # module's constants): it is hashed too, or an edit there keeps stale code
    import sys
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    try:
        from test_imports import imports, modules
    finally:
        sys.path.remove(str(pathlib.Path(__file__).parent))
    graph = imports(modules(), module_level=True)
    used = {d.removeprefix("dfa_model.") for m in _jit.KERNEL_MODULES for d in graph[f"dfa_model.{m}"]}
    assert used - {"_jit"} <= set(_jit.KERNEL_SOURCES), sorted(used - {"_jit"} - set(_jit.KERNEL_SOURCES))


def test_installed_copy_keeps_numba_cache_out_of_its_folder(tmp_path):
    """pip's uninstall removes only the files it installed: numba cache files written into
    an installed site-packages/dfa_model/ outlived it as a namespace package that shadowed
    a later editable install. An installed copy (no pyproject.toml beside it) compiled just
    in time must cache in the user's cache folder instead."""
    import os
    import shutil
    import subprocess
    import sys

    import dfa_model
    site = tmp_path / "site"
    shutil.copytree(pathlib.Path(dfa_model.__file__).parent, site / "dfa_model",
                    ignore=shutil.ignore_patterns("__pycache__", "_kernels_aot*"))
    cache = tmp_path / "cache"
    env = {**os.environ, "DFA_JIT": "1", "XDG_CACHE_HOME": str(cache), "PYTHONPATH": str(site)}
    env.pop("NUMBA_CACHE_DIR", None)
    code = ("import numpy as np, dfa_model; from dfa_model.physics import equations as e\n"
            "assert dfa_model.__file__.startswith(%r)\n"
            "print(e.rho_of(1, np.array([-1e3, 2e12, 1e11]), 5e7))" % str(site))
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert abs(float(out.stdout) - 2e12 + 5e10) < 1e3
    written = [p for p in (site / "dfa_model").rglob("*") if p.is_file()]
    assert not [p for p in written if p.suffix in (".nbi", ".nbc", ".sha256")], written
    assert list(cache.rglob("equations.rho_of-*.nbi"))            # cached where the user caches
