"""Protocol files: one language for a drive, read and written by every part of the toolkit
(README, 'Protocol file'; the contract is in ../shared/notes/architecture.md).

    [[stage]]
    name = "reset"            # optional label ("reset" and "hold" are the metrics' windows)
    waveform = "bipolar"      # dc | bipolar | unipolar | sampled
    voltage = 6000.0          # V, amplitude
    frequency = 30.0          # Hz (bipolar, unipolar)
    duty = 1.0                # bipolar: share of each half period at full voltage (1: no dead time);
                              # unipolar: share of each period on
    slew_rate = 4e7           # V/s: switches are ramps centred on their instants (default: ideal)
    phase = 0.25              # share of a period the drive starts at, or "balanced"
    positive_share = 0.5      # bipolar: share of the period in the positive half
    duration = 3.0            # s
    [[stage]]
    waveform = "sampled"      # a user signal, linear between samples ("hold": zero-order hold)
    file = "signal.csv"       # columns time,voltage (relative to this file), or inline:
    # times = [0.0, 1.0], values = [0.0, 6000.0]
    interpolation = "linear"
    duration = 5.0            # optional for sampled stages: default the last sample's time
    [load]                    # optional: the load opposing zipping
    force = 5.0               # N, or file = "force.csv" (time,force) / times, values
    k_load = 0.0              # N/m, a load spring

Every key is checked: an unknown key, a key that takes no part in the stage's waveform
(a frequency on a DC stage), a value out of range or a sampled file that is not there is
a WaveformError of one line naming the file, the stage and the key.
"""
from __future__ import annotations

import csv
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

from .fileio import toml_float, write_text_atomic
from ..limits import MAX_DURATION
from ..waveforms import (DC, Bipolar, Load, Protocol, Sampled, Stage, Unipolar, WaveformError, balanced_phase,
                         register_file_format)

WAVEFORMS = ("dc", "bipolar", "unipolar", "sampled")
COMMON = ("name", "waveform", "duration")
KEYS = {
    "dc": COMMON + ("voltage",),
    "bipolar": COMMON + ("voltage", "frequency", "duty", "slew_rate", "phase", "positive_share"),
    "unipolar": COMMON + ("voltage", "frequency", "duty", "slew_rate", "phase"),
    "sampled": COMMON + ("file", "times", "values", "interpolation"),
}
LOAD_KEYS = ("force", "k_load", "file", "times", "values", "interpolation")
INLINE_MAX = 200      # save(): sampled signals longer than this go to a CSV beside the file


class _Where:
    """Names the place of an error: 'drive.toml: stage 2 (hold): '."""

    def __init__(self, source):
        self.source = source

    def __call__(self, part="", key=None):
        where = self.source + (f": {part}" if part else "") + (f": {key}" if key else "")
        return where

    def error(self, part, key, message):
        return WaveformError(f"{self(part, key)}: {message}")


def _number(where, part, key, value, lo=None, lo_open=False, hi=None, hi_open=False, unit=""):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise where.error(part, key, f"got {value!r}, expected a number{' (' + unit + ')' if unit else ''}")
    v = float(value)
    bad = not math.isfinite(v) and not (v == math.inf and hi is None and key == "slew_rate")
    bad = bad or (lo is not None and (v < lo or (lo_open and v == lo))) or \
        (hi is not None and (v > hi or (hi_open and v == hi)))
    if bad:
        rng = []
        if lo is not None:
            rng.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            rng.append(f"{'<' if hi_open else '<='} {hi:g}")
        want = f"{' and '.join(rng)} {unit}" if rng else f"({unit})" if unit else ""
        raise where.error(part, key, f"got {value!r}, expected a finite number {want}".rstrip())
    return v


def _text(where, part, key, value, allowed=None):
    if not isinstance(value, str):
        raise where.error(part, key, f"got {value!r}, expected a string")
    if allowed is not None and value not in allowed:
        raise where.error(part, key, f"got {value!r}, expected one of {', '.join(repr(a) for a in allowed)}")
    return value


