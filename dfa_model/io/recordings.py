"""Measured recordings: reading, validating and interpreting a dataset folder.

A dataset (architecture notes, *contract*) is a folder with `actuator.toml` (the parameter
file: what is known about the device) and one CSV per test, header
`time,voltage,force,stroke` (optional `current`; further columns, such as those of
`dfa simulate --out`, are ignored and listed in the notes), SI units, `#` comment lines
allowed before the header.

Checks (each failure is one line naming the file and, where there is one, the row as
its line number in the file):
- the folder exists, holds `actuator.toml` and at least one recording (dataset.toml below);
- the header has the four columns; every value is a finite number;
- time starts within one sample of 0 and strictly increases (a repeated or backward time
  is an error: which sample is right cannot be told);
- at least MIN_SAMPLES rows;
- units: a stroke above the actuator's full stroke x_e that would fit as millimetres, a
  voltage of at most MAX_KV_LOOKING V (kilovolts), a force above MAX_FORCE N;
- the voltage agrees with itself: every stretch between switches sits on one of the
  levels +A, 0, -A of the recording's amplitude A (within LEVEL_TOL of A), and the hold
  (the last stretch) is not 0 V.

Lab exports: a UTF-8 byte-order mark is skipped; CRLF (or CR) line ends read as line ends;
the delimiter is a comma, else the header row's semicolon or tab; a row of units under the
header (UNITS) converts each column to SI (noted). A field longer than csv's limit
(csv.field_size_limit(), 131072 characters) is one line naming the row.

dataset.toml (optional; without it, the contract above exactly: *.csv only, our column
names, SI). Read by read_layout into a Layout:

    [columns]      # our name = the file's column (or channel) name, compared case-blind
    time = "Time (s)"
    voltage = "HV monitor"
    [units]        # per our column, a unit of UNITS: converted to SI (noted)
    voltage = "kV"
    stroke = "mm"
    [files]        # optional
    include = ["*.csv", "*.h5"]   # default *.csv, *.h5, *.hdf5, *.tdms (any other file: CSV text)
    max_bytes = 2_000_000_000     # default MAX_BYTES
    [hdf5]         # optional: where the channels are (default the root), a sample time
    group = "/run1"
    dt = 0.001     # s, for files without a time channel (it wins over their dt attribute)
    [tdms]         # optional: the group of the channels (default the file's only group)
    group = "Analog"

An unknown table or key, a unit not in UNITS, a named column missing from a file, a units
row disagreeing with [units]: one line naming the key, what was found and what is allowed.
The mapping and units apply to every format. Two files with one stem (a.csv, a.h5) are
refused: the report names recordings by stem.

Binary formats (optional extras, `pip install "dfa-toolkit[hdf5]"` / `[tdms]`; a file of
one without its library is one line naming the extra):
- HDF5 (.h5, .hdf5; h5py): one 1-D numeric dataset per channel in [hdf5] group;
- NI TDMS (.tdms; npTDMS): the channels of one group.
Either may lack a time channel: the sample time then gives it, t = offset + i dt (noted):
HDF5 [hdf5] dt, else a `dt` or `wf_increment` attribute of the group or a channel
(`wf_start_offset` the offset, default 0); TDMS the channels' `wf_increment` and
`wf_start_offset` properties (which must agree). A time channel, when there is one, wins.
Errors in them say "sample i" (counted from 0) where CSV says "row" (the line).

Size: a file above MAX_BYTES (1 GiB; dataset.toml [files] max_bytes sets another limit)
is refused before any of it is read, with its size and the limit. Every reading failure
(an unreadable, damaged or foreign file) is one RecordingError line, which `dfa diagnose`
prints as `dfa: error: ...` (exit 2).

Documented handling (listed in Recording.notes, which the diagnosis report states):
- gaps: a time step above GAP_FACTOR x the median step is kept as it is (the model runs
  through it; the fit uses the samples there are);
- a force whose moving mean (FORCE_WINDOW samples: a load cell's noise is not a load)
  varies by more than FORCE_TOL of its mean over the recording is used as a sampled load
  (that moving mean), else its mean as a constant load;
- a stroke offset (sensor zero) is not corrected here: it is a nuisance parameter of the
  fit, read where the model rests on its stop, or fitted when the recording has no rest
  stretch before the drive (noted).

Interpretation: the voltage becomes a Protocol of piecewise-constant levels switched at
the measured threshold crossings (interpolated between samples; a regular square-wave
reset's switches are put on their best-fit regular grid, which times them to a small
fraction of a sample), with the stages 'reset' (up to the last
switch before the hold) and 'hold' (the final constant level), the paper's routine
(Sec. 4.2). `Recording.protocol` and `Recording.load` run on the model as they are.
"""
from __future__ import annotations

import csv
import importlib
import math
import os
import struct
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .parameters import Parameters, ParameterError
from .parameters import load as load_parameters
from ..waveforms import DC, Load, Protocol, Sampled, Stage

REQUIRED = ("time", "voltage", "force", "stroke")
OPTIONAL = ("current",)
MIN_SAMPLES = 10
GAP_FACTOR = 5.0          # a step this many times the median step is a gap
LEVEL_TOL = 0.15          # a voltage stretch within this share of the amplitude of +A, 0 or -A
FORCE_TOL = 0.05          # a force varying more than this share of its mean is a sampled load
CONDITION_V = 0.01        # hold voltages within this share of each other are one condition
CONDITION_F = 0.02        # mean forces likewise (at least 10 mN apart to differ)
FORCE_WINDOW = 51         # samples of the moving mean that judges (and gives) a varying force
MAX_KV_LOOKING = 50.0     # a recording whose |voltage| never exceeds this (V) is in kV
MAX_FORCE = 1000.0        # N: above this a force column is not a DFA load in newtons
MAX_STROKE = 0.1          # m: no DFA strokes 10 cm (without the actuator: the bound for mm)
MAX_BYTES = 2 ** 30       # 1 GiB: a larger file is refused unread (a day at 1 kHz is ~0.5 GB of CSV);
                          # dataset.toml [files] max_bytes sets another limit
