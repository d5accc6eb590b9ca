"""dfa fmu build (registered under the entry-point group 'dfa.commands', pyproject.toml):
the actuator FMU (FMI 2.0 or 3.0) or, with --system, the SSP system with the drive
electronics and the load. The CLI core (dfa_model.cli) does not import this package."""
from __future__ import annotations

import os

from dfa_model import cli as base


def register(sub) -> None:
    pf = sub.add_parser("fmu", help="FMI 2.0 or 3.0 co-simulation FMU of the model")
    fsub = pf.add_subparsers(dest="fmu_command", parser_class=base._Parser, required=True)
    pb = fsub.add_parser("build", help="build the FMU (parameter start values from a preset or file)")
    base._add_params_flags(pb, "default: vshape-table1")
    pb.add_argument("--out", metavar="FILE.fmu", help="default DFAActuator.fmu (with --system: DFASystem.ssp)")
    pb.add_argument("--system", action="store_true",
                    help="build the actuator + drive electronics + load co-simulation as an SSP file")
    pb.add_argument("--drive", metavar="DRIVE.toml",
                    help="with --system: the drive FMU plays this protocol file, the load weighs its [load] force")
    pb.add_argument("--fmi", type=int, choices=(2, 3), default=2,
                    help="FMI version of the FMU: 2 (default, FMI 2.0) or 3 (FMI 3.0 co-simulation; the same model "
                         "and guarantees)")
    pb.set_defaults(func=cmd_fmu_build)


def cmd_fmu_build(args):
    from . import BuildError, build_fmu    # light: pythonfmu is imported by the build itself
    if args.drive is not None and not args.system:
        raise base.CLIError("--drive: only with --system (the drive FMU is part of the system; the actuator FMU alone "
                       "takes its voltage as an input)")
    if args.fmi == 3 and args.system:
        raise base.CLIError("--fmi 3: not with --system (the SSP system's three FMUs are FMI 2.0 co-simulation FMUs); "
                       "expected --fmi 2, or no --fmi")
    if not args.preset and not args.params:
        args.preset = "vshape-table1"
    p = base._params(args)
    src = args.params or "preset " + args.preset
    kwargs = {}
    if args.system:
        from .ssp import build_system as build
        drive, load = "the drive electronics", "the load"
        if args.drive is not None:
            from dfa_model.io.protocol_file import load as load_protocol
            proto = load_protocol(args.drive)       # a bad file: its own one-line WaveformError (exit 2)
            kwargs = {"drive": proto, "drive_source": os.path.basename(args.drive)}
            drive = f"the drive electronics playing {args.drive} for {proto.duration:g} s"
            if proto.load is not None and isinstance(proto.load.F, (int, float)):   # else build refuses it
                load = f"the load weighing its [load] force ({proto.load.F:g} N)"
        default, what = "DFASystem.ssp", (f"SSP 1.0: the actuator with parameters from {src}, {drive} "
                                          f"and {load}, FMI 2.0 co-simulation FMUs; run it with "
                                          f"fmpy.ssp.simulation.simulate_ssp or OMSimulator")
    else:
        build = build_fmu
        kwargs = {"fmi": args.fmi}
        default, what = "DFAActuator.fmu", (f"FMI {args.fmi}.0 co-simulation; inputs voltage, force; parameters "
                                            f"from {src}")
    out = args.out or default
    base.check_writable("--out", out, (default.rpartition(".")[2],))
    try:
        out = build(p, out, **kwargs)
    except BuildError as exc:
        raise base.CLIError(str(exc)) from None
    print(f"wrote {out} ({what})")
