"""`sandbox run`: check the numbers and outputs, build (or resume) the simulation, then open the window (and its
scene picker) or run headless into a video, pictures, a CSV, dumps and checkpoints."""

from __future__ import annotations

import signal
import sys
from dataclasses import dataclass
from pathlib import Path

from ..api import resumed
from ..config.arguments import (
    GIF_WARN,
    MAX_FPS,
    MAX_FRAMES,
    MAX_SIDE,
    MAX_SUBSTEPS,
    check_count,
    check_file_output,
    check_frames_output,
    check_name_lengths,
    check_picture,
    check_rate,
    distinct_outputs,
    file_stem,
    gif_plan,
    gif_warning,
    outputs_not_inputs,
    outside_numbered,
)
from ..core import runtime
from ..errors import SandboxError
from ..files.cache_sequence import CACHE_SUFFIXES, cache_kind, frame_name, frame_pattern, index_path
from ..files.cache_usd import pxr
from ..files.persist import read_meta, saved_scene
from ..render.segments import PngFolder
from ..render.surface import EXPORT_HINT
from ..render.video import check_output
from ..render.video_codec import CODECS, VideoCodec, choose_codec
from ..simulation import Simulation
from .cli_common import EXIT_STOPPED, _load, stability_warnings
from .controller import open_scene
from .run_outputs import RunOutputs
from .runner import run_headless
from .window import WindowUnavailable, run_window, window_unavailable_reason


def _check_run_numbers(args) -> None:
    """The run's numeric options, before the scene is read."""
    check_count("--frames", args.frames, 1, MAX_FRAMES)
    check_count("--substeps", args.substeps, 1, MAX_SUBSTEPS)
    check_rate("--fps", args.fps, MAX_FPS)
    check_count("--width", args.width, 16, MAX_SIDE)
    check_count("--height", args.height, 16, MAX_SIDE)
    if args.still_frame is not None:
        if args.out is None or Path(args.out).suffix.lower() != ".png":
            raise SandboxError(f"--still-frame {args.still_frame}: expected together with a .png --out")
        check_count("--still-frame", args.still_frame, 0, MAX_FRAMES - 1)
    check_count("--checkpoint-every", args.checkpoint_every, 1, MAX_FRAMES)
    check_count("--dump-every", args.dump_every, 1, MAX_FRAMES)
    if args.checkpoint is not None and args.checkpoint_every is None:
        raise SandboxError(f"--checkpoint {args.checkpoint}: expected together with --checkpoint-every N")
    if args.dump_every is not None and args.dump is None:
        raise SandboxError(f"--dump-every {args.dump_every}: expected together with --dump PATH.extxyz")
    check_count("--cache-every", args.cache_every, 1, MAX_FRAMES)
    check_count("--cache-from", args.cache_from, 0, MAX_FRAMES)
    if (args.cache_every is not None or args.cache_from is not None or args.cache_surface) and args.cache is None:
        raise SandboxError(
            "--cache-every/--cache-from/--cache-surface: expected together with --cache PATH.usd|.vtp|.ply"
        )
    if args.no_video and (args.out is not None or args.still_frame is not None):
        raise SandboxError("--no-video with --out or --still-frame: expected pictures or none, not both")
    if args.resume is not None and args.set:
        raise SandboxError("--set with --resume: a resumed run continues the saved scene; expected no --set")


