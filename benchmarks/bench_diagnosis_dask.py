"""Scale-out of `dfa diagnose` (issue 24, item 5): 150 recordings (50 conditions x 3
repetitions of the paper's routine, 23 s at 1 kHz) with a hidden stiffness, diagnosed by
the whole `dfa diagnose --scheduler ADDRESS` process on a dask.distributed LocalCluster
started here (2 workers, 1 thread each: this machine's cores). Streams the diagnosis'
progress lines and prints the wall time, what was found, and the peak memory of the `dfa`
process and of each Dask worker (sampled every 0.5 s with psutil).

    python benchmarks/bench_diagnosis_dask.py [--workers 2] [--N 81] [--keep DIR]

Needs the `dask` extra (dask.distributed) and psutil.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import numpy as np  # noqa: E402

from dfa_model import preset  # noqa: E402
from dfa_model.io.synthetic import Measurement, generate_dataset  # noqa: E402

K_TRUE = 300.0


def conditions():
    """50 conditions: 10 hold voltages of 5-8 kV x 5 loads of 3-7 N."""
    return [(float(V), float(F)) for V in np.linspace(5000, 8000, 10).round(-1) for F in (3.0, 4.0, 5.0, 6.0, 7.0)]


class PeakMemory:
    """Peak resident memory (bytes) of named processes, sampled in a thread."""

    def __init__(self, pids: dict):
        import psutil
        self.procs = {name: psutil.Process(pid) for name, pid in pids.items()}
        self.peak = dict.fromkeys(pids, 0)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def add(self, name, pid):
        import psutil
        self.procs[name], self.peak[name] = psutil.Process(pid), 0

    def _run(self):
        while not self._stop.wait(0.5):
            for name, p in list(self.procs.items()):
                try:
                    self.peak[name] = max(self.peak[name], p.memory_info().rss)
                except Exception:       # the process ended
                    pass

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--N", type=int, default=81)
    ap.add_argument("--keep", help="write the dataset and the report here instead of a temporary folder")
    a = ap.parse_args()
    from distributed import Client, LocalCluster

    root = a.keep or tempfile.mkdtemp(prefix="bench_dask_")
    data, out = os.path.join(root, "data"), os.path.join(root, "report")
    nominal = preset("vshape-table1").replace(N=a.N, rho_l=3e12)
    t0 = time.perf_counter()
    generate_dataset(data, nominal.replace(rho_l=2e12, k=K_TRUE), nominal, conditions(), repetitions=3,
                     measurement=Measurement(noise=2e-6, rho_spread=0.03), seed=11)
    n = sum(f.endswith(".csv") for f in os.listdir(data))
    print(f"dataset: {n} recordings ({len(conditions())} conditions x 3 repetitions, 23 s at 1 kHz), hidden k = "
          f"{K_TRUE:g} N/m, N = {a.N} ({time.perf_counter() - t0:.1f} s to generate)", flush=True)
    with LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        workers = {f"worker {i + 1}": pid for i, pid in enumerate(client.run(os.getpid).values())}
        with PeakMemory(workers) as mem:
            t0 = time.perf_counter()
            proc = subprocess.Popen([sys.executable, "-m", "dfa_model.cli", "diagnose", data, "--out", out,
                                     "--scheduler", cluster.scheduler_address], stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True)
            mem.add("dfa diagnose", proc.pid)
            for line in proc.stdout:
                print("  " + line.rstrip(), flush=True)
            rc = proc.wait()
            wall = time.perf_counter() - t0
    if rc != 0:
        raise SystemExit(f"dfa diagnose failed ({rc})")
    with open(os.path.join(out, "report.json")) as fh:
        report = json.load(fh)
    named = [m["name"] for m in report["missing_physics"]]
    k = next((m["parameters"]["k"]["value"] for m in report["missing_physics"] if m["name"] == "stiffness"), None)
    base, imp = report["fit"]["baseline"], report["fit"]["improved"] or {}
    print(f"\n{n} recordings on a LocalCluster of {a.workers} workers: {wall:.0f} s wall")
    print(f"found: {named}" + (f", k = {k:.4g} N/m (truth {K_TRUE:g})" if k else ""))
    print(f"held-out RMSE: {base['heldout_rmse'] * 1e6:.3g} -> "
          f"{imp.get('heldout_rmse', base['heldout_rmse']) * 1e6:.3g} um")
    print("peak memory (MB): " + ", ".join(f"{name} {v / 2 ** 20:.0f}" for name, v in mem.peak.items()))
    print(f"report in {out}")


if __name__ == "__main__":
    main()
