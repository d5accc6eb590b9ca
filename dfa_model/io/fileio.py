"""Output files: checked before any work starts, written atomically.

A run that ends with "cannot write" after minutes of work loses its result, and a
half-written CSV looks like a complete one. So every output path is checked up front
(`check_writable`), and files appear only complete (`write_atomic`: a temporary file
beside the target, then a rename), with the mode any new file gets under the user's umask.
"""
from __future__ import annotations

import os
import secrets
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


def _create_temp(folder, prefix: str, suffix: str) -> str:
    """A new, empty file in `folder` (a name no one else has), created with the mode an
    ordinary new file gets: 0o666 less the user's umask (0o644 under 0o022), or what the
    folder's default ACL says.

    tempfile.mkstemp creates 0o600 (right for a private temporary file, wrong for an
    output that replaces the target: a shared folder got files nobody else could open).
    Rather than reading the umask and chmod-ing, the file is created with os.open(...,
    0o666) and the kernel applies the umask itself, at that moment. The usual way to read
    the umask, os.umask(0) then os.umask(old), changes the process-wide umask for an
    instant: a thread creating a file then (a sweep's workers, a plotting thread) would
    get a world-writable file, and a lock only orders our own callers. Reading it once at
    import would miss a later change of umask. So the umask is never read here; callers
    that need the mode (the entries of an FMU's zip) take it from the created file."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(tempfile.TMP_MAX):
        tmp = os.path.join(folder, f"{prefix}{secrets.token_hex(4)}{suffix}")
        try:
            fd = os.open(tmp, flags, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"no unused temporary file name in {str(folder)!r}")


def file_mode(path) -> int:
    """The permission bits of `path` (0o644 for a new file under umask 0o022)."""
    return os.stat(path).st_mode & 0o7777


def write_atomic(path, write) -> None:
    """Create `path` complete or not at all: `write(tmp_path)` fills a temporary file in
    the same folder, which then replaces the target. The result has the mode of a new
    file (0o666 less the umask; see _create_temp), also when it replaces an existing file."""
    p = Path(path)
    tmp = _create_temp(p.parent if str(p.parent) else ".", f".{p.name}.", ".part" + p.suffix)
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