def _samples(where, part, table, folder, column):
    """(times, values) of a sampled signal: `file` (CSV with columns time,<column>) or
    inline `times` and `values`."""
    has_file = "file" in table
    has_inline = "times" in table or "values" in table
    if has_file and has_inline:
        raise where.error(part, "file", "give the samples either as a file or as times and values, not both")
    if has_file:
        name = _text(where, part, "file", table["file"])
        path = (Path(folder) / name) if folder is not None else Path(name)
        return read_signal_csv(path, column, where(part, "file"))
    if not has_inline:
        raise where.error(part, "file", f"a sampled signal needs file = \"signal.csv\" (columns time,{column}) or "
                                        "times and values")
    for key in ("times", "values"):
        if key not in table:
            raise where.error(part, key, "required with inline samples (times and values, equal lengths)")
        if not isinstance(table[key], list) or not table[key]:
            raise where.error(part, key, f"got {table[key]!r}, expected a non-empty list of numbers")
    t = [_number(where, part, f"times[{i}]", v) for i, v in enumerate(table["times"])]
    v = [_number(where, part, f"values[{i}]", x) for i, x in enumerate(table["values"])]
    if len(t) != len(v):
        raise where.error(part, "values", f"{len(v)} values for {len(t)} times, expected one value per time")
    return np.array(t), np.array(v)


def read_signal_csv(path, column="voltage", where=None):
    """(times, values) from a CSV with a header row `time,<column>` (`#` comment lines
    before it allowed, further columns ignored), SI units."""
    path = Path(path)
    label = where or str(path)
    if not path.is_file():
        raise WaveformError(f"{label}: {path} not found")
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise WaveformError(f"{label}: cannot read {path} ({exc})") from None
    if not rows:
        raise WaveformError(f"{label}: {path.name} is empty (expected a header row time,{column})")
    head = [h.strip() for h in rows[0]]
    if "time" not in head or column not in head:
        raise WaveformError(f"{label}: {path.name}: header {','.join(head)!r}, expected columns time,{column}")
    it, iv = head.index("time"), head.index(column)
    t, v = [], []
    for n, r in enumerate(rows[1:], start=2):
        try:
            t.append(float(r[it]))
            v.append(float(r[iv]))
        except (ValueError, IndexError):
            raise WaveformError(f"{label}: {path.name}, data row {n - 1}: expected numbers in columns time,{column}, "
                                f"got {r!r}") from None
    if not t:
        raise WaveformError(f"{label}: {path.name} has a header but no samples")
    return np.array(t), np.array(v)


def _stage(where, i, table, folder) -> Stage:
    part = f"stage {i + 1}"
    if not isinstance(table, dict):
        raise where.error(part, None, "expected a table ([[stage]])")
    if "name" in table:
        part += f" ({_text(where, part, 'name', table['name'])})"
    if "waveform" not in table:
        raise where.error(part, "waveform", f"required, one of {', '.join(WAVEFORMS)}")
    kind = _text(where, part, "waveform", table["waveform"], WAVEFORMS)
    for key in table:
        if key not in KEYS[kind]:
            known = {k for keys in KEYS.values() for k in keys}
            why = f"does not apply to a {kind} stage" if key in known else "unknown key"
            raise where.error(part, key, f"{why} (a {kind} stage takes {', '.join(KEYS[kind])})")
    label = table.get("name", "")
    duration = table.get("duration")
    if duration is not None:
        duration = _number(where, part, "duration", duration, 0.0, lo_open=True, hi=MAX_DURATION, unit="s")
    elif kind != "sampled":
        raise where.error(part, "duration", "required (s)")
    try:
        if kind == "sampled":
            t, v = _samples(where, part, table, folder, "voltage")
            interp = _text(where, part, "interpolation", table.get("interpolation", "linear"), ("linear", "hold"))
            wf = Sampled(t, v, hold=interp == "hold")
            if duration is None:
                if not 0 < t[-1] <= MAX_DURATION:
                    raise where.error(part, "duration", f"required: the samples end at {t[-1]:g} s (expected a "
                                                        f"duration > 0 and <= {MAX_DURATION:g} s)")
                duration = float(t[-1])
            return Stage(wf, duration, label)
        if "voltage" not in table:
            raise where.error(part, "voltage", "required (V, amplitude)")
        V = _number(where, part, "voltage", table["voltage"], unit="V")
        if kind == "dc":
            return Stage(DC(V), duration, label)
        if "frequency" not in table:
            raise where.error(part, "frequency", "required (Hz)")
        kw = {"frequency": _number(where, part, "frequency", table["frequency"], 0.0, lo_open=True, unit="Hz"),
              "duty": _number(where, part, "duty", table.get("duty", 1.0 if kind == "bipolar" else 0.5), 0.0,
                              lo_open=True, hi=1.0)}
        if "slew_rate" in table:
            kw["slew_rate"] = _number(where, part, "slew_rate", table["slew_rate"], 0.0, lo_open=True, unit="V/s")
        if "phase" in table:
            ph = table["phase"]
            kw["phase"] = ph if ph == "balanced" else _number(where, part, "phase", ph, 0.0, hi=1.0, hi_open=True)
        if kind == "bipolar" and "positive_share" in table:
            kw["positive_share"] = _number(where, part, "positive_share", table["positive_share"], 0.0, lo_open=True,
                                           hi=1.0, hi_open=True)
        return Stage((Bipolar if kind == "bipolar" else Unipolar)(V, **kw), duration, label)
    except WaveformError as exc:
        msg = str(exc)
        raise WaveformError(msg if msg.startswith(where.source) else f"{where(part)}: {msg}") from None