def _check_run_outputs(args, out: str | None, scene) -> None:
    """Every file the run will write: a known kind, a writable folder (created if missing), no two the same, none a
    file the run reads."""
    outputs = {
        "--out": out,
        "--stats": args.stats,
        "--screenshot": args.screenshot,
        "--record": args.record,
        "--dump": args.dump,
        "--checkpoint": args.checkpoint,
        "--cache": index_path(Path(args.cache)) if args.cache else None,
    }
    distinct_outputs(outputs)
    numbered = {}  # the options that write numbered files: where, and the pattern of their names
    if args.cache is not None:
        numbered["--cache"] = (outputs["--cache"].parent, frame_pattern(outputs["--cache"]))
    if out is not None and not Path(out).suffix:
        numbered["--out"] = (Path(out), PngFolder.FRAME)
    outside_numbered(outputs, numbered)
    for option, path in outputs.items():  # all before any folder is made for one of them
        if path is not None:
            check_name_lengths(option, path)
    inputs = {"--resume": args.resume, "scene": scene.path}
    masks = [thing.mask for thing in (*scene.bodies, *scene.emitters) if thing.mask]
    inputs.update({f"mask {Path(m).name}": m for m in masks})
    outputs_not_inputs(outputs, inputs)
    if args.dump is not None:
        check_file_output("--dump", args.dump, (".extxyz", ".xyz"))
    if args.cache is not None:
        check_cache_output(args.cache, args.cache_surface)
    if args.checkpoint is not None:
        check_file_output("--checkpoint", args.checkpoint, (".npz",))
    if out is not None:
        check_frames_output("--out", out)
        check_output(out)  # the packages its kind needs
    if args.stats is not None:
        check_file_output("--stats", args.stats)
    if args.screenshot is not None:
        check_file_output("--screenshot", args.screenshot, (".png",))
    if args.record is not None:
        check_file_output("--record", args.record, (".mp4",))
        check_output(args.record)


def check_cache_output(path: str, surface: bool) -> None:
    """--cache: a known kind, its packages installed, a writable folder; the frame files' names fit (and, for USD,
    hold no backslash, which USD's asset paths read as a folder separator)."""
    kind = cache_kind(Path(path))
    check_file_output("--cache", path, CACHE_SUFFIXES)
    index = index_path(Path(path))
    check_name_lengths("--cache", index.with_name(frame_name(index, MAX_FRAMES, surface=True)))
    if kind == "usd":
        if "\\" in Path(path).name:
            raise SandboxError(
                f"--cache {path}: a backslash in a USD cache's name, which USD reads as a folder separator (its frames "
                "would resolve to nothing); expected a name without one"
            )
        pxr()
    if surface:
        try:
            import pysplashsurf  # noqa: F401
        except ImportError:
            raise SandboxError(f"--cache-surface: surfaces need pysplashsurf; {EXPORT_HINT}") from None


def _resumed_scene(args):
    """The scene a --resume state file holds (SCENE must name it), the frame it was saved at, and the file's meta."""

    meta = read_meta(args.resume)
    named = Path(args.scene).stem
    if named not in (meta["scene_name"], Path(meta["scene_path"]).stem):
        raise SandboxError(
            f"--resume {args.resume}: saved from scene {meta['scene_name']!r}; expected SCENE to name it"
        )
    return saved_scene(meta, args.resume), int(meta["frame"]), meta


@dataclass
class RunPlan:
    """What `sandbox run` will do, decided from its arguments before anything is built: the scene (resumed or
    loaded), the frames (from `first_frame`, of the saved state's meta `saved`), window or headless, the output and
    its picture size, frame rate and frame stride (a GIF keeps every `every`-th frame), and a video's encoding."""

    scene: object
    first_frame: int
    saved: dict | None
    frames: int
    headless: bool
    out: str | None
    width: int
    height: int
    fps: float
    every: int = 1
    codec: VideoCodec = VideoCodec()


def cmd_run(args) -> int:
    """`sandbox run`: the scene in a window where one can open, else headless into its outputs."""
    plan = _plan_run(args)
    runtime.require(args.arch, plan.scene.world.precision)
    _check_run_outputs(args, plan.out, plan.scene)
    if args.resume:
        sim = resumed(args.resume, args.arch, plan.saved, plan.scene)
    else:
        sim = Simulation(plan.scene, arch=args.arch)
    for line in stability_warnings(sim):
        print(f"warning: {line}; expect the blow-up guard to stop the run", file=sys.stderr)
    if not plan.headless:
        try:
            return _in_window(args, sim)
        except WindowUnavailable as exc:
            print(f"{exc}: running headless", file=sys.stderr)
            plan.out = plan.out or f"out/{file_stem(plan.scene.name)}.mp4"
            check_picture(plan.width, plan.height, plan.out)
            _check_run_outputs(args, plan.out, plan.scene)
    return _headless(args, sim, plan)


