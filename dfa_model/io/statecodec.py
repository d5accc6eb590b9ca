"""A binary codec for saved states that cannot run code, and a structural check of a
decoded state against a live one.

Why not pickle: an FMU state comes back from the host (fmi2DeSerializeFMUstate), and
unpickling bytes runs whatever they say. `decode` only ever builds the types below, checks
every length and offset before using it, and stops at fixed limits.

Values: nested dict (str keys) / tuple / list of None, bool, int (64-bit), float, str,
NumPy float64 / int64 scalars and C-ordered float64 / int64 arrays.

Layout, little-endian:
    8 bytes  MAGIC
    u32      VERSION
    u32      0 (reserved)
    u64      S, the length of the skeleton
    u64      B, the length of the array data
    S bytes  skeleton: UTF-8 JSON; each value is a JSON null / true / false / integer /
             string or a list [tag, ...]: ["f", float.hex] float, ["F", float.hex] NumPy
             float64, ["I", int] NumPy int64, ["T", [items]] tuple, ["L", [items]] list,
             ["D", [[key, value], ...]] dict, ["A", "f8" | "i8", [shape]] array
    B bytes  the arrays' data, in skeleton order, back to back
"""
from __future__ import annotations

import json
import math
import struct

import numpy as np

MAGIC = b"DFASTATE"
VERSION = 1
_HEAD = struct.Struct("<8sIIQQ")
# limits: far above any state of this project (a few hundred kB), far below harm
MAX_BYTES = 64 << 20
MAX_DEPTH = 32
MAX_NODES = 100_000
MAX_NDIM = 8
_DTYPES = {"f8": np.dtype("<f8"), "i8": np.dtype("<i8")}
_I64 = (-(1 << 63), (1 << 63) - 1)


class StateCodecError(ValueError):
    """Bytes that are not a state this codec wrote, or a value it cannot encode."""


# ------------------------------------------------------------------ encode
def encode(value) -> bytes:
    blobs: list[bytes] = []
    skeleton = json.dumps(_enc(value, blobs, 0), separators=(",", ":"), allow_nan=False).encode()
    data = b"".join(blobs)
    return _HEAD.pack(MAGIC, VERSION, 0, len(skeleton), len(data)) + skeleton + data


def _enc(v, blobs, depth):
    if depth > MAX_DEPTH:
        raise StateCodecError(f"encode: nesting deeper than {MAX_DEPTH}")
    if v is None or isinstance(v, (bool, str)):
        return v
    if isinstance(v, np.floating):
        if v.dtype != np.float64:
            raise StateCodecError(f"encode: NumPy scalar of dtype {v.dtype}, expected float64")
        return ["F", float(v).hex()]
    if isinstance(v, np.integer):
        if v.dtype != np.int64:
            raise StateCodecError(f"encode: NumPy scalar of dtype {v.dtype}, expected int64")
        return ["I", int(v)]
    if isinstance(v, float):
        return ["f", v.hex()]
    if isinstance(v, int):
        if not _I64[0] <= v <= _I64[1]:
            raise StateCodecError(f"encode: integer {v} outside 64 bits")
        return v
    if isinstance(v, (tuple, list)):
        return ["T" if isinstance(v, tuple) else "L", [_enc(x, blobs, depth + 1) for x in v]]
    if isinstance(v, dict):
        if not all(isinstance(k, str) for k in v):
            raise StateCodecError("encode: dict keys must be strings")
        return ["D", [[k, _enc(x, blobs, depth + 1)] for k, x in v.items()]]
    if isinstance(v, np.ndarray):
        code = next((c for c, d in _DTYPES.items() if v.dtype == d), None)
        if code is None:
            raise StateCodecError(f"encode: array of dtype {v.dtype}, expected float64 or int64")
        blobs.append(np.ascontiguousarray(v, dtype=_DTYPES[code]).tobytes())
        return ["A", code, list(v.shape)]
    raise StateCodecError(f"encode: cannot encode a {type(v).__name__}")


