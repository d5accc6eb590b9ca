"""Ctrl-C (SIGINT) while a compiled kernel runs, and in the process pools.

The integrator is one compiled call: a 1900 s run at 30 Hz is ten seconds in it, a long
DC hold sampled finely most of that inside a single step's outputs. Python runs its
SIGINT handler only between bytecodes, so Ctrl-C waited for the call's end, and with
numba's just-in-time kernels (no compiled extension) the KeyboardInterrupt went off while
numba boxed the call's results, which left a NULL in the returned tuple: a segmentation
fault instead of an exit.

`arm()` (the `dfa` command calls it; main thread, default SIGINT handler, POSIX) sets up:

- `FLAG`, one int64 the integrator reads before every step and every dense output
  (integrator.integrate's `interrupt`): it lies in a page of shared memory that is also
  Python's signal wakeup fd, so the C-level signal handler writes the signal's number into
  it the moment SIGINT arrives, while the kernel is still running; the kernel returns
  with status INTERRUPTED within a step;
- a SIGINT handler that raises KeyboardInterrupt as Python's own does, except inside a
  kernel call (`with KERNEL:`), where it only notes the signal: the call returns and is
  boxed undisturbed, and KeyboardInterrupt is raised when it has. It also notes that a
  SIGINT came (`received()`), for an exception that a KeyboardInterrupt turned into
  another (a C extension's import fails with ImportError).

Unarmed (a library caller, a thread, Windows, an event loop's wakeup fd in place) FLAG is
a zero nobody writes and Ctrl-C acts as it did.

Process pools (`local_pool`): a worker arms its own flag, and after a SIGINT its kernel
calls raise KeyboardInterrupt (the task's exception: the run in progress and those queued
for it end within a step) while the worker itself waits for the pool's shutdown, so a
terminal's Ctrl-C, which reaches the whole process group, prints no worker tracebacks and
breaks no pool (on main a worker waiting for work died of it, and `dfa diagnose` hung
in the pool's shutdown). The workers are forked with SIGINT held back (a signal handled
in Python's at-fork hooks is swallowed: the command ran on). On the way out of an
exception (Ctrl-C included) `stop_pool` drops the queued work and sends the workers SIGINT:
their runs end within a step and the pool shuts down in the ordinary way, at once; a
worker that does not end within a grace time is terminated.
"""
from __future__ import annotations

import mmap
import os
import signal
import threading
import time

import numpy as np

FLAG = np.zeros(1, dtype=np.int64)    # integrate's `interrupt` argument (read it at call time)
_armed = False
_fd = -1
_map = None
_depth = 0                            # kernel calls in progress (`with KERNEL:`)
_pending = False                      # SIGINT arrived during one
_received = False                     # SIGINT arrived (armed)
_worker = False                       # a pool's worker: SIGINT outside a kernel call is ignored


