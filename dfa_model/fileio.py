"""Output files: checked before any work starts, written atomically.

A run that ends with "cannot write" after minutes of work loses its result, and a
half-written CSV looks like a complete one. So every output path is checked up front
(`check_writable`), and files appear only complete (`write_atomic`: a temporary file
beside the target, then a rename).
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

PLOT_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "tif", "tiff", "eps", "ps", "webp")


class OutputError(ValueError):
    """An output path that cannot be written (the message names the flag or field)."""


def check_writable(name: str, path, formats: tuple[str, ...] | None = None) -> Path:
    """Raise OutputError unless `path` can be created or overwritten as a file (its folder
    exists and is writable; it is not a folder itself), with a suffix from `formats`."""
    p = Path(path)
    if str(path) == "" or p.name == "":
        raise OutputError(f"{name}: expected a file name, got {str(path)!r}")
    if formats is not None and p.suffix.lower().lstrip(".") not in formats:
        has = f"has the suffix {p.suffix!r}" if p.suffix else "has no suffix"
        raise OutputError(f"{name}: {str(p)!r} {has}; expected one of {', '.join('.' + f for f in formats)}")
    if p.is_dir():
        raise OutputError(f"{name}: {str(p)!r} is a folder, expected a file name")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError(f"{name}: folder {str(folder)!r} does not exist (create it first)")
    if p.exists() and not os.access(p, os.W_OK):
        raise OutputError(f"{name}: {str(p)!r} is not writable (permission denied)")
    # permissions alone do not tell (root passes os.access; /proc refuses new files): try
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".probe", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"{name}: cannot create a file in folder {str(folder)!r} ({exc.strerror}); expected a "
                          f"writable folder") from None
    return p


def write_atomic(path, write) -> None:
    """Create `path` complete or not at all: `write(tmp_path)` fills a temporary file in
    the same folder, which then replaces the target."""
    p = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part" + p.suffix, dir=p.parent if str(p.parent) else ".")
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text_atomic(path, text: str) -> None:
    write_atomic(path, lambda tmp: Path(tmp).write_text(text))


def toml_float(v) -> str:
    """A float as TOML text that reads back to the same float: the shortest of %.6g ..
    %.17g that round-trips, with a decimal point or exponent so TOML reads a float
    (6000.0, 2e+12, 1.7556e-05, inf)."""
    v = float(v)
    if v != v:
        return "nan"
    if v in (float("inf"), float("-inf")):
        return "inf" if v > 0 else "-inf"
    for digits in range(6, 18):
        text = f"{v:.{digits}g}"
        if float(text) == v:
            break
    if not any(c in text for c in ".en"):
        text += ".0"
    return text
