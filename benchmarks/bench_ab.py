"""Two checkouts of the package, timed in one run: this one against another (e.g. a git
worktree of the commit before a refactoring, with its kernels compiled: `python -m
dfa_model.aot` there). The machine's speed drifts by tens of percent within minutes, so
the two are measured in interleaved rounds (a process each, alternating), and the figure
is the median over rounds of each round's ratio.

Timed, as users run them (each the fastest of --repeats calls in its process, after a
warm-up: the least disturbed by other work on the machine):
  full       simulate() + unzipping_speed, the standard protocol (bench_protocol.py's)
  surrogate  the fitted surrogate's simulate() + unzipping_speed, the same protocol
             (bench_reduced.py's (1)); the surrogate is fitted once, by this checkout
  stepper    10 000 exact FMU-style communication steps of 1 ms under 5 Hz inversion

With --instructions (valgrind's callgrind on the PATH), each workload's machine
instructions per call are counted instead: deterministic, so a difference of 1 % shows
(the time of atomic reference counts and cache misses is not in it).

    python benchmarks/bench_ab.py OTHER_CHECKOUT [--rounds N] [--repeats N] [--instructions]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))

CHILD = r"""
import gc, json, statistics, sys, time, warnings
sys.path.insert(0, sys.argv[1])
from dfa_model import PhysicsWarning, Protocol, preset, simulate, _jit
from dfa_model.numerics.stepper import Stepper
import reduced
warnings.simplefilter("ignore")
repeats, surrogate_file = int(sys.argv[2]), sys.argv[3]
p = preset("vshape-table1")
proto = Protocol.reset_then_hold(6000.0, 20.0)
s = reduced.load(surrogate_file)

def stepper():
    st = Stepper(p, v_nominal=6000.0)
    for k in range(10000):
        st.step(1e-3, 6000.0 if (k // 100) % 2 == 0 else -6000.0, 5.0)

WORK = {"full": lambda: simulate(p, proto, load=5.0).unzipping_speed,
        "surrogate": lambda: s.simulate(proto, 5.0).unzipping_speed, "stepper": stepper}
if len(sys.argv) > 4:             # count: run one workload n times (under callgrind)
    fn = WORK[sys.argv[4]]
    fn()
    for _ in range(repeats):
        fn()
    raise SystemExit(0)


def med(fn, n):
    fn()
    ts = []
    for _ in range(n):
        gc.disable()
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
        gc.enable()
    return min(ts)

out = {"mode": _jit.MODE,
       "full": med(lambda: simulate(p, proto, load=5.0).unzipping_speed, repeats),
       "surrogate": med(lambda: s.simulate(proto, 5.0).unzipping_speed, 10 * repeats),
       "stepper": med(stepper, max(1, repeats // 5))}
print(json.dumps(out))
"""


def run(tree, repeats, surrogate_file):
    r = subprocess.run([sys.executable, "-c", CHILD, tree, str(repeats), surrogate_file], capture_output=True,
                       text=True, cwd=tempfile.gettempdir())
    if r.returncode != 0:
        raise SystemExit(f"{tree}: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def count(tree, work, n, surrogate_file):
    """Instructions of `n` calls of `work` in a process, by callgrind (the interpreter
    itself, not a shim script: sys.executable)."""
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "cg.out")
        r = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", sys.executable, "-c", CHILD,
                            tree, str(n), surrogate_file, work], capture_output=True, text=True,
                           cwd=tempfile.gettempdir())
        for line in r.stderr.splitlines():
            if "Collected :" in line:
                return int(line.split()[-1])
        raise SystemExit(f"{tree}: callgrind gave no count: {r.stderr.strip()[-300:]}")


def instructions(this, other, sfile):
    """Per call: the difference between runs of many and few calls (the start-up cancels)."""
    reps = {"full": (2, 12), "surrogate": (10, 110), "stepper": (0, 1)}
    print("machine instructions per call (callgrind)")
    for key, (lo, hi) in reps.items():
        per = {}
        for name, tree in (("this", this), ("other", other)):
            per[name] = (count(tree, key, hi, sfile) - count(tree, key, lo, sfile)) / (hi - lo)
        print(f"  {key:10s} this {per['this'] / 1e6:9.3f} M   other {per['other'] / 1e6:9.3f} M   "
              f"this/other {per['this'] / per['other']:.3f}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", help="the other checkout (its folder holds dfa_model/)")
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--instructions", action="store_true", help="count instructions (callgrind) instead of timing")
    a = ap.parse_args()
    this = os.path.dirname(HERE)
    sys.path.insert(0, this)
    import reduced
    from dfa_model import preset
    with tempfile.TemporaryDirectory() as d:
        sfile = os.path.join(d, "table1.json")
        reduced.fit(preset("vshape-table1"), family="charge", progress=False).save(sfile)
        if a.instructions:
            return instructions(this, a.other, sfile)
        rows = {"this": [], "other": []}
        for k in range(a.rounds):
            order = (("this", this), ("other", a.other)) if k % 2 == 0 else (("other", a.other), ("this", this))
            for name, tree in order:
                rows[name].append(run(tree, a.repeats, sfile))
            print(f"round {k + 1}/{a.rounds}: " + ", ".join(
                f"{key} {rows['this'][-1][key] * 1e3:.3f}/{rows['other'][-1][key] * 1e3:.3f} ms"
                for key in ("full", "surrogate", "stepper")), flush=True)
    print(f"\nthis ({rows['this'][0]['mode']}) against {a.other} ({rows['other'][0]['mode']}), {a.rounds} interleaved "
          f"rounds; medians over rounds")
    for key in ("full", "surrogate", "stepper"):
        t = statistics.median(r[key] for r in rows["this"])
        o = statistics.median(r[key] for r in rows["other"])
        ratio = statistics.median(x[key] / y[key] for x, y in zip(rows["this"], rows["other"]))
        print(f"  {key:10s} this {t * 1e3:9.3f} ms   other {o * 1e3:9.3f} ms   this/other {ratio:.3f} "
              f"(per-round ratios {min(x[key] / y[key] for x, y in zip(rows['this'], rows['other'])):.3f}-"
              f"{max(x[key] / y[key] for x, y in zip(rows['this'], rows['other'])):.3f})")


if __name__ == "__main__":
    main()