CONFIG = "dataset.toml"   # the optional description of a dataset's files (Layout)
# dataset.toml: its tables and their keys
TABLES = {"columns": REQUIRED + OPTIONAL, "units": REQUIRED + OPTIONAL, "files": ("include", "max_bytes"),
          "hdf5": ("group", "dt"), "tdms": ("group",)}
BINARY = (".h5", ".hdf5", ".tdms")
DEFAULT_INCLUDE = ("*.csv", "*.h5", "*.hdf5", "*.tdms")   # with a dataset.toml; without one, *.csv
EXTRAS = {"hdf5": ("h5py", "HDF5"), "tdms": ("nptdms", "TDMS")}   # extra -> (module, format)


class RecordingError(ValueError):
    """A recording or dataset that cannot be used as it is (one line: file, row, what)."""


@dataclass
class Recording:
    """One measured test. Arrays in SI units; `line` maps sample i to its line in the file
    (in a binary file, HDF5 or TDMS: i itself)."""

    name: str
    path: Path
    t: np.ndarray
    voltage: np.ndarray
    force: np.ndarray
    stroke: np.ndarray
    current: np.ndarray | None
    line: np.ndarray
    notes: list = field(default_factory=list)
    protocol: Protocol | None = None
    load: Load | None = None
    amplitude: float = 0.0
    hold_voltage: float = 0.0
    reset_end: float = 0.0
    group: tuple | None = None      # its condition, set by read_dataset (group_conditions)
    # the drive read off the voltage: its switch instants (s) and the level of each stretch
    # (the stretch before the first switch, then after each one): retimed() rebuilds it
    switches: np.ndarray | None = None
    levels: tuple = ()
    gridded: bool = False           # the reset's switches were put on one regular grid (_regular_switches)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def dt(self) -> float:
        """Median sample step (s)."""
        return float(np.median(np.diff(self.t)))

    @property
    def force_mean(self) -> float:
        return float(np.mean(self.force))

    def condition(self) -> tuple:
        """(hold voltage magnitude, mean force) of its condition: recordings of one
        condition (repetitions) share it. In a dataset, the group's (group_conditions);
        alone, its own, rounded to the nearest 10 V and 10 mN. The magnitude: the model
        is odd in V (a drive and its mirror give one stroke), and a polarity inversion
        ends on either polarity by the phase its recording stops at."""
        if self.group is not None:
            return self.group
        return (round(abs(self.hold_voltage), -1), round(self.force_mean, 2))


@dataclass
class Dataset:
    folder: Path
    params: Parameters
    recordings: list

    def conditions(self) -> dict:
        """condition -> the recordings of it (repetitions), in file order."""
        out = {}
        for r in self.recordings:
            out.setdefault(r.condition(), []).append(r)
        return out


# ------------------------------------------------------------------------ reading
def _where(path, line=None) -> str:
    # a binary recording has no rows: its samples are counted from 0, as its arrays index them
    word = "sample" if path.suffix.lower() in BINARY else "row"
    return f"{path.name}, {word} {line}" if line is not None else path.name


def _show(text, n=60) -> str:
    """A file's text in a message: cut short (a message stays one line of sense)."""
    text = str(text).strip()
    return text if len(text) <= n else text[:n] + "..."


def _size(n) -> str:
    for unit, f in (("GiB", 2 ** 30), ("MiB", 2 ** 20), ("KiB", 2 ** 10)):
        if n >= f:
            return f"{n / f:.3g} {unit}"
    return f"{n} bytes"


# a units row under the header: the units each column may be given in, with their factor to SI
UNITS = {"time": {"s": 1.0, "ms": 1e-3},
         "voltage": {"v": 1.0, "kv": 1e3},
         "force": {"n": 1.0, "mn": 1e-3},
         "stroke": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6},
         "current": {"a": 1.0, "ma": 1e-3, "ua": 1e-6, "µa": 1e-6, "na": 1e-9}}


# ------------------------------------------------------------------------ dataset.toml
@dataclass
class Layout:
    """How a dataset's files name and scale the channels: dataset.toml (module docstring).
    The defaults are the contract (no dataset.toml): our column names, SI, *.csv."""

    columns: dict = field(default_factory=dict)   # our column -> the file's column / channel name
    units: dict = field(default_factory=dict)     # our column -> (unit as written, factor to SI)
    include: tuple = ("*.csv",)
    max_bytes: int | None = None                  # None: MAX_BYTES (read when a file is checked)
    hdf5_group: str = "/"
    hdf5_dt: float | None = None
    tdms_group: str | None = None
    source: str | None = None                     # "dataset.toml" when read from one


def _keys(table, name, allowed) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise RecordingError(f"{CONFIG}: unknown key [{name}] {unknown[0]}; allowed: {', '.join(allowed)}")


def _text(name, key, v) -> str:
    if not isinstance(v, str) or not v.strip():
        raise RecordingError(f"{CONFIG}: [{name}] {key} = {v!r}: text expected")
    return v


def _positive(name, key, v, integer=False) -> float:
    ok = isinstance(v, int) if integer else isinstance(v, (int, float)) and math.isfinite(v)
    if isinstance(v, bool) or not ok or v <= 0:
        raise RecordingError(f"{CONFIG}: [{name}] {key} = {v!r}: a positive "
                             f"{'whole number of bytes' if integer else 'number (s)'} expected")
    return v


