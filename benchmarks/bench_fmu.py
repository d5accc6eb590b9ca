"""FMU benchmark: the Table 1 standard protocol (3 s reset at 30 Hz, then 20 s DC at
6 kV, 5 N) through fmpy at a 1 ms communication step (23 000 doSteps). Goal: >= 100x
faster than real time (<= 0.23 s). Prints medians over repeats, for both stepping
modes, through fmpy's FMU2Slave API and with preallocated ctypes arrays (fmpy's bound
FMI functions), and the direct Stepper (no FMU) measured in the same run: the
difference is the FMU's per-step overhead.

    taskset -c 1 python benchmarks/bench_fmu.py [--repeats 5]
"""
import argparse
import statistics
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from dfa_model import PhysicsWarning, preset
from dfa_model.stepper import Stepper
from fmu import build_fmu

H, N = 1e-3, 23000
OUTS = ("stroke", "velocity", "zipped_length", "zipping_angle", "electrostatic_force", "current", "capacitance",
        "stored_energy")


def voltage():
    k = np.arange(N)
    return np.where(k < 3000, np.where((k // 17) % 2 == 0, 6000.0, -6000.0), 6000.0).tolist()


def direct(exact):
    V = voltage()
    st = Stepper(preset("vshape-table1"), v_nominal=6000.0, t_end=N * H, exact=exact)
    w = time.perf_counter()
    for k in range(N):
        st.step(H, V[k], 5.0)
        st.out.tolist()
    return time.perf_counter() - w, st.out[0]


def through_fmpy(path, exact, raw):
    import fmpy
    from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2ValueReference
    md = fmpy.read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path)),
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    s.instantiate()
    s.setupExperiment(startTime=0.0, stopTime=N * H)
    s.enterInitializationMode()
    s.setBoolean([vr["land_on_communication_points"]], [exact])
    s.exitInitializationMode()
    V = voltage()
    outs = [vr[o] for o in OUTS]
    vin = [vr["voltage"], vr["force"]]
    w = time.perf_counter()
    if raw:
        c = s.component
        a_in, v_in = (fmi2ValueReference * 2)(*vin), (fmi2Real * 2)()
        a_out, v_out = (fmi2ValueReference * 8)(*outs), (fmi2Real * 8)()
        v_in[1] = 5.0
        for k in range(N):
            v_in[0] = V[k]
            s.fmi2SetReal(c, a_in, 2, v_in)
            s.fmi2DoStep(c, k * H, H, 1)
            s.fmi2GetReal(c, a_out, 8, v_out)
        x = v_out[0]
    else:
        for k in range(N):
            s.setReal(vin, [V[k], 5.0])
            s.doStep(k * H, H)
            x = s.getReal(outs)[0]
    wall = time.perf_counter() - w
    s.terminate()
    s.freeInstance()
    return wall, x


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    warnings.simplefilter("ignore", PhysicsWarning)
    with tempfile.TemporaryDirectory() as tmp:
        path = build_fmu(None, Path(tmp) / "DFAActuator.fmu")
        print(f"standard protocol through the FMU: {N} communication steps of {H * 1e3:g} ms (23 s); "
              f"medians of {args.repeats}")
        for exact in (True, False):
            mode = "land_on_communication_points=" + ("true " if exact else "false")
            rows = [("direct Stepper (no FMU)", lambda: direct(exact)),
                    ("fmpy FMU2Slave API", lambda: through_fmpy(path, exact, False)),
                    ("fmpy, preallocated ctypes", lambda: through_fmpy(path, exact, True))]
            base = None
            for label, fn in rows:
                fn()                                              # warm-up (JIT cache, imports)
                res = [fn() for _ in range(args.repeats)]
                med = statistics.median(r[0] for r in res)
                base = base or med
                print(f"  {mode}  {label:28s} {med:7.3f} s  {23.0 / med:6.1f}x real time  "
                      f"{med / N * 1e6:6.2f} us/step  (+{(med - base) / N * 1e6:5.2f} us/step over direct)  "
                      f"stroke(23 s) = {res[0][1] * 1e3:.6f} mm")
        print("goal: <= 0.230 s (>= 100x real time)")


if __name__ == "__main__":
    main()
