"""The surrogate a command designs or tunes on: a fitted one from a file (`--model`, written
by `dfa reduce`), checked to be of the same device as the parameters, or one fitted now
and kept in the user's cache, one per parameter set and family.

    s, note = surrogate_for(params, model="act.json")    # family None: families.default_family

A surrogate of another device is an error naming the keys that differ. Discretization
keys (N, scheme, rtol, rho_t_s) are not the device: a difference there is a note (the
surrogate's maps come from its own N; the full-model checks run at the parameters').
"""
from __future__ import annotations

import hashlib
import math
import os
from pathlib import Path

from dfa_model.io.parameters import Parameters

DISCRETIZATION = "discretization"
REL_TOL = 5e-6       # surrogate files before exact TOML numbers kept 6 significant digits


def _flat(params: Parameters) -> dict:
    out = {}
    for table, keys in params.to_dict().items():
        if isinstance(keys, dict):
            out.update({(table, k): v for k, v in keys.items()})
        else:
            out[("", table)] = keys
    return out


def _same(a, b) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return math.isclose(float(a), float(b), rel_tol=REL_TOL, abs_tol=0.0)


def device_differences(a: Parameters, b: Parameters):
    """([(key, a's value, b's value)] of the device's keys that differ, [(...)] of the
    discretization's)."""
    fa, fb = _flat(a), _flat(b)
    device, disc = [], []
    for k in sorted(set(fa) | set(fb), key=str):
        va, vb = fa.get(k, "absent"), fb.get(k, "absent")
        if not _same(va, vb):
            (disc if k[0] == DISCRETIZATION else device).append((k[1], va, vb))
    return device, disc


def check_same_device(s, params: Parameters, model_name: str, params_name: str) -> str | None:
    """ValueError naming the keys if surrogate `s` is of another device than `params`; a
    note (or None) on discretization differences."""
    device, disc = device_differences(s.params, params)
    if device:
        shown = "; ".join(f"{k} = {va!r} in {model_name}, {vb!r} in {params_name}" for k, va, vb in device[:4])
        more = f" (and {len(device) - 4} more)" if len(device) > 4 else ""
        raise ValueError(f"--model: {model_name} is a surrogate of another device: {shown}{more}; expected one of "
                         f"these parameters: fit it with dfa reduce --params FILE --out MODEL, or leave --model out")
    if disc:
        return ("the surrogate was fitted at " + ", ".join(f"{k} = {va!r}" for k, va, _ in disc) +
                "; the full-model checks run at " + ", ".join(f"{k} = {vb!r}" for k, _, vb in disc))
    return None


def cache_dir() -> Path:
    """$DFA_SURROGATE_CACHE, else the user's cache (~/.cache/dfa-toolkit/surrogates)."""
    if os.environ.get("DFA_SURROGATE_CACHE"):
        return Path(os.environ["DFA_SURROGATE_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "dfa-toolkit" / "surrogates"


def _code_digest() -> str:
    """What a cached surrogate depends on besides its parameters: this package's fitting
    and the model's kernels."""
    from dfa_model import _jit
    h = hashlib.sha256(_jit.source_digest().encode())
    here = Path(__file__).resolve().parent
    for name in ("families", "fitting", "frozen", "surrogate", "compare"):   # the kernel: _jit
        h.update((here / f"{name}.py").read_bytes())
    return h.hexdigest()


def cache_path(params: Parameters, family: str) -> Path:
    h = hashlib.sha256((params.to_toml() + family + _code_digest()).encode()).hexdigest()
    return cache_dir() / f"{family}-{h[:24]}.json"


def surrogate_for(params: Parameters, family: str | None = None, model=None, params_name="the parameters",
                  progress=True, say=None):
    """(surrogate, note): the one in file `model` (checked against `params`; its own
    family), else the
    cached fit for (params, family), else a new fit, cached (family None:
    families.default_family). `say(text)` reports what is happening (a fit takes seconds
    to a minute)."""
    from .families import default_family
    from .fitting import fit
    from .files import load
    if model is not None:
        s = load(model)          # the file decides the family
        return s, check_same_device(s, params, str(model), params_name)
    family = default_family(params) if family is None else family
    path = cache_path(params, family)
    if path.is_file():
        try:
            return load(path), f"surrogate from the cache ({path})"
        except ValueError:
            path.unlink(missing_ok=True)       # corrupt or of an old format: fit again
    if say:
        say(f"fitting a {family} surrogate for these parameters against the full model (once: it is cached in "
            f"{path.parent}; give one with --model FILE from dfa reduce)")
    s = fit(params, family=family, progress=progress)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        s.save(path)
        note = f"surrogate fitted now and cached ({path})"
    except OSError as exc:
        note = f"surrogate fitted now (not cached: {exc.strerror})"
    return s, note
