"""The simulation from a script or a notebook: run frames into a table, read particles by id, draw pictures, save
and export. A mixin of Simulation (the facade): each method here only combines what the other parts provide."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .files.table import FrameTable


class Scripting:
    """Simulation's script-facing methods."""

    def run(self, frames: int, progress: bool = False) -> FrameTable:
        """Advance `frames` frames (the scene's substeps each) and return their measurements, one row per frame,
        numbered on from the frames already run. `progress`: a progress bar (tqdm; in Jupyter, its notebook bar).
        Raises SimulationError when the blow-up guard stops the run (the frames before it have been run)."""
        return self._run_frames(frames, progress)

    def movie(self, frames: int, width: int = 480, height: int = 270, every: int = 1, progress: bool = False):
        """Run `frames` frames, drawing every `every`-th as a `width` x `height` picture (even sizes, for MP4);
        returns a notebook.Movie (it plays inline in Jupyter; .save(path) writes it; .table holds the run's
        measurements, as run() returns them)."""
        from .render.notebook import Movie

        if width % 2 or height % 2:
            raise ValueError(f"a movie needs an even width and height, got {width}x{height}")
        pictures: list[np.ndarray] = []

        def draw(k: int) -> None:
            if k % every == every - 1:
                pictures.append(self.picture(width, height))

        table = self._run_frames(frames, progress, draw)
        return Movie(pictures, self.scene.render.fps / every, table, self.scene.name)

    def _run_frames(self, frames: int, progress: bool, after=None) -> FrameTable:
        """Advance and measure `frames` frames into a FrameTable, calling after(k) after frame k (0-based)."""
        if not isinstance(frames, int) or frames < 0:
            raise ValueError(f"frames must be a whole number >= 0, got {frames!r}")
        table = FrameTable()
        bar = _progress_bar(frames, self.scene.name) if progress else None
        try:
            for k in range(frames):
                t0 = time.perf_counter()
                taken = self.advance_frame()
                table.append(self.frames_done, self.stats(), (time.perf_counter() - t0) / taken)
                if after is not None:
                    after(k)
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        return table

    def _repr_html_(self) -> str:
        """Jupyter's view of a simulation: its picture now, and where it stands."""
        from .render.notebook import png_html

        n = int(self.particles.n[None])
        caption = f"{self.scene.name}: {n:,} particles, t = {self.time:.3g} s after {self.frames_done} frames"
        return png_html(self.picture(480, 270), caption)

    def particle_table(self) -> dict[str, np.ndarray]:
        """What `sim.particles()` returns (sim.particles is also the particle fields, sim.particles.x and so on):
        the live particles, sorted by their stable id (the same particle keeps its id while storage is
        reordered, and emitted or spawned particles get new ones). Keys and shapes, N particles, D = scene.dim:
        `id` (N,) int; `position` (N, D) length; `velocity` (N, D) length/time; `temperature` (N,) degrees (NaN
        without heat); `melt_fraction` (N,) in [0, 1]; `material` (N,) index into `material_names`; `body` (N,)
        index into scene.groups (bodies, then emitters, then the spawn tool). Each call returns new arrays."""
        self.check_alive()
        p = self.particles
        n = int(p.n[None])
        ids = p.ident.to_numpy()[:n]
        order = np.argsort(ids, kind="stable")
        heat = self.heat is not None
        out = {
            "id": ids[order].astype(np.int64),
            "position": p.x.to_numpy()[:n][order],
            "velocity": p.v.to_numpy()[:n][order],
            "temperature": p.T.to_numpy()[:n][order] if heat else np.full(n, np.nan),
            "melt_fraction": self.melt_fractions()[order],
            "material": p.material.to_numpy()[:n][order].astype(np.int64),
            "body": p.group.to_numpy()[:n][order].astype(np.int64),
        }
        return out

    def picture(self, width: int | None = None, height: int | None = None, **render) -> np.ndarray:
        """The scene drawn now as a new (height, width, 3) uint8 RGB array, top row first. `width`, `height`:
        pixels (default: the scene's render size); `render`: [render] settings to change for this picture
        (color_by="temperature", legend=False, ...). The renderer is kept between calls of the same settings."""
        import dataclasses

        from .render.raster import Renderer

        cfg = self.scene.render
        if render:
            unknown = sorted(set(render) - {f.name for f in dataclasses.fields(cfg)})
            if unknown:
                raise ValueError(f"unknown render setting(s) {unknown}; expected fields of [render]")
            cfg = dataclasses.replace(cfg, **render)
        size = (width or cfg.width, height or cfg.height)
        key = (size, cfg)
        cached = getattr(self, "_picture_renderer", None)
        if cached is None or cached[0] != key:
            cached = (key, Renderer(self, size[0], size[1], cfg, output="picture"))
            self._picture_renderer = cached
        return np.array(cached[1].frame(), copy=True)

    def save(self, path: str | Path) -> Path:
        """Write the whole state to `path` (.npz) so that sandbox.resume(path) continues bit for bit; atomic (a
        crash while writing leaves any earlier file of that name whole). Returns the path written."""
        from .files.persist import save_state

        return save_state(self, path)

    def write_extxyz(self, path: str | Path, append: bool = True, bonds: bool = False) -> None:
        """Write the particles as one extended-XYZ frame (ASE, OVITO) to `path`: appended to it (`append`), or
        replacing it. `bonds`: the live springs as a Bonds key of particle-id pairs."""
        from .files.extxyz import append_frame, frame_text

        world = self.scene.world
        pairs = None
        if bonds and self.springs is not None:
            pairs = self.spring_pairs()
        text = frame_text(
            self.particle_table(),
            self.material_names,
            world.lo,
            world.hi,
            world.periodic,
            self.time,
            self.step_count,
            pairs,
        )
        path = Path(path)
        if not append:
            path.unlink(missing_ok=True)
        append_frame(path, text)

    def spring_pairs(self) -> np.ndarray:
        """The live springs as (M, 2) particle ids."""
        s = self.springs
        span = int(s.span[None])
        i, j, alive = s.i.to_numpy()[:span], s.j.to_numpy()[:span], s.alive.to_numpy()[:span]
        ids = self.particles.ident.to_numpy()
        live = alive != 0
        return np.stack([ids[i[live]], ids[j[live]]], axis=1)


def _progress_bar(total: int, label: str):
    """tqdm's bar (its notebook widget where one runs), or None without tqdm."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="frame", desc=label)
