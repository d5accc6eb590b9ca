"""Measured recordings: reading, validating and interpreting a dataset folder.

A dataset (architecture notes, *contract*) is a folder with `actuator.toml` (the parameter
file: what is known about the device) and one CSV per test, header
`time,voltage,force,stroke` (optional `current`; further columns, such as those of
`dfa simulate --out`, are ignored and listed in the notes), SI units, `#` comment lines
allowed before the header.

Checks (each failure is one line naming the file and, where there is one, the row as
its line number in the file):
- the folder exists, holds `actuator.toml` and at least one CSV;
- the header has the four columns; every value is a finite number;
- time starts within one sample of 0 and strictly increases (a repeated or backward time
  is an error: which sample is right cannot be told);
- at least MIN_SAMPLES rows;
- units: a stroke above the actuator's full stroke x_e that would fit as millimetres, a
  voltage of at most MAX_KV_LOOKING V (kilovolts), a force above MAX_FORCE N;
- the voltage agrees with itself: every stretch between switches sits on one of the
  levels +A, 0, -A of the recording's amplitude A (within LEVEL_TOL of A), and the hold
  (the last stretch) is not 0 V.

Lab exports: a UTF-8 byte-order mark is skipped; the delimiter is a comma, else the
header row's semicolon or tab; a row of units under the header (UNITS) converts each
column to SI (noted).

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
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .parameters import Parameters, ParameterError
from .parameters import load as load_parameters
from .waveforms import DC, Load, Protocol, Sampled, Stage

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


class RecordingError(ValueError):
    """A recording or dataset that cannot be used as it is (one line: file, row, what)."""


@dataclass
class Recording:
    """One measured test. Arrays in SI units; `line` maps sample i to its line in the file."""

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
        """(hold voltage, mean force) of its condition: recordings of one condition
        (repetitions) share it. In a dataset, the group's (group_conditions); alone, its
        own, rounded to the nearest 10 V and 10 mN."""
        if self.group is not None:
            return self.group
        return (round(self.hold_voltage, -1), round(self.force_mean, 2))


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
    return f"{path.name}, row {line}" if line is not None else path.name


# a units row under the header: the units each column may be given in, with their factor to SI
UNITS = {"time": {"s": 1.0, "ms": 1e-3},
         "voltage": {"v": 1.0, "kv": 1e3},
         "force": {"n": 1.0, "mn": 1e-3},
         "stroke": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6},
         "current": {"a": 1.0, "ma": 1e-3, "ua": 1e-6, "µa": 1e-6, "na": 1e-9}}


def _is_units_row(row, cols) -> bool:
    """A row whose used columns are all text (not numbers): read as the units row."""
    def num(x):
        try:
            float(x)
            return True
        except ValueError:
            return False
    return all(j < len(row) and row[j].strip() and not num(row[j].strip()) for j in cols.values())


def _units(path, line, row, cols) -> dict:
    out = {}
    for c, j in cols.items():
        u = row[j].strip().strip("[]()").lower()
        if u not in UNITS[c]:
            raise RecordingError(f"{_where(path, line)}: {c} in unit '{row[j].strip()}' (units row); allowed: "
                                 f"{', '.join(UNITS[c])}")
        out[c] = UNITS[c][u]
    return out


def read_csv(path, x_e: float | None = None) -> Recording:
    """Read and check one recording (module docstring). x_e: the actuator's full stroke
    (m), which bounds the stroke column (read_dataset gives it); without it, MAX_STROKE."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")     # a spreadsheet's byte-order mark is not the header
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{path.name}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    lines = text.splitlines()
    k = 0
    while k < len(lines) and (not lines[k].strip() or lines[k].lstrip().startswith("#")):
        k += 1
    if k == len(lines):
        raise RecordingError(f"{path.name}: empty (no header row '{','.join(REQUIRED)}')")
    # the delimiter: a comma, else what the header row uses (a semicolon or a tab, as
    # spreadsheets with a decimal comma and some DAQ exports write)
    delim = "," if "," in lines[k] else next((d for d in (";", "\t") if d in lines[k]), ",")
    header = [h.strip().lower() for h in next(csv.reader([lines[k]], delimiter=delim))]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise RecordingError(f"{_where(path, k + 1)}: missing column(s) {', '.join(missing)} in the header "
                             f"'{lines[k].strip()}' (expected {','.join(REQUIRED)}[,current])")
    dup = sorted({h for h in header if header.count(h) > 1 and h in REQUIRED + OPTIONAL})
    if dup:
        raise RecordingError(f"{_where(path, k + 1)}: column(s) {', '.join(dup)} appear more than once")
    cols = {c: header.index(c) for c in REQUIRED + OPTIONAL if c in header}
    extra = [h for h in header if h not in cols]
    rows, line_no = [], []
    scale, units_row = {c: 1.0 for c in cols}, None
    for i, row in enumerate(csv.reader(lines[k + 1:], delimiter=delim), start=k + 2):
        if not row or all(not c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue
        if not rows and units_row is None and _is_units_row(row, cols):
            scale, units_row = _units(path, i, row, cols), i
            continue
        if len(row) < len(header):
            raise RecordingError(f"{_where(path, i)}: {len(row)} values, the header has {len(header)} columns")
        vals = []
        for c, j in cols.items():
            s = row[j].strip()
            try:
                v = float(s)
            except ValueError:
                raise RecordingError(f"{_where(path, i)}: {c} is '{s}', not a number") from None
            if not math.isfinite(v):
                raise RecordingError(f"{_where(path, i)}: {c} is {s} (values must be finite numbers)")
            vals.append(v)
        rows.append(vals)
        line_no.append(i)
    if len(rows) < MIN_SAMPLES:
        raise RecordingError(f"{path.name}: {len(rows)} data rows, at least {MIN_SAMPLES} needed")
    a = np.array(rows)
    line = np.array(line_no)
    data = {c: a[:, n] * scale[c] for n, c in enumerate(cols)}
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
    if units_row is not None and any(v != 1.0 for v in scale.values()):
        rec.notes.append("units row (line " + str(units_row) + "): " + ", ".join(
            f"{c} x {scale[c]:g}" for c in cols if scale[c] != 1.0) + " to SI")
    if extra:
        rec.notes.append(f"ignored column(s) {', '.join(extra)}")
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
                             f"{p.name}: the voltage is 0 throughout: nothing was applied")
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
    through all of them averages those errors out. Used when every switch lies within
    0.75 dt of the line (the first one - the end of a pre-trigger stretch at 0 V - and
    the last one - the start of the hold - may be off it); else the measured crossings
    stand."""
    for first, last in ((0, 0), (0, 1), (1, 0), (1, 1)):
        n = len(t_sw) - first - last
        if n < 4:
            continue
        k = np.arange(n)
        b, a = np.polyfit(k, t_sw[first:first + n], 1)
        fit = a + b * k
        if np.max(np.abs(t_sw[first:first + n] - fit)) <= 0.75 * dt:
            return np.concatenate([t_sw[:first], fit, t_sw[first + n:]])
    return t_sw


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
    t_sw = _regular_switches(np.array(t_sw), float(np.median(np.diff(t))))
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
                                 f"this recording (+{A:g}, 0, -{A:g} V, within {LEVEL_TOL:.0%}): the voltage column "
                                 f"contradicts itself")
        levels.append(float(np.mean(core)) if s != 0 else 0.0)
    if levels[-1] == 0.0:
        raise RecordingError(f"{p.name}: the voltage ends at 0 V (from {edges[-2]:g} s): no hold stage to fit")
    rec.amplitude = A
    rec.hold_voltage = levels[-1]
    rec.reset_end = float(edges[-2])
    stages = []
    if len(levels) > 1:
        reset = Sampled(edges[:-2], np.array(levels[:-1]), hold=True)
        stages.append(Stage(reset, float(edges[-2]), "reset"))
    stages.append(Stage(DC(levels[-1]), float(edges[-1] - edges[-2]), "hold"))
    rec.protocol = Protocol(stages)
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


def read_dataset(folder) -> Dataset:
    """The actuator and every recording of a dataset folder, checked (module docstring)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingError(f"{folder}: not a folder")
    toml = folder / "actuator.toml"
    if not toml.is_file():
        raise RecordingError(f"{folder}: no actuator.toml (the parameter file of the device)")
    try:
        params = load_parameters(toml)
    except ParameterError as exc:
        raise RecordingError(f"actuator.toml: {exc}") from None
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise RecordingError(f"{folder}: no recordings (*.csv)")
    from .kinematics import make
    x_e = float(make(params).x_e)
    recs = [read_csv(f, x_e) for f in files]
    group_conditions(recs)
    return Dataset(folder, params, recs)


def group_conditions(recs) -> None:
    """Group repetitions into conditions: hold voltages within CONDITION_V of each other
    (relative) and mean forces within CONDITION_F (relative, at least 10 mN) are one
    condition - a voltage monitor's gain error (0.2 %) and a load cell's noise must not
    split repetitions. Each recording's `group` becomes its condition's (first member's
    values, rounded to 10 V and 10 mN)."""
    keys = []
    for r in recs:
        V, F = r.hold_voltage, r.force_mean
        for k, (V0, F0) in keys:
            if abs(V - V0) <= CONDITION_V * abs(V0) and abs(F - F0) <= max(CONDITION_F * abs(F0), 0.01):
                r.group = k
                break
        else:
            r.group = (round(V, -1), round(F, 2))
            keys.append((r.group, (V, F)))
