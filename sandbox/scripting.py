"""What the Simulation offers scripts and notebooks, as functions of a simulation: run frames into a table, read the
particles by id, draw pictures and movies, export extended-XYZ frames, and its memory by part. Each only combines
what the model, state, terms and renderer provide."""

from __future__ import annotations

import dataclasses
import time
import warnings
from pathlib import Path

import numpy as np

from .config.arguments import MAX_SIDE
from .config.schema import parse_table
from .errors import SandboxError
from .files.extxyz import append_frame, frame_text
from .files.table import FrameTable
from .physics.phase import ENTHALPY_LAW, temperature_np
from .render.notebook import Movie, png_html
from .render.raster import Renderer
from .world_view import one_world


def run_frames(sim, frames: int, progress: bool = False, after=None) -> FrameTable:
    """Advance and measure `frames` frames (the scene's substeps each) into a FrameTable, one row per frame,
    numbered on from the frames already run, calling after(k) after frame k (0-based). `progress`: a progress bar
    (tqdm; in Jupyter, its notebook bar)."""
    if not isinstance(frames, int) or frames < 0:
        raise ValueError(f"frames must be a whole number >= 0, got {frames!r}")
    table = FrameTable()
    bar = _progress_bar(frames, sim.scene.name) if progress else None
    try:
        for k in range(frames):
            t0 = time.perf_counter()
            taken = sim.advance_frame()
            table.append(sim.frames_done, sim.stats(), (time.perf_counter() - t0) / taken)
            if after is not None:
                after(k)
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return table


def movie(sim, frames: int, width: int = 480, height: int = 270, every: int = 1, progress: bool = False) -> Movie:
    """Run `frames` frames, drawing every `every`-th as a `width` x `height` picture (even sizes, for MP4); returns
    a notebook Movie (it plays inline in Jupyter; .save(path) writes it; .table holds the run's measurements)."""
    one_world(sim, "a movie")
    if width % 2 or height % 2:
        raise ValueError(f"a movie needs an even width and height, got {width}x{height}")
    pictures: list[np.ndarray] = []

    def draw(k: int) -> None:
        if k % every == every - 1:
            pictures.append(picture(sim, width, height))

    table = run_frames(sim, frames, progress, draw)
    return Movie(pictures, sim.scene.render.fps / every, table, sim.scene.name)


def picture(sim, width: int | None = None, height: int | None = None, **render) -> np.ndarray:
    """The scene drawn now as a new (height, width, 3) uint8 RGB array, top row first. `width`, `height`: pixels
    (default: the scene's render size); `render`: [render] settings to change for this picture (color_by="temperature",
    legend=False, ...). The renderer is kept between calls of the same settings."""
    one_world(sim, "a picture")
    cfg = sim.scene.render
    if render:  # checked as the scene's [render] table is: a SceneError naming the setting
        given = {k: list(v) if isinstance(v, tuple) else v for k, v in render.items()}
        checked = parse_table(type(cfg), given, "picture()", "render")
        cfg = dataclasses.replace(cfg, **{k: getattr(checked, k) for k in render})
    for name, side in (("width", width), ("height", height)):
        if side is not None and (isinstance(side, bool) or not isinstance(side, int) or not 16 <= side <= MAX_SIDE):
            raise SandboxError(f"picture(): {name} {side!r}; expected a whole number of pixels from 16 to {MAX_SIDE}")
    size = (width or cfg.width, height or cfg.height)
    key = (size, cfg)
    cached = getattr(sim, "_picture_renderer", None)
    if cached is None or cached[0] != key:
        if cached is not None:
            sim.state.drop(cached[1].tails)
        renderer = Renderer(sim.model, sim.state, size[0], size[1], cfg, output="picture")
        sim.state.carry(renderer.tails)
        cached = sim._picture_renderer = (key, renderer)
    if cached[1].plots():
        cached[1].record(sim.stats())  # the charts and the phase diagram's dot show this moment
    return np.array(cached[1].frame(), copy=True)


def html(sim) -> str:
    """Jupyter's view of a simulation: its picture now, and where it stands (of many worlds: where it stands)."""
    n = sim.state.live_count()
    if sim.worlds > 1:
        counts = [sim.state.particles.block(k)[1] for k in range(sim.live_worlds)]
        each = f"{counts[0]:,}" if len(set(counts)) == 1 else f"{min(counts):,} to {max(counts):,}"
        return f"<p>{sim.scene.name}: {sim.live_worlds} worlds of {each} particles, t = {sim.time:.3g} s</p>"
    caption = f"{sim.scene.name}: {n:,} particles, t = {sim.time:.3g} s after {sim.frames_done} frames"
    return png_html(picture(sim, 480, 270), caption)