def read_layout(folder) -> Layout:
    """The folder's dataset.toml as a Layout; no dataset.toml: the defaults (the contract)."""
    path = Path(folder) / CONFIG
    if not path.is_file():
        return Layout()
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{CONFIG}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise RecordingError(f"{CONFIG}: not valid TOML: {exc}") from None
    for name, table in data.items():
        if name not in TABLES:
            what = f"table [{name}]" if isinstance(table, dict) else f"key {name}"
            raise RecordingError(f"{CONFIG}: unknown {what}; allowed tables: "
                                 f"{', '.join('[' + t + ']' for t in TABLES)}")
        if not isinstance(table, dict):
            raise RecordingError(f"{CONFIG}: {name} = {_show(repr(table))}: a table [{name}] expected")
        _keys(table, name, TABLES[name])
    out = Layout(include=DEFAULT_INCLUDE, source=CONFIG)
    for c, v in data.get("columns", {}).items():
        out.columns[c] = _text("columns", c, v)
    named = {}
    for c, v in out.columns.items():
        if v.strip().lower() in named:
            raise RecordingError(f"{CONFIG}: [columns] {named[v.strip().lower()]} and {c} both name {v!r}; expected "
                                 f"one column of the file per name")
        named[v.strip().lower()] = c
    for c, v in data.get("units", {}).items():
        u = _text("units", c, v).strip().lower()
        if u not in UNITS[c]:
            raise RecordingError(f"{CONFIG}: [units] {c} = {v!r}: not a unit of {c}; allowed: {', '.join(UNITS[c])}")
        out.units[c] = (v.strip(), UNITS[c][u])
    files = data.get("files", {})
    if "include" in files:
        inc = files["include"]
        if not isinstance(inc, list) or not inc:
            raise RecordingError(f"{CONFIG}: [files] include = {_show(repr(inc))}: a list of patterns expected "
                                 f"(e.g. [\"*.csv\", \"*.h5\"])")
        for g in inc:
            # patterns within the folder: Path.glob refuses absolute ones, '..' leaves the dataset
            if not isinstance(g, str) or not g.strip() or g.startswith(("/", "\\")) or ".." in g:
                raise RecordingError(f"{CONFIG}: [files] include has {g!r}: a file pattern within the folder "
                                     f"expected (e.g. \"*.csv\")")
        out.include = tuple(inc)
    if "max_bytes" in files:
        out.max_bytes = _positive("files", "max_bytes", files["max_bytes"], integer=True)
    h5 = data.get("hdf5", {})
    if "group" in h5:
        out.hdf5_group = _text("hdf5", "group", h5["group"])
    if "dt" in h5:
        out.hdf5_dt = float(_positive("hdf5", "dt", h5["dt"]))
    if "group" in data.get("tdms", {}):
        out.tdms_group = _text("tdms", "group", data["tdms"]["group"])
    return out


# ------------------------------------------------------------------------ common to all formats
def _check_size(path, layout) -> None:
    """Refuse a file above the size limit before reading any of it."""
    limit = MAX_BYTES if layout.max_bytes is None else layout.max_bytes
    try:
        n = os.stat(path).st_size
    except OSError as exc:
        raise RecordingError(f"{path.name}: cannot read: {exc.strerror or exc}") from None
    if n > limit:
        src = (f"{CONFIG} [files] max_bytes" if layout.max_bytes is not None else
               f"MAX_BYTES; {CONFIG} [files] max_bytes sets it")
        raise RecordingError(f"{path.name}: {_size(n)} ({n} bytes), above the limit of {_size(limit)} ({limit} "
                             f"bytes, {src}): refused unread")


def _select(path, names, layout, where, found, time_optional=False) -> dict:
    """our column -> index in `names` (the file's columns or channels, compared stripped and
    case-blind): dataset.toml [columns] names it, else our own name does. time_optional: a
    binary file's time channel may be absent (even if named: one dataset.toml serves CSV
    files with a time column and binary ones with a sample time)."""
    norm = [n.strip().lower() for n in names]
    cols = {}
    for c in REQUIRED + OPTIONAL:
        want = layout.columns.get(c, c).strip().lower()
        if want in norm:
            cols[c] = norm.index(want)
        elif c in layout.columns and not (c == "time" and time_optional):
            raise RecordingError(f"{where}: [columns] {c} = {layout.columns[c]!r} ({CONFIG}) is not in {found}; "
                                 f"expected one of its columns")
    missing = [c for c in REQUIRED if c not in cols and not (c == "time" and time_optional)]
    if missing:
        raise RecordingError(f"{where}: missing column(s) {', '.join(missing)} in {found} (expected "
                             f"{','.join(REQUIRED)}[,current]" + (f", or named in {CONFIG} [columns])"
                                                                 if layout.source else ")"))
    dup = sorted({c for c, j in cols.items() if norm.count(norm[j]) > 1}, key=(REQUIRED + OPTIONAL).index)
    if dup:
        raise RecordingError(f"{where}: column(s) {', '.join(names[cols[c]].strip() for c in dup)} appear more "
                             f"than once; expected each once")
    return cols


def _mapping_note(named) -> list:
    """named: our column -> the file's name for it."""
    renamed = [f"{c} = '{n.strip()}'" for c, n in named.items() if n.strip().lower() != c]
    return [f"columns named in {CONFIG}: {', '.join(renamed)}"] if renamed else []


