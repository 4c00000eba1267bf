"""`sandbox study`: the integrator study, the phase-change validation and the molecular model's coexistence study and
heating curve."""

from __future__ import annotations

import sys

from ..config.arguments import check_folder_output, check_names, check_pool_arguments, pool_arguments
from ..errors import SandboxError
from ..research.coexistence import parse_temperatures, run_coexistence
from ..research.heating_curve import run_heating_study
from ..research.phase_study import run_phase_study
from ..research.study import INTEGRATORS, PROBLEMS, run_study
from ..research.triple_point import run_triple_study
from .cli_common import EXIT_INTERRUPTED


def _check_modes(args) -> None:
    """One study a run, and only the options that study reads: the Dask options reach the integrator and
    coexistence studies (the heating and phase studies run in this process), --temperatures and --dim the
    coexistence study, --integrators and --problems the integrator study."""
    modes = [flag for flag in ("phase", "coexistence", "heating", "triple") if getattr(args, flag)]
    if len(modes) > 1:
        raise SandboxError(f"--{' and --'.join(modes)}: one study a run; expected one of them")
    mode = modes[0] if modes else "integrators"
    pool = [o for o, v in (("--scheduler", args.scheduler != "auto"), ("--workers", args.workers),
                           ("--threads", args.threads)) if v]  # fmt: skip
    temperatures = ["--temperatures"] * (args.temperatures is not None)
    # the heating, phase and triple-point studies run in this process and at their own temperatures
    unread = {"integrators": temperatures, "coexistence": []}.get(mode, pool + temperatures)
    if mode != "integrators":
        unread += [o for o, v in (("--integrators", args.integrators), ("--problems", args.problems)) if v]
    if mode != "coexistence" and args.dim != 3:
        unread.append("--dim")
    if unread:
        study = f"--{mode}" if modes else "the integrator study"
        raise SandboxError(f"{', '.join(unread)} with {study}: it does not read them; expected them left out")


def cmd_study(args) -> int:
    check_pool_arguments(args)
    _check_modes(args)
    integrators = check_names("--integrators", args.integrators, INTEGRATORS)
    problems = check_names("--problems", args.problems, PROBLEMS)
    temperatures = parse_temperatures(args.temperatures, args.dim) if args.coexistence else None
    out = check_folder_output("--out", args.out)
    log = lambda line: print(line, file=sys.stderr)  # noqa: E731
    if args.coexistence:
        run_coexistence(out, temperatures, args.quick, log, args.dim, args.scheduler, args.workers, args.threads)
        print(f"wrote {out}/coexistence.md and coexistence.csv")
        return 0
    validation = {  # flag: (runner, what it writes, the plot it adds where matplotlib is installed, if any)
        "heating": (run_heating_study, "heating_curve.md and heating_curve.csv", "heating_curve.png"),
        "phase": (run_phase_study, "phase.md, stefan.csv, heating_curve.csv", "stefan.png"),
        "triple": (run_triple_study, "triple_point.md and triple_point.csv", None),
    }
    for flag, (runner, files, plot) in validation.items():
        if getattr(args, flag):
            runner(out, quick=args.quick, log=log)
            print(f"wrote {out}/{files}" + (" and plots" if plot and (out / plot).exists() else ""))
            return 0
    try:
        run_study(
            out,
            quick=args.quick,
            integrators=integrators,
            problems_to_run=problems,
            scheduler=args.scheduler,
            workers=args.workers,
            threads=args.threads,
            log=lambda line: print(line, file=sys.stderr),
        )
    except KeyboardInterrupt:
        print("interrupted: the study writes its files only when every task is done", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(
        f"wrote {out}/report.md, runs.csv, stability.csv, stiff.csv"
        + ("" if not list(out.glob("*.png")) else " and plots")
    )
    return 0


def study_arguments(sub) -> None:
    """`sandbox study`'s arguments."""
    study = sub.add_parser("study", help="integrators: error against run time, convergence orders, stability")
    study.add_argument("--out", required=True, help="folder for runs.csv, report.md and plots")
    study.add_argument("--quick", action="store_true", help="reduced ladders (under a minute)")
    study.add_argument(
        "--phase", action="store_true", help="instead: phase change (Stefan problem, heating curve) validation"
    )
    study.add_argument(
        "--coexistence",
        action="store_true",
        help="instead: liquid-vapour coexistence of the molecular model (3D slabs) beside NIST's Lennard-Jones tables",
    )
    study.add_argument(
        "--heating",
        action="store_true",
        help="instead: the molecular model's heating curve (a crystal under a lid heated at constant power, two lid "
        "pressures: about 5 minutes)",
    )
    study.add_argument(
        "--triple",
        action="store_true",
        help="instead: the molecular model's triple point by direct three-phase coexistence (3D; about 3 minutes)",
    )
    study.add_argument(
        "--temperatures",
        help="with --coexistence: comma-separated reduced temperatures (default 0.7,0.75,0.8,0.85 in 3D, "
        "0.3,0.33,0.36,0.39 in 2D)",
    )
    study.add_argument(
        "--dim", type=int, choices=(2, 3), default=3, help="with --coexistence: slabs in 2 or 3 dimensions (default 3)"
    )
    study.add_argument("--integrators", help="comma-separated integrators to study (default: all)")
    study.add_argument("--problems", help="comma-separated problems to run (default: all)")
    pool_arguments(study, "task")
    study.set_defaults(func=cmd_study)