# ------------------------------------------------------------------ decode
def decode(data: bytes):
    """The value `encode` wrote into `data`; StateCodecError for anything else."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise StateCodecError(f"decode: expected bytes, got {type(data).__name__}")
    data = bytes(data)
    if len(data) > MAX_BYTES:
        raise StateCodecError(f"decode: {len(data)} bytes, more than the limit of {MAX_BYTES}")
    if len(data) < _HEAD.size:
        raise StateCodecError(f"decode: {len(data)} bytes, shorter than the {_HEAD.size}-byte header (truncated)")
    magic, version, reserved, n_skel, n_data = _HEAD.unpack_from(data)
    if magic != MAGIC:
        raise StateCodecError("decode: not a state written by dfa_model.io.statecodec (bad magic)")
    if version != VERSION or reserved != 0:
        raise StateCodecError(f"decode: format version {version}, this codec reads version {VERSION}")
    if _HEAD.size + n_skel + n_data != len(data):
        raise StateCodecError(f"decode: header announces {_HEAD.size + n_skel + n_data} bytes, got {len(data)} "
                              "(truncated or extended)")
    try:
        skeleton = json.loads(data[_HEAD.size:_HEAD.size + n_skel].decode("utf-8"), parse_float=_no_float,
                              parse_constant=_no_float, object_pairs_hook=_no_object)
    except StateCodecError:
        raise
    except (ValueError, RecursionError) as exc:     # UnicodeDecodeError and JSONDecodeError included
        raise StateCodecError(f"decode: skeleton is not valid: {exc}") from None
    dec = _Decoder(memoryview(data)[_HEAD.size + n_skel:])
    value = dec.node(skeleton, 0)
    if dec.pos != len(dec.blob):
        raise StateCodecError(f"decode: {len(dec.blob) - dec.pos} bytes of array data not described by the skeleton")
    return value


def _no_float(text):
    raise StateCodecError(f"decode: bare JSON number {text!r} (floats are tagged)")


def _no_object(pairs):
    raise StateCodecError("decode: JSON objects are not used by this format")


class _Decoder:
    def __init__(self, blob):
        self.blob, self.pos, self.nodes = blob, 0, 0

    def node(self, n, depth):
        self.nodes += 1
        if depth > MAX_DEPTH or self.nodes > MAX_NODES:
            raise StateCodecError(f"decode: deeper than {MAX_DEPTH} or more than {MAX_NODES} values")
        if n is None or isinstance(n, (bool, str)):
            return n
        if isinstance(n, int):
            return _int64(n)
        if not (isinstance(n, list) and n and isinstance(n[0], str)):
            raise StateCodecError(f"decode: malformed skeleton node {_short(n)}")
        tag, args = n[0], n[1:]
        if tag in ("f", "F") and len(args) == 1 and isinstance(args[0], str):
            try:
                x = float.fromhex(args[0])
            except (ValueError, OverflowError):
                raise StateCodecError(f"decode: bad float {_short(args[0])}") from None
            return x if tag == "f" else np.float64(x)
        if tag == "I" and len(args) == 1 and isinstance(args[0], int) and not isinstance(args[0], bool):
            return np.int64(_int64(args[0]))
        if tag in ("T", "L") and len(args) == 1 and isinstance(args[0], list):
            items = [self.node(x, depth + 1) for x in args[0]]
            return tuple(items) if tag == "T" else items
        if tag == "D" and len(args) == 1 and isinstance(args[0], list):
            out = {}
            for kv in args[0]:
                if not (isinstance(kv, list) and len(kv) == 2 and isinstance(kv[0], str)) or kv[0] in out:
                    raise StateCodecError(f"decode: bad or repeated dict entry {_short(kv)}")
                out[kv[0]] = self.node(kv[1], depth + 1)
            return out
        if tag == "A" and len(args) == 2:
            return self.array(*args)
        raise StateCodecError(f"decode: malformed skeleton node {_short(n)}")

    def array(self, code, shape):
        if code not in _DTYPES:
            raise StateCodecError(f"decode: array dtype {_short(code)}, expected one of {', '.join(_DTYPES)}")
        if not (isinstance(shape, list) and len(shape) <= MAX_NDIM
                and all(isinstance(d, int) and not isinstance(d, bool) and 0 <= d <= MAX_BYTES for d in shape)):
            raise StateCodecError(f"decode: bad array shape {_short(shape)}")
        nbytes = math.prod(shape) * 8
        if nbytes > len(self.blob) - self.pos:
            raise StateCodecError(f"decode: array of shape {tuple(shape)} needs {nbytes} bytes, "
                                  f"{len(self.blob) - self.pos} left (truncated)")
        a = np.frombuffer(self.blob[self.pos:self.pos + nbytes], dtype=_DTYPES[code]).reshape(shape)
        self.pos += nbytes
        return a.astype(a.dtype.newbyteorder("="), copy=True)   # owned, writable, native order


def _int64(n):
    if not _I64[0] <= n <= _I64[1]:
        raise StateCodecError("decode: integer outside 64 bits")
    return n


def _short(x):
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


# ------------------------------------------------------------------ structure
class Optional:
    """In a template: None here, or a value like `inner`."""

    def __init__(self, inner):
        self.inner = inner


def template(*refs):
    """A template that accepts the structure of every reference value: where the
    references differ only in that some hold None, the template takes either."""
    t = refs[0]
    for r in refs[1:]:
        t = _merge(t, r)
    return t


def _merge(a, b):
    if isinstance(a, Optional) or isinstance(b, Optional):
        return Optional(_merge(a.inner if isinstance(a, Optional) else a,
                               b.inner if isinstance(b, Optional) else b))
    if a is None or b is None:
        return a if b is None and a is None else Optional(b if a is None else a)
    if isinstance(a, (tuple, list)) and type(a) is type(b) and len(a) == len(b):
        return type(a)(_merge(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys():
        return {k: _merge(a[k], b[k]) for k in a}
    if _kind(a) != _kind(b):
        raise ValueError(f"template: references differ ({_kind(a)} vs {_kind(b)})")
    return a


def _kind(v):
    if v is None:
        return "None"
    if isinstance(v, (bool, np.bool_)):
        return "bool"
    if isinstance(v, (int, np.integer)):
        return "int"
    if isinstance(v, (float, np.floating)):
        return "float"
    if isinstance(v, np.ndarray):
        return f"array {v.dtype} {v.shape}"
    return type(v).__name__


def check_like(value, tmpl, path="state", finite=True) -> None:
    """Raise ValueError naming the first place where `value` differs from the template
    in nesting, types, array dtypes or shapes; with `finite`, also where a float or a
    float array holds NaN or infinity."""
    if isinstance(tmpl, Optional):
        if value is not None:
            check_like(value, tmpl.inner, path, finite)
        return
    kind = _kind(tmpl)
    if isinstance(tmpl, (tuple, list)):
        if type(value) is not type(tmpl) or len(value) != len(tmpl):
            raise ValueError(f"{path}: expected a {type(tmpl).__name__} of {len(tmpl)}, got {_describe(value)}")
        for i, (v, t) in enumerate(zip(value, tmpl)):
            check_like(v, t, f"{path}[{i}]", finite)
        return
    if isinstance(tmpl, dict):
        if not isinstance(value, dict) or value.keys() != tmpl.keys():
            raise ValueError(f"{path}: expected a dict with keys {sorted(tmpl)}, got {_describe(value)}")
        for k in tmpl:
            check_like(value[k], tmpl[k], f"{path}[{k!r}]", finite)
        return
    if _kind(value) != kind:
        raise ValueError(f"{path}: expected {kind}, got {_describe(value)}")
    if finite and kind == "float" and not math.isfinite(value):
        raise ValueError(f"{path}: expected a finite number, got {value!r}")
    if finite and isinstance(value, np.ndarray) and value.dtype.kind == "f" and not np.all(np.isfinite(value)):
        raise ValueError(f"{path}: array holds NaN or infinity")


def _describe(v):
    if isinstance(v, (tuple, list)):
        return f"a {type(v).__name__} of {len(v)}"
    if isinstance(v, dict):
        return f"a dict with keys {sorted(map(str, v))[:8]}"
    return _kind(v)
