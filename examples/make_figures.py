"""Regenerate every example figure in one command: the paper's Figs. 2, 3, 4 and 9, the
Peano-HASEL convergence in N, the FMU co-simulation, a stroke-holding loop in python-control on
the sampled surrogate, and the `dfa simulate --plot` figure
of the README's quick start.

    python examples/make_figures.py [--quick] [--out DIR] [--only NAME ...]

Each example runs in its own process (DFA_EXAMPLES_OUT=DIR, default examples/figures/).
--quick passes the examples' reduced grids (seconds; the smoke test's mode, whose numbers
are not the README's). Exit status 1 if any example fails. About 2 minutes in full on one
core, most of it the paper scheme at N = 1500 and 3001 (Fig. 2).
"""
import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
# name: (argv after the interpreter, figures it writes)
EXAMPLES = {
    "fig2": (["fig2_convergence.py"], ["fig2_convergence.png"]),
    "fig3": (["fig3_statics.py"], ["fig3_statics.png"]),
    "fig4": (["fig4_dynamics.py"], ["fig4_dynamics.png"]),
    "fig9": (["fig9_peano.py"], ["fig9_peano.png"]),
    "peano_convergence": (["peano_convergence.py"], ["peano_convergence.png"]),
    "fmu": (["fmu_cosimulation.py"], ["fmu_cosimulation.png"]),
    "python_control_loop": (["python_control_loop.py"], ["python_control_loop.png"]),
    "cli": (["-m", "dfa_model.cli", "simulate", "--preset", "vshape-table1", "--voltage", "6000", "--force", "5",
             "--reset", "3", "--duration", "20", "--out", "{out}/baseline.csv", "--plot", "{out}/baseline.png"],
            ["baseline.png"]),
}


def run(name, out, quick):
    argv, pngs = EXAMPLES[name]
    argv = [a.format(out=out) for a in argv]
    if name == "cli":
        if quick:
            argv[argv.index("--duration") + 1] = "2"
    else:
        argv = [str(HERE / argv[0])] + argv[1:] + (["--quick"] if quick else [])
    env = dict(os.environ, DFA_EXAMPLES_OUT=str(out), MPLBACKEND="Agg")
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable] + argv, cwd=HERE, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    text = proc.stdout + proc.stderr
    missing = [p for p in pngs if not (Path(out) / p).is_file()]
    if name == "cli" and not missing:
        from _common import compact_png        # the library writes full-colour PNGs; the examples' are compact
        compact_png(Path(out) / pngs[0])
    ok = proc.returncode == 0 and not missing and "failed:" not in proc.stdout
    print(f"{'ok ' if ok else 'FAILED'} {name:18s} {wall:6.1f} s  " + ", ".join(str(Path(out) / p) for p in pngs))
    if not ok:
        print(text[-3000:] + (f"\nmissing: {missing}" if missing else ""))
    return ok, proc.stdout


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced grids (seconds)")
    ap.add_argument("--out", default=str(HERE / "figures"), help="output folder (default: examples/figures/)")
    ap.add_argument("--only", nargs="+", choices=list(EXAMPLES), help="run these only")
    args = ap.parse_args(argv)
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    results = {name: run(name, out, args.quick) for name in (args.only or EXAMPLES)}
    return 0 if all(ok for ok, _ in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