def _plan_run(args) -> RunPlan:
    """The run's plan, every argument checked against the scene (SandboxError with one line)."""
    _check_run_numbers(args)
    scene, first_frame, saved_meta = _resumed_scene(args) if args.resume else (_load(args), 0, None)
    frames = args.frames or scene.render.frames
    finishing = bool(saved_meta and saved_meta.get("outputs")) and not args.restart_outputs
    if frames < first_frame or (frames == first_frame and not finishing):
        raise SandboxError(f"--frames {frames}: the state was saved at frame {first_frame}; expected more frames")
    if args.checkpoint_every and args.checkpoint is None:
        args.checkpoint = f"out/{file_stem(scene.name)}.state.npz"
    if args.still_frame is not None:
        check_count("--still-frame", args.still_frame, 0, frames - 1)
    if args.cache_from is not None and args.cache_from > frames:
        raise SandboxError(f"--cache-from {args.cache_from}: the run ends at frame {frames}; expected 0 to {frames}")
    headless = args.headless or args.no_video
    if not headless and (args.dump or args.checkpoint_every or args.cache):
        print("--dump, --cache and --checkpoint-every write from headless runs: running headless", file=sys.stderr)
        headless = True
    if not headless:
        reason = window_unavailable_reason()
        if reason:
            headless = True
            print(f"{reason}: running headless", file=sys.stderr)
    out = args.out
    if headless and out is None and not args.no_video:
        out = f"out/{file_stem(scene.name)}.mp4"
        try:
            check_output(out)
        except SandboxError:
            out = f"out/{file_stem(scene.name)}"
            print(f"imageio-ffmpeg is not installed: writing PNG frames to {out}/ instead of an MP4", file=sys.stderr)
    plan = RunPlan(
        scene, first_frame, saved_meta, frames, headless, out,
        args.width or scene.render.width, args.height or scene.render.height, args.fps or scene.render.fps,
    )  # fmt: skip
    suffix = Path(out).suffix if out is not None and headless else None
    plan.codec = choose_codec(suffix, args.codec, args.quality, args.lossless, args.alpha)
    if out is not None and Path(out).suffix.lower() == ".gif":
        sized = args.width is not None or args.height is not None
        # planned for the whole run, so that a resumed run keeps the frames the uninterrupted one keeps
        plan.width, plan.height, plan.every, size = gif_plan(plan.width, plan.height, plan.fps, frames, sized)
        if size > GIF_WARN:
            print(f"warning: {gif_warning(out, plan.width, plan.height, plan.fps / plan.every, size)}", file=sys.stderr)
    check_picture(plan.width, plan.height, out)
    return plan


def _in_window(args, sim) -> int:
    """The window, then each scene its picker opens, in this process."""
    scene = sim.scene
    window = (args.width or scene.render.width, args.height or scene.render.height)
    ran = run_window(
        sim, frames=args.frames, screenshot=args.screenshot, substeps=args.substeps, record=args.record, size=window
    )
    while ran.next_scene:  # the panel's scene picker: the same process opens the next scene
        sim = open_scene(ran.next_scene, args.arch)
        ran = run_window(sim, size=ran.size)
    return 0


def _headless(args, sim, plan: RunPlan) -> int:
    """The frames written to the run's outputs; the exit status (EXIT_STOPPED after a blow-up, 128 + the signal
    after an interruption)."""
    scene, first_frame, frames, out = plan.scene, plan.first_frame, plan.frames, plan.out
    outputs = RunOutputs(
        sim,
        out,
        args.stats,
        size=(plan.width, plan.height, plan.fps),
        every=plan.every,
        still_frame=args.still_frame,
        dump=args.dump,
        dump_every=args.dump_every or 1,
        checkpoint=args.checkpoint,
        checkpoint_every=args.checkpoint_every,
        resume=(Path(args.resume), plan.saved) if args.resume else None,
        restart=args.restart_outputs,
        cache=args.cache,
        cache_every=args.cache_every or 1,
        cache_surface=args.cache_surface,
        cache_from=args.cache_from or 0,
        codec=plan.codec,
    )
    start = f"frames {first_frame + 1} to {frames}" if first_frame else f"{frames} frames"
    if frames == first_frame:
        start = f"no frames (the outputs of the {frames} saved are finished)"
    print(
        f"{scene.name}: {sim.model.built.count} particles, {sim.model.built.spring_count} springs, {start} x "
        f"{args.substeps or scene.world.substeps} steps on {sim.arch} -> {out or _written(args)}",
        file=sys.stderr,
    )
    result = run_headless(
        sim,
        frames - first_frame,
        args.substeps,
        out,
        width=plan.width,
        height=plan.height,
        fps=args.fps,
        progress=not args.quiet,
        first_frame=first_frame,
        outputs=outputs,
        overlays=not args.no_overlays,
    )
    return _said(args, sim, plan, result)


