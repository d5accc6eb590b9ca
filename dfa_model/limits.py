"""Stated limits: input ranges and resource bounds, checked before work starts.

Every entry point (the Python API, the `dfa` command, the FMU) checks against these, so
that nothing allocates tens of GiB or runs for minutes by accident, and an input the
solver cannot resolve is refused with the key to change instead of failing mid-run.
README, 'Reliability', lists them.
"""
from __future__ import annotations

import math

MAX_VOLTAGE = 1e6           # V: far above any DFA (their films break down at tens of kV)
MAX_FORCE = 1e6             # N: load magnitude
MAX_DURATION = 1e7          # s: total protocol length
MAX_SEGMENTS = 5_000_000    # input breakpoints (switches, samples); each costs at least one step
MAX_OUTPUT_BYTES = 1 << 30  # output arrays: rows x columns x 8 bytes (1 GiB)
# output samples: each costs a full evaluation of the outputs (about 14 us at N = 81), so
# this bounds the output's time to about 30 s as well as its memory to about 300 MB
MAX_OUTPUT_SAMPLES = 2_000_000
MAX_STEPS = 5_000_000       # default step limit of simulate (about a minute at N = 81)
# the stroke must take at least this long to cross its range (b x_e / F, or sqrt(m x_e / F)
# with mass): faster mechanics make TR-BDF2's trapezoidal stage overshoot the stops by
# orders of magnitude (runs failed at 3e-13 s and passed at 9e-13 s; 100x margin)
TAU_MECH_MIN = 1e-11


class LimitError(ValueError):
    """A request beyond a stated limit (the message names the flag or field and the limit)."""


# the magnitude bound and unit of each kind of input signal
SIGNALS = {"voltage": (MAX_VOLTAGE, "V"), "force": (MAX_FORCE, "N")}


def finite_within(name: str, value, bound: float, unit: str = "") -> float:
    """`value` as a float, or ValueError naming `name` unless it is finite with
    |value| <= bound."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: got {value!r}, expected a number") from None
    if not (math.isfinite(v) and abs(v) <= bound):
        raise ValueError(f"{name}: got {value!r}, expected a finite number of magnitude <= {bound:g}"
                         + (f" {unit}" if unit else ""))
    return v


def signal_value(kind: str, value) -> float:
    """A value of input signal `kind` ('voltage', 'force') within its bound (SIGNALS)."""
    return finite_within(kind, value, *SIGNALS[kind])


def check_rows(name: str, rows: int, columns: int, hint: str = "") -> None:
    """Refuse an output of more than MAX_OUTPUT_SAMPLES rows, or of `rows` x `columns`
    float64 beyond MAX_OUTPUT_BYTES."""
    if rows > MAX_OUTPUT_SAMPLES:
        raise LimitError(f"{name}: {rows:.3g} output samples, above the limit of {MAX_OUTPUT_SAMPLES:,} (each costs "
                         f"an evaluation of all outputs: about 30 s and 300 MB at the limit)"
                         f"{'; ' + hint if hint else ''}")
    need = float(rows) * columns * 8
    if need > MAX_OUTPUT_BYTES:
        raise LimitError(f"{name}: {rows:.3g} output samples x {columns} columns would take {need / 2 ** 30:.3g} GiB, "
                         f"above the limit of {MAX_OUTPUT_BYTES / 2 ** 30:g} GiB"
                         f" ({int(MAX_OUTPUT_BYTES / (8 * columns)):,} samples){'; ' + hint if hint else ''}")


def check_segments(name: str, count: float, hint: str = "") -> None:
    """Refuse an input signal of more than MAX_SEGMENTS pieces (before building it)."""
    if count > MAX_SEGMENTS:
        raise LimitError(f"{name}: {count:.3g} signal segments (switches or samples), above the limit of "
                         f"{MAX_SEGMENTS:,}: each is at least one solver step{'; ' + hint if hint else ''}")