def arm() -> bool:
    """Make SIGINT stop a running kernel (see the module's docstring). Returns whether it
    is armed; False leaves everything as it was."""
    global FLAG, _armed, _fd, _map, _received
    if _armed:
        return True
    if (os.name == "nt" or threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        return False
    fd, mm = -1, None
    try:
        if hasattr(os, "memfd_create"):
            fd = os.memfd_create("dfa-interrupt")
        else:                                   # macOS: an unlinked temporary file
            import tempfile
            with tempfile.TemporaryFile() as f:
                fd = os.dup(f.fileno())
        os.ftruncate(fd, mmap.PAGESIZE)
        mm = mmap.mmap(fd, mmap.PAGESIZE)
        os.set_blocking(fd, False)              # set_wakeup_fd requires it
        previous = signal.set_wakeup_fd(fd, warn_on_full_buffer=False)
    except (OSError, ValueError, AttributeError):
        if mm is not None:
            mm.close()
        if fd >= 0:
            os.close(fd)
        return False
    if previous != -1:                          # someone's event loop: theirs stays
        signal.set_wakeup_fd(previous)
        mm.close()
        os.close(fd)
        return False
    _fd, _map, _received = fd, mm, False
    FLAG = np.ndarray((1,), dtype=np.int64, buffer=mm)
    signal.signal(signal.SIGINT, _on_sigint)
    _armed = True
    return True


def disarm() -> None:
    """Undo `arm()`: Python's SIGINT handler, no wakeup fd, FLAG an unwritten zero."""
    global FLAG, _armed, _fd, _map, _pending
    if not _armed:
        return
    if signal.getsignal(signal.SIGINT) is _on_sigint:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    previous = signal.set_wakeup_fd(-1)
    if previous not in (_fd, -1):               # replaced meanwhile: not ours to remove
        signal.set_wakeup_fd(previous)
    FLAG, _armed, _pending = np.zeros(1, dtype=np.int64), False, False
    try:
        _map.close()
    except BufferError:                         # an array on it is still alive: its collection closes it
        pass
    os.close(_fd)
    _fd, _map = -1, None


class armed:
    """`with armed():` arm() for the block (if it can), disarm() after it if it did."""

    def __enter__(self):
        self.did = not _armed and arm()
        return self

    def __exit__(self, *exc):
        if self.did:
            disarm()
        return False


def received() -> bool:
    """Whether a SIGINT came since arm()."""
    return _received


def _on_sigint(signum, frame):
    global _pending, _received
    _received = True
    if _depth:
        _pending = True       # the kernel has seen FLAG; KeyboardInterrupt once it has returned
        return
    if _worker:               # between runs, or before the kernel: every kernel call stops from now on
        _pending = True
        return
    signal.default_int_handler(signum, frame)


def _reset() -> None:
    """Clear FLAG (a SIGINT handled outside a kernel, or another signal's wakeup byte):
    the next wakeup byte lands in it again."""
    FLAG[0] = 0
    os.lseek(_fd, 0, os.SEEK_SET)


class _KernelCall:
    """`with KERNEL:` around a compiled call: a SIGINT during it is raised as
    KeyboardInterrupt when the call has returned (see the module's docstring)."""

    def __enter__(self):
        global _depth
        if _worker and _pending:  # a worker told to stop: the runs queued for it end here
            raise KeyboardInterrupt
        if _armed and FLAG[0] and not _depth:
            _reset()
        _depth += 1

    def __exit__(self, *exc):
        global _depth, _pending
        _depth -= 1
        if _pending and not _depth:
            _pending = _worker
            _reset()
            raise KeyboardInterrupt
        return False


KERNEL = _KernelCall()


def rerun() -> bool:
    """After a kernel call that returned INTERRUPTED without raising: True, with FLAG
    cleared, when another signal with a Python handler wrote the wakeup fd (the run is to
    be run again); KeyboardInterrupt when the byte was SIGINT's."""
    if not (_armed and FLAG[0]):
        return False
    sigint = signal.SIGINT in int(FLAG[0]).to_bytes(8, "little")
    _reset()
    if sigint:
        raise KeyboardInterrupt
    return True


# ------------------------------------------------------------------ process pools
def _worker_init(initializer=None, initargs=()):
    global FLAG, _armed, _fd, _map, _depth, _pending, _received, _worker
    # a forked worker has the parent's handler, wakeup fd and page: its own instead
    if _armed:
        signal.set_wakeup_fd(-1)
        os.close(_fd)
        FLAG, _armed, _fd, _map, _depth, _pending = np.zeros(1, dtype=np.int64), False, -1, None, 0, False
    signal.signal(signal.SIGINT, signal.default_int_handler)
    _worker = True
    if not arm():
        signal.signal(signal.SIGINT, signal.SIG_IGN)    # nothing to stop a run with: the parent terminates
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})   # held back while the parent forked
    if initializer is not None:
        initializer(*initargs)


def local_pool(max_workers=None, initializer=None, initargs=()):
    """A ProcessPoolExecutor whose workers take SIGINT as the end of the run in progress
    only (then run `initializer`), started now."""
    from concurrent.futures import ProcessPoolExecutor
    ex = ProcessPoolExecutor(max_workers=max_workers or os.cpu_count() or 1, initializer=_worker_init,
                             initargs=(initializer, initargs))
    # with the fork method the first submission forks every worker; the at-fork hooks
    # (logging's locks) are Python code, where a KeyboardInterrupt is swallowed: SIGINT
    # waits until they are done
    held = threading.current_thread() is threading.main_thread()
    if held:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        ex.submit(int)
    finally:
        if held:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    return ex


def stop_pool(executor, grace: float = 2.0) -> None:
    """End a local pool (local_pool) now: cancel what is queued, send the workers SIGINT
    (their runs end within a step), and shut down; a worker still running after `grace`
    seconds is terminated."""
    procs = list((getattr(executor, "_processes", None) or {}).values())
    manager = getattr(executor, "_executor_manager_thread", None)
    results = getattr(executor, "_result_queue", None)
    executor.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        try:
            os.kill(p.pid, signal.SIGINT)
        except (ProcessLookupError, TypeError):
            pass
    deadline = time.monotonic() + grace
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
    if manager is not None:
        manager.join(max(0.0, deadline - time.monotonic()))
    if not any(p.is_alive() for p in procs) and (manager is None or not manager.is_alive()):
        return
    # stuck: terminate. The executor's thread then takes the pool for broken, and may fail
    # on a future cancelled meanwhile (InvalidStateError): nothing to report for a pool
    # being given up
    hook = threading.excepthook
    threading.excepthook = lambda a: None if a.thread is manager else hook(a)
    try:
        for p in procs:
            if p.is_alive():
                p.kill()
            p.join(grace)
        # a worker ended while sending its result leaves half a message in the pipe: the
        # thread would wait for the rest for ever (and the interpreter's exit with it);
        # with the parent's write end closed too it reads end-of-file instead
        try:
            results._writer.close()
        except (AttributeError, OSError):
            pass
        if manager is not None:
            manager.join(grace)
    finally:
        threading.excepthook = hook


class owned_pool:
    """`with owned_pool(executor) as ex:` shuts `executor` down on the way out: waiting
    for it normally, at once (stop_pool) on an exception, KeyboardInterrupt included."""

    def __init__(self, executor):
        self.executor = executor

    def __enter__(self):
        return self.executor

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.executor.shutdown()
        else:
            stop_pool(self.executor)
        return False
