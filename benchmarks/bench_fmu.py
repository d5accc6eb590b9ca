"""FMU benchmark, as users run it: the Table 1 standard protocol (3 s charge reset at
30 Hz, then 20 s DC, 6 kV, 5 N) at 1 ms communication steps (23 000 steps), against the
floor of each host: the project's trivial mass-spring FMU (fmu/mass_spring_load.py) run
the same way in the same process, interleaved.

1. fmpy.simulate_fmu(fmu, stop_time=23, step_size=1e-3, output_interval=1e-3, input=...)
   with default start values; the trivial FMU gets an input signal with the same events.
   Goal: <= 1.5x the trivial FMU (>= 50x real time). Also the FMI 3.0 FMU
   (`dfa fmu build --fmi 3`), the same way.
2. A C host (tests/fmu_host.c, compiled here): setReal, doStep, getReal at every step,
   23 000 steps at 6 kV, 5 N. Goal: per-step cost <= 1.5x the trivial FMU's.
3. Instantiate + initialize in a fresh process (the C host; fmpy). Goal: <= 0.5 s.
4. With FMUCHECK=/path/to/fmuCheck.linux64: the FMU Compliance Checker
   (fmuCheck -h 1e-3 -s 23), total wall time of both and its findings.

    python benchmarks/bench_fmu.py [--repeats 5]
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from fmu import build_companion_fmu, build_fmu

HERE = Path(__file__).resolve().parent
T, H = 23.0, 1e-3


def square_input(names, high, low, extra):
    """fmpy input: `names[0]` switching high/low every 1/60 s for 3 s, then high; the
    other columns constant (extra). Repeated time rows mark the switches."""
    half = 1.0 / 60.0
    t, v = [0.0], [high]
    for k in range(1, 180):
        t += [k * half, k * half]
        v += [v[-1], low if k % 2 else high]
    t += [3.0, 3.0, T]
    v += [v[-1], high, high]
    cols = [("time", float), (names[0], float)] + [(n, float) for n in extra]
    return np.array([(ti, vi, *extra.values()) for ti, vi in zip(t, v)], dtype=cols)


def simulate_fmu(path, inp, start_values=None):
    import fmpy
    w = time.perf_counter()
    r = fmpy.simulate_fmu(str(path), stop_time=T, step_size=H, output_interval=H, input=inp,
                          start_values=start_values or {})
    return time.perf_counter() - w, r


def interleaved(fns, repeats):
    """Median wall time of each function, run in interleaved rounds after one warm-up."""
    for fn in fns.values():
        fn()
    times = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            times[k].append(fn()[0])
    return {k: (statistics.median(v), min(v), max(v)) for k, v in times.items()}


def c_host(tmp):
    exe = Path(tmp) / "fmu_host"
    cc = shutil.which("gcc") or shutil.which("cc")
    if not cc:
        return None
    subprocess.run([cc, "-O2", "-o", str(exe), str(HERE.parent / "tests" / "fmu_host.c"), "-ldl"], check=True)
    return exe


def run_c_host(exe, path, tmp, inputs, output, values, nsteps):
    import fmpy
    md = fmpy.read_model_description(str(path))
    d = fmpy.extract(str(path), str(Path(tmp) / (Path(path).stem + "_c")))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    so = Path(d) / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    args = [str(exe), str(so), (Path(d) / "resources").as_uri(), md.guid, str(vr[inputs[0]]), str(vr[inputs[1]]),
            str(vr[output]), str(nsteps), str(H), *map(str, values)]
    out = subprocess.run(args, capture_output=True, text=True, timeout=600)
    lines = out.stdout.split("\n")
    if out.returncode != 0 or not lines[-2].startswith("seconds"):
        raise RuntimeError(f"C host failed: {out.stdout} {out.stderr[-2000:]}")
    words = lines[-2].split()
    return float(words[4]), (float(words[2]), float(lines[0].split()[1]))   # steps time, (init time, output)


INIT_CODE = """
import sys, time
t0 = time.perf_counter()
import fmpy
from fmpy.fmi2 import FMU2Slave
md = fmpy.read_model_description(sys.argv[1])
d = fmpy.extract(sys.argv[1])
t1 = time.perf_counter()
s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName='a')
s.instantiate()
s.setupExperiment(startTime=0.0, stopTime=23.0)
s.enterInitializationMode()
s.exitInitializationMode()
t2 = time.perf_counter()
print(t2 - t1)
"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as tmp:
        ours = build_fmu(None, Path(tmp) / "DFAActuator.fmu")
        ours3 = build_fmu(None, Path(tmp) / "DFAActuator3.fmu", fmi=3)
        trivial = build_companion_fmu("load", Path(tmp) / "MassSpringLoad.fmu")
        print(f"load average {os.getloadavg()[0]:.2f}; medians (min-max) of {args.repeats} interleaved rounds")

        print(f"\n1. fmpy.simulate_fmu, standard protocol, {int(T / H)} communication steps of {H * 1e3:g} ms:")
        v_in = square_input(["voltage"], 6000.0, -6000.0, {"force": 5.0})
        x_in = square_input(["stroke"], 1e-3, 0.0, {})
        res = interleaved({
            "trivial FMU (floor)": lambda: simulate_fmu(trivial, x_in),
            "DFAActuator, default start values": lambda: simulate_fmu(ours, v_in),
            "DFAActuator FMI 3.0, default start values": lambda: simulate_fmu(ours3, v_in),
            "DFAActuator, land_on_communication_points": lambda: simulate_fmu(
                ours, v_in, {"land_on_communication_points": True}),
        }, args.repeats)
        floor = res["trivial FMU (floor)"][0]
        for k, (med, lo, hi) in res.items():
            print(f"   {k:44s} {med:7.3f} s ({lo:.3f}-{hi:.3f})  {med / floor:5.2f}x floor  {T / med:6.1f}x real time")
        x_end = simulate_fmu(ours, v_in)[1]["stroke"][-1]
        print(f"   stroke at 23 s {x_end * 1e3:.9f} mm")
        print("   goal: default start values <= 1.5x floor (>= 50x real time)")

        exe = c_host(tmp)
        if exe is None:
            print("\n2./3. C host: no C compiler, skipped")
        else:
            n = int(T / H)
            print(f"\n2. C host (tests/fmu_host.c): {n} x (setReal, doStep, getReal), 1 ms steps:")
            res = interleaved({
                "trivial FMU (floor)": lambda: run_c_host(exe, trivial, tmp, ("stroke", "stroke"), "force",
                                                          (1e-3, 1e-3), n),
                "DFAActuator at 6 kV, 5 N": lambda: run_c_host(exe, ours, tmp, ("voltage", "force"), "stroke",
                                                               (6000.0, 5.0), n),
            }, args.repeats)
            floor = res["trivial FMU (floor)"][0]
            for k, (med, lo, hi) in res.items():
                print(f"   {k:44s} {med / n * 1e6:7.2f} us/step ({lo / n * 1e6:.2f}-{hi / n * 1e6:.2f})  "
                      f"{med / floor:5.2f}x floor")
            print("   goal: <= 1.5x floor")
            print("\n3. instantiate + initialize in a fresh process:")
            inits = [run_c_host(exe, ours, tmp, ("voltage", "force"), "stroke", (6000.0, 5.0), 1)[1][0]
                     for _ in range(args.repeats)]
            print(f"   C host (starts the interpreter)   {statistics.median(inits):.3f} s "
                  f"({min(inits):.3f}-{max(inits):.3f})")
        inits = []
        for _ in range(args.repeats):
            out = subprocess.run([sys.executable, "-c", INIT_CODE, str(ours)], capture_output=True, text=True)
            inits.append(float(out.stdout.split()[-1]))
        print(f"   fmpy (Python host)                {statistics.median(inits):.3f} s ({min(inits):.3f}-{max(inits):.3f})")
        print("   goal: <= 0.5 s")

        chk = os.environ.get("FMUCHECK")
        if chk:
            print("\n4. FMU Compliance Checker: fmuCheck -h 1e-3 -s 23 (zero inputs), total wall time:")
            for name, path in (("trivial FMU", trivial), ("DFAActuator", ours)):
                ts, found = [], ""
                for _ in range(args.repeats):
                    w = time.perf_counter()
                    out = subprocess.run([chk, "-h", "1e-3", "-s", "23", "-o", os.devnull, str(path)],
                                         capture_output=True, text=True)
                    ts.append(time.perf_counter() - w)
                    found = " ".join(line.strip() for line in (out.stdout + out.stderr).splitlines()
                                     if "Warning(s)" in line or "Error(s)" in line)
                print(f"   {name:14s} {statistics.median(ts):.3f} s ({min(ts):.3f}-{max(ts):.3f})  {found}")


if __name__ == "__main__":
    main()