def _load(where, table, folder) -> Load:
    part = "load"
    if not isinstance(table, dict):
        raise where.error(part, None, "expected a table ([load])")
    for key in table:
        if key not in LOAD_KEYS:
            raise where.error(part, key, f"unknown key (the load takes {', '.join(LOAD_KEYS)})")
    k_load = _number(where, part, "k_load", table.get("k_load", 0.0), 0.0, unit="N/m")
    sampled = any(k in table for k in ("file", "times", "values"))
    if sampled and "force" in table:
        raise where.error(part, "force", "give a constant force or a sampled one (file, or times and values), "
                                         "not both")
    try:
        if sampled:
            t, v = _samples(where, part, table, folder, "force")
            interp = _text(where, part, "interpolation", table.get("interpolation", "linear"), ("linear", "hold"))
            return Load(Sampled(t, v, hold=interp == "hold", name="force"), k_load)
        if "interpolation" in table:
            raise where.error(part, "interpolation", "applies to a sampled force only")
        return Load(_number(where, part, "force", table.get("force", 0.0), unit="N"), k_load)
    except WaveformError as exc:
        msg = str(exc)
        raise WaveformError(msg if msg.startswith(where.source) else f"{where(part)}: {msg}") from None


def from_toml(text: str, folder=None, source="protocol") -> Protocol:
    """A Protocol from protocol-file text; sampled files are looked up in `folder`."""
    where = _Where(source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise WaveformError(f"{source}: not valid TOML ({exc})") from None
    for key in data:
        if key not in ("stage", "load"):
            raise where.error("", key, "unknown key (a protocol file holds [[stage]] tables and an optional [load])")
    stages = data.get("stage")
    if not isinstance(stages, list) or not stages:
        raise where.error("", "stage", "no stages: a protocol file needs at least one [[stage]] table")
    stages = [_stage(where, i, s, folder) for i, s in enumerate(stages)]
    try:
        proto = Protocol(stages)
    except WaveformError as exc:        # the whole protocol's checks (its total duration)
        raise WaveformError(f"{source}: {exc}") from None
    if "load" in data:
        proto.load = _load(where, data["load"], folder)
    return proto


def load(path) -> Protocol:
    """Read a protocol file (sampled signals' files relative to its folder)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise WaveformError(f"{path}: protocol file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise WaveformError(f"{path}: cannot read the protocol file ({exc})") from None
    return from_toml(text, path.parent, str(path))


# ------------------------------------------------------------------------ writing
def _samples_toml(lines, t, v, column, csv_name, write_csv):
    if csv_name is not None:
        write_csv(csv_name, t, v, column)
        lines.append(f'file = "{csv_name}"')
    else:
        lines.append("times = [" + ", ".join(toml_float(x) for x in t) + "]")
        lines.append("values = [" + ", ".join(toml_float(x) for x in v) + "]")


def _stage_toml(st: Stage, i: int, csv_name=None, write_csv=None) -> list:
    wf = st.waveform
    lines = ["[[stage]]"]
    if st.label:
        lines.append(f'name = "{st.label}"')
    if isinstance(wf, DC):
        lines += ['waveform = "dc"', f"voltage = {toml_float(wf.V)}"]
    elif isinstance(wf, (Bipolar, Unipolar)):
        kind = "bipolar" if isinstance(wf, Bipolar) else "unipolar"
        lines += [f'waveform = "{kind}"', f"voltage = {toml_float(wf.V)}", f"frequency = {toml_float(wf.frequency)}",
                  f"duty = {toml_float(wf.duty)}"]
        if wf.slew_rate is not None:
            lines.append(f"slew_rate = {toml_float(wf.slew_rate)}")
        if wf.phase:
            note = ""
            try:
                if abs(balanced_phase(wf) - wf.phase) <= 1e-12:
                    note = "   # the charge-balanced start"
            except WaveformError:
                pass
            lines.append(f"phase = {toml_float(wf.phase)}{note}")
        if kind == "bipolar" and wf.positive_share != 0.5:
            lines.append(f"positive_share = {toml_float(wf.positive_share)}")
    elif isinstance(wf, Sampled):
        if wf.name != "voltage":
            raise WaveformError(f"stage {i + 1}: a sampled {wf.name} signal is not a voltage")
        lines.append('waveform = "sampled"')
        _samples_toml(lines, wf.times, wf.values, "voltage", csv_name, write_csv)
        lines.append(f'interpolation = "{"hold" if wf.hold else "linear"}"')
    else:
        raise WaveformError(f"stage {i + 1}{' (' + st.label + ')' if st.label else ''}: a {type(wf).__name__} "
                            "waveform has no protocol-file form (sample it: waveforms.from_function)")
    lines.append(f"duration = {toml_float(st.duration)}")
    return lines


def _load_toml(load: Load, csv_name=None, write_csv=None) -> list:
    lines = ["[load]"]
    F = load.F
    if isinstance(F, Sampled):
        _samples_toml(lines, F.times, F.values, "force", csv_name, write_csv)
        lines.append(f'interpolation = "{"hold" if F.hold else "linear"}"')
    elif callable(F):
        raise WaveformError("load: a force given as a Python callable has no protocol-file form (sample it: "
                            "waveforms.from_function(fn, duration, dt, name='force'))")
    else:
        lines.append(f"force = {toml_float(F)}")
    if load.k_load:
        lines.append(f"k_load = {toml_float(load.k_load)}")
    return lines


def to_toml(protocol: Protocol, header=None, _files=None) -> str:
    """The protocol-file text of `protocol` (and its `load`, if set): every number exactly
    (read back, it is the same drive to the last bit); sampled signals inline.
    `header`: comment lines to start with (provenance)."""
    lines = [f"# {h}" if h else "#" for h in (header.splitlines() if isinstance(header, str) else header or [])]
    lines.append("# dfa protocol file: stages in order, SI units (docs/reference/protocol-file.md)")
    for i, st in enumerate(protocol.stages):
        name = _files(i, st) if _files else None
        lines += [""] + _stage_toml(st, i, name, _files and _files.write)
    ld = getattr(protocol, "load", None)
    if ld is not None:
        name = _files("load", ld) if _files else None
        lines += [""] + _load_toml(ld, name, _files and _files.write)
    return "\n".join(lines) + "\n"


class _SideFiles:
    """save(): names and writes the CSVs of sampled signals longer than INLINE_MAX."""

    def __init__(self, path: Path):
        self.path = path
        self.written = []

    def __call__(self, i, obj):
        sig = obj.F if isinstance(obj, Load) else obj.waveform
        if not isinstance(sig, Sampled) or sig.times.size <= INLINE_MAX:
            return None
        return f"{self.path.stem}.{'load' if i == 'load' else f'stage{i + 1}'}.csv"

    def write(self, name, t, v, column):
        text = f"time,{column}\n" + "".join(f"{toml_float(a)},{toml_float(b)}\n" for a, b in zip(t, v))
        write_text_atomic(self.path.parent / name, text)
        self.written.append(self.path.parent / name)


def save(protocol: Protocol, path, header=None) -> list:
    """Write `protocol` to a protocol file; sampled signals of more than INLINE_MAX samples
    go to CSV files beside it (named after it). Returns the paths written."""
    path = Path(path)
    side = _SideFiles(path)
    text = to_toml(protocol, header, side)
    write_text_atomic(path, text)
    return [path] + side.written


register_file_format(sys.modules[__name__])