def _written(args) -> str:
    """What a run without pictures (--no-video) writes, in words."""
    named = [p for p in (args.stats, args.dump, args.cache, args.checkpoint) if p]
    return ", ".join(str(p) for p in named) or "no file (--no-video and nothing else asked for)"


def _said(args, sim, plan: RunPlan, result) -> int:
    """What a headless run says when it ends, and its exit status."""
    out, first_frame = plan.out, plan.first_frame
    if result.stopped:
        print(f"error: the blow-up guard stopped the run: {result.stopped}", file=sys.stderr)
        if result.frames and out:
            kept = f"kept the {result.frames} frames before it in {out}"
            kept += f" and their measurements in {args.stats}" if args.stats else ""
        else:
            kept = "no frame was drawn, so no picture was written" + (
                f"; {args.stats} holds the header only" if args.stats else ""
            )
        print(kept, file=sys.stderr)
        return EXIT_STOPPED
    last = result.last
    count = (
        f"{first_frame + result.frames} frames, {result.frames} of them now"
        if first_frame
        else f"{result.frames} frames"
    )
    summary = f"wrote {out or _written(args)} ({count}, t = {result.sim_time:.3g}, {result.wall_seconds:.1f} s wall)"
    if last is not None and sim.terms.heat is not None:
        summary += f"; molten fraction {last.molten_fraction:.2f}, broken springs {last.broken_springs}"
    if not result.kept:
        print(summary, file=sys.stderr)
    if result.interrupted:
        name = signal.Signals(result.signal).name if result.signal else "SIGINT"
        if result.kept:
            again = f"--resume {args.checkpoint} continues them" if args.checkpoint else "they hold the frames done"
            names = ", ".join(p.name for p in result.kept)
            print(f"stopped by {name}, which stopped ffmpeg too: the outputs are kept under partial names ({names}); "
                  f"{again}", file=sys.stderr)  # fmt: skip
        else:
            print(f"stopped by {name}: the files written so far are complete and valid", file=sys.stderr)
        return 128 + (result.signal or 2)
    return 0


def film_arguments(run) -> None:
    """`sandbox run`'s arguments for film work: the video's encoding (render/video_codec.py) and the particle cache
    (docs/export.md), each an argument group of its own in --help."""
    group = run.add_argument_group("video for editors (an .mp4 or .mov --out)")
    group.add_argument(
        "--codec",
        choices=CODECS,
        help="the video's codec: h264 (the .mp4 default) or h265 in .mp4 or .mov; prores (the .mov default) or png "
        "in .mov (docs/export.md, Video for editors)",
    )
    group.add_argument(
        "--quality", type=int, metavar="Q", help="h264/h265: the CRF, 0..51, lower is better (15); prores: 0..3 (3 HQ)"
    )
    group.add_argument("--lossless", action="store_true", help="h264/h265 at no loss (4:4:4); png is always lossless")
    group.add_argument("--alpha", action="store_true", help="prores (4444) or png in .mov: the background transparent")
    group = run.add_argument_group("particle caches for Blender, Houdini and ParaView")
    group.add_argument(
        "--cache",
        metavar="PATH",
        help="write a particle cache for Blender, Houdini, ParaView: PATH.usd (.usda/.usdc), PATH.vtp (with a .pvd) "
        "or PATH.ply, one file per cached frame (docs/export.md)",
    )
    group.add_argument("--cache-every", type=int, metavar="N", help="with --cache: every N frames (default 1)")
    group.add_argument(
        "--cache-from",
        type=int,
        metavar="FRAME",
        help="with --cache: the first frame cached (default 0, the state the run starts from)",
    )
    group.add_argument(
        "--cache-surface", action="store_true", help="with --cache: a surface mesh of the bodies and melts too"
    )
