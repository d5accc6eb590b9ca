"""Surrogate files: read back what Surrogate.save and `dfa reduce --out` write (JSON: the
family, the parameter file, the maps, the fitted constants), checking every field."""
from __future__ import annotations

import json
import math
import tomllib

import numpy as np

from dfa_model.io.parameters import ParameterError
from dfa_model.io.parameters import from_dict as params_from_dict
from dfa_model.numerics import surrogate_kernel as sk

from .families import FAMILIES
from .surrogate import FORMAT, GIU_V7, VERSION, Surrogate

FIELDS = ("family", "params_toml", "x_grid", "tables", "n_points", "c_ell", "c_w")   # what a surrogate file holds


def _array(key, value, ndim) -> np.ndarray:
    """A surrogate file's list (of lists) of finite numbers as an array of `ndim` dimensions."""
    what = "a list of numbers" if ndim == 1 else "a list of rows of numbers (one row per grid point)"
    rows = value if isinstance(value, list) else []
    if ndim == 2:
        ok = bool(rows) and all(isinstance(r, list) for r in rows) and len({len(r) for r in rows}) == 1
        numbers = [x for r in rows for x in r] if ok else []
    else:
        ok, numbers = bool(rows), rows
    ok = ok and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in numbers)
    a = np.array(value, dtype=float) if ok else None
    if a is None or a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"{key}: expected {what}, all finite (the file is damaged: fit it again with dfa reduce)")
    return a


def from_dict(d: dict) -> Surrogate:
    """A Surrogate from the dict of its file (to_dict). Anything missing, of the wrong type
    or out of range is a ValueError naming the key (the file is damaged, or not one)."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ValueError(f"format: not a surrogate file (expected \"format\": \"{FORMAT}\", as dfa reduce --out "
                         f"writes)")
    version = d.get("version")
    if version not in (VERSION - 1, VERSION) or isinstance(version, bool):
        raise ValueError(f"version: got {version!r}, expected {VERSION - 1} or {VERSION}: this toolkit reads surrogate "
                         f"files of those versions (fit it again: dfa reduce)")
    for key in FIELDS:
        if key not in d:
            raise ValueError(f"{key}: missing (a surrogate file holds {', '.join(FIELDS)}; fit it again: dfa reduce)")
    if d["family"] not in FAMILIES:
        raise ValueError(f"family: got {d['family']!r}, expected one of {', '.join(FAMILIES)}")
    if not isinstance(d["params_toml"], str):
        raise ValueError(f"params_toml: got {type(d['params_toml']).__name__}, expected the parameter file as text")
    try:
        params = params_from_dict(tomllib.loads(d["params_toml"]), "the surrogate file")
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"params_toml: not a valid parameter file ({exc})") from None
    except ParameterError as exc:
        raise ValueError(f"params_toml: {exc}") from None
    x_grid, tables = _array("x_grid", d["x_grid"], 1), _array("tables", d["tables"], 2)
    if version == VERSION - 1 and tables.shape[1] > GIU_V7:
        # version 7 kept the fixed material's gap slope there, which modulated the layer's gap within
        # the material lag: dropped (it changed neither the 10 Hz holds nor the development panel)
        tables = np.delete(tables, GIU_V7, axis=1)
    if x_grid.size < 2 or not (x_grid[0] >= 0 and np.all(np.diff(x_grid) > 0)):
        raise ValueError("x_grid: expected at least 2 strokes, increasing from >= 0 (m)")
    n_points = d["n_points"]
    if isinstance(n_points, bool) or not isinstance(n_points, int):
        raise ValueError(f"n_points: got {n_points!r}, expected 0 or an integer >= 2")
    for key in ("c_ell", "c_w"):
        value = d[key]
        if value is None and key == "c_ell":        # inf: the lumped circuit's layer is never renewed
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and value > 0):
            raise ValueError(f"{key}: got {value!r}, expected a finite number > 0" +
                             (" (or null: never renewed)" if key == "c_ell" else ""))
    info = d.get("info")
    if info is not None and not isinstance(info, dict):
        raise ValueError(f"info: got {type(info).__name__}, expected a table (or null)")
    c_ell = d["c_ell"] if d["c_ell"] is not None else float("inf")
    c_m = d.get("c_m", 0.0)
    if isinstance(c_m, bool) or not isinstance(c_m, (int, float)) or not (math.isfinite(c_m) and c_m >= 0):
        raise ValueError(f"c_m: got {c_m!r}, expected a finite number >= 0 (0: no material lag)")
    c_adv = d.get("c_adv", 1.0)
    if isinstance(c_adv, bool) or not isinstance(c_adv, (int, float)) or not (0.0 <= c_adv <= 1.0):
        raise ValueError(f"c_adv: got {c_adv!r}, expected a number in [0, 1] (the advection kept within the lag)")
    s = Surrogate(d["family"], params, x_grid, tables, n_points, c_ell, info, d["c_w"], c_m=c_m, c_adv=c_adv)
    if not (np.all(s.tables[:, sk.WF] > 0) and np.all(s.tables[:, sk.CAP] > 0)):
        raise ValueError("tables: a layer width or capacitance <= 0, expected > 0 at every stroke (the file is "
                         "damaged: fit it again with dfa reduce)")
    # no device holds more than its two films in series over the whole electrode (the liquid
    # only lowers it): maps scaled past that are damaged, though finite (the lattice family
    # ran them, pinned at a stop)
    c_max = params.eps_f * params.w * params.l_e / (2.0 * params.t_f)
    cap = float(np.max(s.tables[:, sk.CAP]))
    if cap > 1.05 * c_max:
        raise ValueError(f"tables: a capacitance of {cap:.3g} F, expected at most the "
                         f"films' {c_max:.3g} F over the whole electrode (the file is damaged: fit it again with dfa "
                         f"reduce)")
    return s


def load(path) -> Surrogate:
    """Read a surrogate written by Surrogate.save / `dfa reduce`. Any failure is one
    ValueError line starting with the path."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            d = json.load(fh)
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror or exc}); expected a surrogate file written by dfa "
                         f"reduce --out") from None
    except ValueError as exc:          # json.JSONDecodeError, UnicodeDecodeError
        detail = f"{exc.msg} at line {exc.lineno}" if isinstance(exc, json.JSONDecodeError) else str(exc)
        raise ValueError(f"{path}: not JSON ({detail}); expected a surrogate file written by dfa reduce --out") \
            from None
    try:
        return from_dict(d)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