def particle_table(sim) -> dict[str, np.ndarray]:
    """What `sim.particles()` returns (sim.particles is also the particle fields, sim.particles.x and so on): the
    live particles, sorted by their stable id (the same particle keeps its id while storage is reordered, and emitted
    or spawned particles get new ones). Keys and shapes, N particles, D = scene.dim: `id` (N,) int; `position` (N, D)
    length; `velocity` (N, D) length/time; `temperature` (N,) degrees (NaN without heat); `melt_fraction` (N,) in
    [0, 1]; `material` (N,) index into `material_names`; `body` (N,) index into scene.groups (bodies, then emitters,
    then the spawn tool). Each call returns new arrays; a RuntimeWarning says when the state is past a blow-up."""
    one_world(sim, "the particle table")
    sim.check_alive()
    if sim.broken:
        warnings.warn(f"the state is past a blow-up ({sim.broken}); its values are not physical", stacklevel=3)
    p = sim.particles
    n = sim.state.live_count()
    ids = p.ident.to_numpy()[:n]
    order = np.argsort(ids, kind="stable")
    return {
        "id": ids[order].astype(np.int64),
        "position": p.x.to_numpy()[:n][order],
        "velocity": p.v.to_numpy()[:n][order],
        "temperature": p.T.to_numpy()[:n][order] if p.heat else np.full(n, np.nan),
        "melt_fraction": melt_fractions(sim)[order],
        "material": p.material.to_numpy()[:n][order].astype(np.int64),
        "body": p.group.to_numpy()[:n][order].astype(np.int64),
    }


def melt_fractions(sim) -> np.ndarray:
    """Melt fraction in [0, 1] of the live particles, (N,) (0 without heat)."""
    p = sim.particles
    rows = sim.state.live_rows()
    if not p.heat:
        return np.zeros(rows.stop if isinstance(rows, slice) else len(rows))
    ids = p.material.to_numpy()[rows]
    law = [sim.model.column(name, ids) for name in ENTHALPY_LAW]
    return temperature_np(p.h.to_numpy()[rows], *law)[1]


def spring_pairs(sim) -> np.ndarray:
    """The live springs as (M, 2) particle ids."""
    s = sim.state.springs
    span = int(s.span[None])
    i, j, alive = s.i.to_numpy()[:span], s.j.to_numpy()[:span], s.alive.to_numpy()[:span]
    ids = sim.particles.ident.to_numpy()
    live = alive != 0
    return np.stack([ids[i[live]], ids[j[live]]], axis=1)


def extxyz_text(sim, bonds: bool = False) -> str:
    """The particles as one extended-XYZ frame (ASE, OVITO); `bonds`: the live springs as a Bonds key of particle-id
    pairs."""
    one_world(sim, "an extended-XYZ frame")
    world = sim.scene.world
    pairs = spring_pairs(sim) if bonds and sim.state.springs is not None else None
    return frame_text(
        particle_table(sim), sim.material_names, world.lo, world.hi, world.periodic, sim.time, sim.step_count, pairs
    )


def write_extxyz(sim, path: str | Path, append: bool = True, bonds: bool = False) -> None:
    """Write the particles as one extended-XYZ frame to `path`: appended to it (`append`), or replacing it."""
    path = Path(path)
    if not append:
        path.unlink(missing_ok=True)
    append_frame(path, extxyz_text(sim, bonds))


def memory_bytes(sim) -> dict[str, int]:
    """Bytes of field memory by part: the particles, springs, neighbourhood (grid, lists, sort scratch), half-list
    buffers."""
    real = 8 if sim.scene.world.precision == "f64" else 4
    model, rates = sim.model, sim.rates
    out = {"particles": sim.particles.nbytes() + model.capacity * sim.dim * real}  # + the rates' forces
    if sim.state.springs is not None:
        out["springs"] = sim.state.springs.nbytes(real)
    if sim.hood is not None:
        out.update(sim.hood.nbytes(model.capacity, sim.dim))
    if rates.half:
        out["half-list buffers"] = (
            rates.n_pair_rows * model.capacity * (sim.dim + (1 if rates.has_heat_rate else 0)) * real
        )
    return out


def _progress_bar(total: int, label: str):
    """tqdm's bar (its notebook widget where one runs), or None without tqdm."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="frame", desc=label)