def _units_note(scale, source) -> list:
    conv = [f"{c} x {f:g}" for c, f in scale.items() if f != 1.0]
    return [f"{source}: {', '.join(conv)} to SI"] if conv else []


def _is_units_row(row, cols) -> bool:
    """A row whose used columns are all text (not numbers): read as the units row."""
    def num(x):
        try:
            float(x)
            return True
        except ValueError:
            return False
    return all(j < len(row) and row[j].strip() and not num(row[j].strip()) for j in cols.values())


def _units(path, line, row, cols, layout) -> dict:
    """The units row's factors to SI; a dataset.toml [units] entry must agree with it."""
    out = {}
    for c, j in cols.items():
        u = row[j].strip().strip("[]()").lower()
        if u not in UNITS[c]:
            raise RecordingError(f"{_where(path, line)}: {c} in unit '{_show(row[j], 20)}' (units row); allowed: "
                                 f"{', '.join(UNITS[c])}")
        if c in layout.units and layout.units[c][1] != UNITS[c][u]:
            raise RecordingError(f"{_where(path, line)}: {c} in '{row[j].strip()}' (units row) but in "
                                 f"'{layout.units[c][0]}' ({CONFIG} [units] {c}): they must agree")
        out[c] = UNITS[c][u]
    return out


def _rows(path, lines, first, delim):
    """(line number, row) of CSV text lines from line `first`; what csv cannot read (a field
    above its limit, csv.field_size_limit()) is one line naming the row."""
    reader = csv.reader(lines, delimiter=delim)
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            line = first + reader.line_num - 1
            what = (f"a field longer than {csv.field_size_limit()} characters (no value of a recording is)"
                    if "field larger than field limit" in str(exc) else f"not readable as CSV ({exc})")
            raise RecordingError(f"{_where(path, line)}: {what}; expected one number per field") from None
        yield first + reader.line_num - 1, row


def read_csv(path, x_e: float | None = None, layout: Layout | None = None) -> Recording:
    """Read and check one recording (module docstring). x_e: the actuator's full stroke
    (m), which bounds the stroke column (read_dataset gives it); without it, MAX_STROKE.
    layout: the dataset's dataset.toml (read_layout); without it, the contract's names in SI."""
    path = Path(path)
    layout = layout or Layout()
    _check_size(path, layout)
    try:
        # a spreadsheet's byte-order mark is not the header; CRLF and CR read as line ends
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{path.name}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    lines = text.splitlines()
    k = 0
    while k < len(lines) and (not lines[k].strip() or lines[k].lstrip().startswith("#")):
        k += 1
    if k == len(lines):
        raise RecordingError(f"{path.name}: empty; expected a header row '{','.join(REQUIRED)}' and the samples")
    # the delimiter: a comma, else what the header row uses (a semicolon or a tab, as
    # spreadsheets with a decimal comma and some DAQ exports write)
    delim = "," if "," in lines[k] else next((d for d in (";", "\t") if d in lines[k]), ",")
    names = next(_rows(path, [lines[k]], k + 1, delim))[1]
    header = [h.strip().lower() for h in names]
    cols = _select(path, names, layout, _where(path, k + 1), f"the header '{_show(lines[k], 120)}'")
    extra = [h for j, h in enumerate(header) if j not in cols.values()]
    rows, line_no = [], []
    scale = {c: layout.units[c][1] if c in layout.units else 1.0 for c in cols}
    units_row = None
    for i, row in _rows(path, lines[k + 1:], k + 2, delim):
        if not row or all(not c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue
        if not rows and units_row is None and _is_units_row(row, cols):
            scale, units_row = _units(path, i, row, cols, layout), i
            continue
        if len(row) < len(header):
            raise RecordingError(f"{_where(path, i)}: {len(row)} values, the header has {len(header)} columns; "
                                 f"expected a value in each")
        vals = []
        for c, j in cols.items():
            s = row[j].strip()
            try:
                v = float(s)
            except ValueError:
                raise RecordingError(f"{_where(path, i)}: {c} is '{_show(s, 40)}', not a number") from None
            if not math.isfinite(v):
                raise RecordingError(f"{_where(path, i)}: {c} is {s} (values must be finite numbers)")
            vals.append(v)
        rows.append(vals)
        line_no.append(i)
    if len(rows) < MIN_SAMPLES:
        raise RecordingError(f"{path.name}: {len(rows)} data rows, at least {MIN_SAMPLES} needed")
    a = np.array(rows)
    data = {c: a[:, n] * scale[c] for n, c in enumerate(cols)}
    notes = _mapping_note({c: names[j] for c, j in cols.items()})
    notes += _units_note(scale, f"units row (line {units_row})" if units_row is not None else f"{CONFIG} [units]")
    if extra:
        notes.append(f"ignored column(s) {', '.join(extra)}")
    return _recording(path, data, np.array(line_no), notes, x_e)


# ------------------------------------------------------------------------ binary formats
def _library(path, kind):
    """The optional reader of a binary format (pyproject extras hdf5, tdms)."""
    module, fmt = EXTRAS[kind]
    try:
        return importlib.import_module(module)
    except ImportError:
        raise RecordingError(f"{path.name}: reading {fmt} needs the optional {module} package: "
                             f"pip install \"dfa-toolkit[{kind}]\"") from None


def _unreadable(path, fmt, exc) -> RecordingError:
    # the libraries raise OSError, KeyError, ValueError, ... on a damaged file: one line of it
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return RecordingError(f"{path.name}: cannot read as {fmt}: {_show(first, 120)}")


def _channels(path, names, layout, found) -> dict:
    """our column -> channel name, time optional (a sample time may give it)."""
    cols = _select(path, names, layout, path.name, found, time_optional=True)
    return {c: names[j] for c, j in cols.items()}


def _array(path, c, name, a) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 1:
        raise RecordingError(f"{path.name}: channel '{name}' ({c}) has shape {a.shape}; one 1-D array per channel "
                             f"expected")
    if a.dtype.kind not in "iuf":
        raise RecordingError(f"{path.name}: channel '{name}' ({c}) holds {a.dtype} values, not numbers")
    return a.astype(float)


def _seconds(path, value, source, positive=True) -> float:
    """A time attribute or property (a number, or an array of one) in seconds."""
    try:
        x = float(np.asarray(value, dtype=float).reshape(-1)[0]) if np.size(value) == 1 else math.nan
    except (TypeError, ValueError):
        x = math.nan
    if not math.isfinite(x) or (positive and x <= 0):
        raise RecordingError(f"{path.name}: {source} is {_show(repr(value), 40)}: a "
                             f"{'positive ' if positive else ''}number of seconds expected")
    return x


def _binary(path, data, names, notes, layout, dt, x_e) -> Recording:
    """A binary recording's channels (our column -> array, as stored) to a Recording: the
    lengths agree, the values are finite, units to SI, time from a sample time if absent."""
    n = {c: a.size for c, a in data.items()}
    if len(set(n.values())) > 1:
        raise RecordingError(f"{path.name}: channels of different lengths: " +
                             ", ".join(f"{c} ('{names[c]}') {m}" for c, m in n.items()))
    size = next(iter(n.values()))
    if size < MIN_SAMPLES:
        raise RecordingError(f"{path.name}: {size} samples, at least {MIN_SAMPLES} needed")
    for c, a in data.items():
        bad = np.nonzero(~np.isfinite(a))[0]
        if bad.size:
            raise RecordingError(f"{_where(path, int(bad[0]))}: {c} is {a[bad[0]]} (values must be finite numbers)")
    scale = {c: layout.units[c][1] if c in layout.units else 1.0 for c in data}
    data = {c: a * scale[c] for c, a in data.items()}
    notes = _mapping_note(names) + _units_note(scale, f"{CONFIG} [units]") + notes
    if "time" not in data:
        step, offset, source = dt
        data["time"] = offset + step * np.arange(size)
        notes.append(f"no time channel: time from the sample time {step:g} s ({source})" +
                     (f", starting at {offset:g} s" if offset else ""))
    return _recording(path, data, np.arange(size), notes, x_e)


def read_hdf5(path, x_e: float | None = None, layout: Layout | None = None) -> Recording:
    """One recording in HDF5 (h5py): one 1-D dataset per channel in the group [hdf5] group
    (default the root), named as in CSV (dataset.toml [columns] maps them); without a time
    channel the sample time is [hdf5] dt, else a `dt` or `wf_increment` attribute of the
    group or of a channel (and `wf_start_offset`, default 0, its start)."""
    path = Path(path)
    layout = layout or Layout()
    _check_size(path, layout)
    h5py = _library(path, "hdf5")
    try:
        with h5py.File(path, "r") as f:
            g = f.get(layout.hdf5_group)
            if not isinstance(g, h5py.Group):
                groups = ["/"]
                f.visititems(lambda name, o: groups.append("/" + name) if isinstance(o, h5py.Group) else None)
                raise RecordingError(f"{path.name}: no group '{layout.hdf5_group}' ([hdf5] group); its groups: "
                                     f"{_show(', '.join(groups), 120)}")
            names = [k for k, v in g.items() if isinstance(v, h5py.Dataset)]
            chans = _channels(path, names, layout, f"the channels of group '{g.name}' "
                                                   f"({_show(', '.join(names) or 'none', 120)})")
            data = {c: _array(path, c, name, g[name][()]) for c, name in chans.items()}
            dt = None
            if "time" not in chans:
                dt = _hdf5_dt(path, g, [g[chans[c]] for c in chans], layout)
    except RecordingError:
        raise
    except (OSError, LookupError, ValueError, TypeError, RuntimeError) as exc:
        raise _unreadable(path, "HDF5", exc) from None
    return _binary(path, data, chans, [], layout, dt, x_e)


def _hdf5_dt(path, group, channels, layout) -> tuple:
    """(sample time, start, where it came from) of an HDF5 recording without a time channel."""
    if layout.hdf5_dt is not None:
        return layout.hdf5_dt, 0.0, f"{CONFIG} [hdf5] dt"
    for obj in [group] + channels:
        for key in ("dt", "wf_increment"):
            if key in obj.attrs:
                where = f"attribute {key} of '{obj.name}'"
                t0 = _seconds(path, obj.attrs.get("wf_start_offset", 0.0), f"attribute wf_start_offset of "
                                                                            f"'{obj.name}'", positive=False)
                return _seconds(path, obj.attrs[key], where), t0, where
    raise RecordingError(f"{path.name}: no time channel ('{layout.columns.get('time', 'time')}') and no sample "
                         f"time (a dt or wf_increment attribute, or {CONFIG} [hdf5] dt)")


def read_tdms(path, x_e: float | None = None, layout: Layout | None = None) -> Recording:
    """One recording in NI TDMS (npTDMS): the channels of one group ([tdms] group, else the
    file's only group), named as in CSV (dataset.toml [columns] maps them); without a time
    channel, time from the channels' wf_increment and wf_start_offset properties."""
    path = Path(path)
    layout = layout or Layout()
    _check_size(path, layout)
    nptdms = _library(path, "tdms")
    try:
        f = nptdms.TdmsFile.read(path)
        groups = {g.name: g for g in f.groups()}
        if layout.tdms_group is None and len(groups) != 1:
            raise RecordingError(f"{path.name}: {len(groups)} groups ({_show(', '.join(groups) or 'none', 120)}): "
                                 f"name the one with the channels in {CONFIG} [tdms] group")
        name = layout.tdms_group or next(iter(groups))
        if name not in groups:
            raise RecordingError(f"{path.name}: no group '{name}' ([tdms] group); its groups: "
                                 f"{_show(', '.join(groups) or 'none', 120)}")
        channels = {ch.name: ch for ch in groups[name].channels()}
        chans = _channels(path, list(channels), layout, f"the channels of group '{name}' "
                                                        f"({_show(', '.join(channels) or 'none', 120)})")
        data = {c: _array(path, c, ch, channels[ch][:]) for c, ch in chans.items()}
        props = {c: dict(channels[ch].properties) for c, ch in chans.items()}
    except RecordingError:
        raise
    except (OSError, LookupError, ValueError, TypeError, RuntimeError, EOFError, struct.error) as exc:
        raise _unreadable(path, "TDMS", exc) from None
    return _binary(path, data, chans, [], layout, None if "time" in chans else _tdms_dt(path, chans, props, layout),
                   x_e)


def _tdms_dt(path, chans, props, layout) -> tuple:
    """(sample time, start, where) from the channels' waveform properties; they must agree."""
    found = {c: (_seconds(path, p["wf_increment"], f"wf_increment of '{chans[c]}'"),
                 _seconds(path, p.get("wf_start_offset", 0.0), f"wf_start_offset of '{chans[c]}'", positive=False))
             for c, p in props.items() if "wf_increment" in p}
    if not found:
        raise RecordingError(f"{path.name}: no time channel ('{layout.columns.get('time', 'time')}') and no "
                             f"wf_increment property on the channels to give the sample time")
    if len(set(found.values())) > 1:
        raise RecordingError(f"{path.name}: the channels' sample times disagree: " + ", ".join(
            f"{c} wf_increment {dt:g} s, wf_start_offset {t0:g} s" for c, (dt, t0) in found.items()))
    c, (dt, t0) = next(iter(found.items()))
    return dt, t0, f"wf_increment of '{chans[c]}'"


READERS = {".h5": read_hdf5, ".hdf5": read_hdf5, ".tdms": read_tdms}


def read_recording(path, x_e: float | None = None, layout: Layout | None = None) -> Recording:
    """One recording of any format, by its suffix: HDF5 (.h5, .hdf5), TDMS (.tdms), else CSV text."""
    path = Path(path)
    return READERS.get(path.suffix.lower(), read_csv)(path, x_e, layout)


def _recording(path, data, line, notes, x_e) -> Recording:
    """The checks every format shares (time, units, levels) and the interpretation.
    data: our column -> SI array; line: each sample's row in the file (sample index if binary)."""
    t = data["time"]
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if bad.size:
        i = int(bad[0]) + 1
        what = "repeats" if dt[i - 1] == 0 else "goes back from"
        raise RecordingError(f"{_where(path, line[i])}: time {t[i]:g} s {what} the previous row's {t[i - 1]:g} s "
                             f"(time must increase strictly)")
    step = float(np.median(dt))
    if abs(t[0]) > 1.5 * step:
        raise RecordingError(f"{_where(path, line[0])}: time starts at {t[0]:g} s; it must start at 0 at the "
                             f"start of the protocol (reset stage first)")
    rec = Recording(path.stem, path, t, data["voltage"], data["force"], data["stroke"], data.get("current"), line)
    rec.notes.extend(notes)
    gaps = np.nonzero(dt > GAP_FACTOR * step)[0]
    if gaps.size:
        spans = ", ".join(f"{t[g]:.4g}-{t[g + 1]:.4g} s" for g in gaps[:5]) + (" ..." if gaps.size > 5 else "")
        rec.notes.append(f"{gaps.size} gap(s) in time (steps over {GAP_FACTOR:g}x the median {step * 1e3:.3g} ms): "
                         f"{spans}; kept, the fit uses the samples there are")
    _check_units(rec, x_e)
    _interpret(rec)
    return rec


def _check_units(rec: Recording, x_e: float | None = None) -> None:
    p = rec.path
    vmax = float(np.max(np.abs(rec.voltage)))
    if vmax <= MAX_KV_LOOKING:
        i = int(np.argmax(np.abs(rec.voltage)))
        raise RecordingError(f"{_where(p, rec.line[i])}: voltage peaks at {rec.voltage[i]:g}; SI units (V) expected, "
                             f"this looks like kilovolts" if vmax > 0 else
                             f"{p.name}: the voltage is 0 throughout: nothing was applied; expected the drive's "
                             f"voltage (V)")
    fmax = float(np.max(np.abs(rec.force)))
    if fmax > MAX_FORCE:
        i = int(np.argmax(np.abs(rec.force)))
        raise RecordingError(f"{_where(p, rec.line[i])}: force {rec.force[i]:g} N; SI units (N) expected, above "
                             f"{MAX_FORCE:g} N is not a DFA load")
    smax = float(np.max(np.abs(rec.stroke)))
    limit = MAX_STROKE if x_e is None else 1.5 * x_e
    if smax > limit:
        i = int(np.argmax(np.abs(rec.stroke)))
        # millimetres: the value over 1000 fits, and the value itself is far out of reach
        mm = smax / 1000.0 <= limit and (x_e is None or smax > 10.0 * limit)
        raise RecordingError(f"{_where(p, rec.line[i])}: stroke {rec.stroke[i]:g}; SI units (m) expected" +
                             (f" - this looks like millimetres (the actuator's full stroke is {x_e * 1e3:.3g} mm)"
                              if mm and x_e is not None else " - this looks like millimetres" if mm else
                              f", above the actuator's reach ({limit:g} m)"))


def _regular_switches(t_sw: np.ndarray, dt: float) -> np.ndarray:
    """Switch instants of a square-wave reset, timed to a fraction of a sample: a 1 kHz
    record of an ideal square wave only brackets each switch within a sample (the
    interpolated crossing errs by up to dt/2), but a regular wave's switches lie on
    t0 + k P/2, and the sampling phase walks along the wave, so a straight-line fit
    through all of them averages those errors out. Used when every switch but the last
    lies within 0.75 dt of the line (the first one - the end of a pre-trigger stretch at
    0 V - may be off it); else the measured crossings stand. The last switch - the last
    of the wave, or the hold's start on the generator's own timer, off the wave's grid -
    joins the line only when it lies within HOLD_ON_GRID dt of the line through the
    others: a unipolar 2 Hz reset's 3 switches and the hold's start, all within 0.75 dt
    of one line, gave a line 1.2e-3 off the wave's period and switches 0.6 ms off. Three
    switches of a wave are enough for its line (GRID_MIN): read one by one, each within its
    sample, a 4 Hz unipolar reset's were up to 0.6 ms apart from a grid, which no shift or
    clock of the drive (the diagnosis's timing nuisances) could mend - a 137 um spike at a
    switch of a held-out recording, 6.7 um RMS over its reset."""
    for first in (0, 1):
        n = len(t_sw) - first - 1
        if n < GRID_MIN:
            continue
        k = np.arange(n)
        b, a = np.polyfit(k, t_sw[first:first + n], 1)
        if np.max(np.abs(t_sw[first:first + n] - (a + b * k))) > 0.75 * dt:
            continue
        if abs(t_sw[-1] - (a + b * n)) <= HOLD_ON_GRID * dt:     # the wave's own last switch
            k = np.arange(n + 1)
            b, a = np.polyfit(k, t_sw[first:], 1)
            return np.concatenate([t_sw[:first], a + b * k])
        return np.concatenate([t_sw[:first], a + b * k, t_sw[first + n:]])
    return t_sw


HOLD_ON_GRID = 0.6    # the last switch within this many samples of the others' line is on it
GRID_MIN = 3          # switches of a wave (the last one aside) that put it on a line


def _interpret(rec: Recording) -> None:
    """Voltage -> Protocol (levels switched at threshold crossings, module docstring),
    force -> Load."""
    p, t, v = rec.path, rec.t, rec.voltage
    A = float(np.percentile(np.abs(v), 99))
    # the level of each sample: +1, 0, -1 (half-amplitude thresholds)
    lev = np.where(v > 0.5 * A, 1, np.where(v < -0.5 * A, -1, 0))
    sw = np.nonzero(np.diff(lev) != 0)[0]            # switch between sample i and i + 1
    # a switch's time: where the voltage crosses the midpoint between the two levels
    t_sw = []
    for i in sw:
        mid = 0.5 * A * (lev[i] + lev[i + 1])
        dv = v[i + 1] - v[i]
        f = 0.5 if dv == 0 else min(max((mid - v[i]) / dv, 0.0), 1.0)
        t_sw.append(t[i] + f * (t[i + 1] - t[i]))
    raw = np.array(t_sw)
    t_sw = _regular_switches(raw, float(np.median(np.diff(t))))
    rec.gridded = bool(len(raw) and not np.array_equal(t_sw, raw))
    edges = np.concatenate([[0.0], t_sw, [t[-1]]])
    starts = np.concatenate([[0], sw + 1])
    ends = np.concatenate([sw + 1, [len(t)]])
    levels = []
    for a, b, s in zip(starts, ends, lev[starts]):
        seg = v[a:b]
        # the stretch must sit on its level (ramps at the switches excluded: one sample each side)
        core = seg[1:-1] if len(seg) > 3 else seg
        off = np.abs(core - s * A)
        if off.size and off.max() > LEVEL_TOL * A:
            j = int(a + (1 if len(seg) > 3 else 0) + np.argmax(off))
            raise RecordingError(f"{_where(p, rec.line[j])}: voltage {v[j]:g} V at {t[j]:g} s is off every level of "
                                 f"this recording: expected +{A:g}, 0 or -{A:g} V within {LEVEL_TOL:.0%} between "
                                 f"switches (the voltage column contradicts itself)")
        levels.append(float(np.mean(core)) if s != 0 else 0.0)
    if levels[-1] == 0.0:
        raise RecordingError(f"{p.name}: the voltage ends at 0 V (from {edges[-2]:g} s): no hold stage to fit; "
                             f"expected a recording that ends in its hold")
    rec.amplitude = A
    rec.hold_voltage = levels[-1]
    rec.switches, rec.levels = np.asarray(t_sw, float), tuple(levels)
    _drive(rec)
    if lev[0] != 0:
        rec.notes.append("no rest stretch before the drive: the sensor zero is fitted over the whole recording with "
                         "its timing, not read at rest (it then also takes up a constant stroke mismatch)")
    F = rec.force
    Fm = float(np.mean(F))
    # judged on a moving mean over FORCE_WINDOW samples: a load cell's noise (its peak to
    # peak over 20 000 samples is ~8 SD) is not a varying load, and is not fed to the model
    k = min(FORCE_WINDOW, F.size)
    Fs = np.convolve(np.pad(F, (k // 2, k - 1 - k // 2), mode="edge"), np.ones(k) / k, mode="valid")
    if np.ptp(Fs) > FORCE_TOL * max(abs(Fm), 1e-3):
        rec.load = Load(Sampled(t, Fs, name="force"))
        rec.notes.append(f"the force varies ({Fs.min():.4g}-{Fs.max():.4g} N, moving mean over {k} samples): used "
                         f"as a sampled load")
    else:
        rec.load = Load(Fm)


def _drive(rec: Recording) -> None:
    """rec.protocol and rec.reset_end from rec.switches and rec.levels: the levels held
    between the switches, the last one held to the end of the recording."""
    edges = np.concatenate([[0.0], rec.switches, [rec.duration]])
    levels = rec.levels
    rec.reset_end = float(edges[-2])
    stages = []
    if len(levels) > 1:
        reset = Sampled(edges[:-2], np.array(levels[:-1]), hold=True)
        stages.append(Stage(reset, float(edges[-2]), "reset"))
    stages.append(Stage(DC(levels[-1]), float(edges[-1] - edges[-2]), "hold"))
    rec.protocol = Protocol(stages)


def retimed(rec: Recording, clock: float = 0.0, hold_shift: float = 0.0, shift: float = 0.0,
            gain: float = 0.0) -> Recording:
    """A copy of rec whose drive ran on other timing than read off its voltage record:
    the reset's switches (all but the last) `shift` seconds later and stretched by
    (1 + clock) about the first one (its generator's clock `clock` slower than the
    sampler's), and the hold's start (the last switch) `hold_shift` seconds later. A
    generator's clock is not the data-acquisition system's (0.1 % apart is common); a
    1 kHz record of a few switches cannot show it (8 switches of a 2 Hz train drift by
    0.6 ms in all at 3.5e-4, less than a sample), nor a switch within its sample, and the
    zipping each switch starts moves at ~1 m/s (the diagnosis fits them from the stroke:
    diagnosis/timing.py). `gain`: the voltage monitor read the levels (1 + gain) times
    what the actuator saw (its calibration): the drive is the read levels over 1 + gain."""
    if rec.switches is None or len(rec.switches) == 0:
        return replace(rec)
    if not -0.5 < gain < 0.5:
        raise RecordingError(f"{rec.name}: the voltage monitor's gain corrected by {gain:g}; expected a small "
                             f"correction (|gain| < 0.5)")
    sw = rec.switches.copy()
    if clock or shift or hold_shift:
        if len(sw) > 1:
            sw[:-1] = sw[0] + shift + (sw[:-1] - sw[0]) * (1.0 + clock)
        sw[-1] += hold_shift
        if not (np.all(np.diff(sw) > 0) and 0.0 < sw[0] and sw[-1] < rec.duration):
            raise RecordingError(f"{rec.name}: the drive's timing corrected by {shift:g} s, {clock:g} and "
                                 f"{hold_shift:g} s puts its switches out of order or outside the recording; expected "
                                 f"small corrections")
    levels = rec.levels if not gain else tuple(float(v) / (1.0 + gain) for v in rec.levels)
    out = replace(rec, switches=sw, levels=levels, notes=list(rec.notes))
    _drive(out)
    return out


def _files(folder, layout) -> list:
    """The recordings: the files matching [files] include (one list, sorted by name)."""
    found = set()
    for g in layout.include:
        found.update(f for f in folder.glob(g) if f.is_file() and f.name not in ("actuator.toml", CONFIG))
    return sorted(found)


def read_dataset(folder) -> Dataset:
    """The actuator and every recording of a dataset folder, checked (module docstring)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingError(f"{folder}: not a folder")
    toml = folder / "actuator.toml"
    if not toml.is_file():
        raise RecordingError(f"{folder}: no actuator.toml; expected the parameter file of the device there")
    try:
        params = load_parameters(toml)
    except ParameterError as exc:
        raise RecordingError(f"actuator.toml: {exc}") from None
    layout = read_layout(folder)
    files = _files(folder, layout)
    if not files:
        # without a dataset.toml only CSV is read (the contract): say so when binary files lie there
        binary = [] if layout.source else sorted(f.name for f in folder.iterdir() if f.suffix.lower() in BINARY)
        raise RecordingError(f"{folder}: no recordings ({', '.join(layout.include)}); expected one file per test" + (
            f" ({binary[0]}{' ...' if len(binary) > 1 else ''} is read when the folder has a {CONFIG})" if binary
            else ""))
    stems = {}
    for f in files:
        if f.stem in stems:     # the report names a recording by its file's stem
            raise RecordingError(f"{folder}: {stems[f.stem]} and {f.name} are both recording '{f.stem}'; "
                                 f"rename one")
        stems[f.stem] = f.name
    from ..physics.kinematics import make
    x_e = float(make(params).x_e)
    recs = [read_recording(f, x_e, layout) for f in files]
    group_conditions(recs)
    return Dataset(folder, params, recs)


def group_conditions(recs) -> None:
    """Group repetitions into conditions: hold voltages whose magnitudes lie within
    CONDITION_V of each other (relative) and mean forces within CONDITION_F (relative, at
    least 10 mN) are one condition - a voltage monitor's gain error (0.2 %) and a load
    cell's noise must not split repetitions, nor the polarity a polarity inversion's
    recording happens to end on (the model is odd in V). Each recording's `group` becomes
    its condition's (first member's values, rounded to 10 V and 10 mN)."""
    keys = []
    for r in recs:
        V, F = abs(r.hold_voltage), r.force_mean
        for k, (V0, F0) in keys:
            if abs(V - V0) <= CONDITION_V * abs(V0) and abs(F - F0) <= max(CONDITION_F * abs(F0), 0.01):
                r.group = k
                break
        else:
            r.group = (round(V, -1), round(F, 2))
            keys.append((r.group, (V, F)))
