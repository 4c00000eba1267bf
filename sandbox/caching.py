"""Particle caches from a simulation (docs/export.md): the particles now as a cache frame with the scene's walls,
plates and lid and its pictures' camera, and the Cache a script writes frame by frame. The formats themselves are
files/cache_formats.py, files/cache_usd.py and files/cache_parts.py; the frames' files files/cache_sequence.py."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .files.cache_formats import COLOR_COLUMNS, SURFACE_VELOCITY, CacheFrame
from .files.cache_parts import Part
from .files.cache_sequence import CacheSequence, index_path
from .files.claim import Claim
from .physics.phase import ENTHALPY_LAW, gas_fraction_np
from .render.camera import scene_camera
from .render.colormaps import TEMPERATURE_STOPS, ramp_np_many
from .render.style import LID_COLOR, WALL_GAIN, WALL_LIFT
from .render.surface import reconstruct
from .scripting import particle_table, run_frames, spring_pairs
from .world_view import one_world


def particle_phases(sim, table: dict[str, np.ndarray]) -> np.ndarray:
    """Phase code per row of `table` (particle_table): 0 solid (melt fraction below one half), 1 liquid, 2 gas (gas
    fraction at least one half). Without heat every particle is 0."""
    n = len(table["id"])
    if sim.terms.heat is None:
        return np.zeros(n, dtype=np.int32)
    p, live = sim.particles, sim.state.live_count()
    order = np.argsort(p.ident.to_numpy()[:live], kind="stable")
    ids = table["material"]
    c, _, liquidus, latent, boil, vapor, liquid_c, _ = (sim.model.column(name, ids) for name in ENTHALPY_LAW)
    gas = gas_fraction_np(p.h.to_numpy()[:live][order], c, liquidus, latent, boil, vapor, liquid_c)
    return np.where(gas >= 0.5, 2, np.where(table["melt_fraction"] >= 0.5, 1, 0)).astype(np.int32)


def cache_frame(sim, surface: bool = False) -> CacheFrame:
    """The particles now as one cache frame (files/cache_formats.py): positions in 3 components, velocity,
    temperature (degrees C), melt fraction, phase, material, body and id as point data, widths (each particle's
    diameter, length), the live springs, and with `surface` the surface of the bodies and melts (not the emitted
    particles, not the gas) with the temperature, velocity and colour there on its vertices (render/surface.py, the
    scene's surface_* keys); the scene's parts and its pictures' camera."""
    table = particle_table(sim)
    dim, n = sim.dim, len(table["id"])
    points = np.zeros((n, 3), dtype=np.float32)
    points[:, :dim] = table["position"]
    velocity = np.zeros((n, 3), dtype=np.float32)
    velocity[:, :dim] = table["velocity"]
    phase = particle_phases(sim, table)
    colors = cache_colors(sim, table)
    groups = sim.scene.groups
    diameter = np.array([2 * g.particle_radius if hasattr(g, "particle_radius") else sim.scene.spacing for g in groups])
    widths = np.where(
        table["body"] < len(groups), diameter[np.minimum(table["body"], len(groups) - 1)], sim.scene.spacing
    )
    data = {
        "velocity": velocity,
        "temperature": np.nan_to_num(table["temperature"].astype(np.float32), nan=0.0),
        "melt_fraction": table["melt_fraction"].astype(np.float32),
        "phase": phase,
        "material": table["material"].astype(np.int32),
        "body": table["body"].astype(np.int32),
        "id": table["id"],
    }
    bonds = None
    if sim.state.springs is not None:
        bonds = np.searchsorted(table["id"], spring_pairs(sim)).astype(np.int64).reshape(-1, 2)  # ids -> rows
    gravity = np.abs(np.asarray(sim.scene.world.gravity or (0.0,) * dim))
    up = "Z" if dim == 3 and gravity.size == 3 and gravity.argmax() == 2 and gravity.max() > 0 else "Y"
    shape = None
    if surface:
        emitted = (table["body"] >= len(sim.scene.bodies)) & (table["body"] < len(groups))
        keep = ~emitted & (phase < 2)
        r = sim.scene.render
        values = {"temperature": data["temperature"][keep]}
        values.update({name: velocity[keep, k] for k, name in enumerate(SURFACE_VELOCITY)})
        if not sim.particles.heat:  # the materials' colours, blended across the surface
            values.update({c: colors[keep, k].astype(np.float32) for k, c in enumerate(COLOR_COLUMNS)})
        shape = reconstruct(
            points[keep], values, 0.5 * sim.scene.spacing, r.surface_smoothing, r.surface_iso, r.surface_cell, dim
        )
        if sim.particles.heat:  # the colour of the temperature there, as the particles have theirs
            shape.colors = temperature_colors(sim, shape.vertex_data["temperature"])
        else:
            blended = np.stack([shape.vertex_data.pop(c) for c in COLOR_COLUMNS], axis=1)
            shape.colors = np.clip(np.round(blended), 0, 255).astype(np.uint8)
    frame = CacheFrame(
        sim.frames_done, sim.time, points, data, widths.astype(np.float32), bonds, shape, up, sim.frame_seconds
    )
    frame.colors = colors
    frame.parts, frame.camera = scene_parts(sim), scene_camera(sim.scene)
    return frame


def cache_colors(sim, table: dict) -> np.ndarray:
    """Each particle's colour as the sandbox draws it, (N, 3) uint8 sRGB: the temperature colour map over the scene's
    render.temperature_range where the scene has heat, else its material's colour."""
    if sim.particles.heat:
        return temperature_colors(sim, table["temperature"])
    return color_bytes(sim.model.materials.colors[table["material"]])


def temperature_colors(sim, temperature: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 sRGB: the temperature colour map over the scene's render.temperature_range at `temperature`
    (N,) degrees C."""
    lo, hi = sim.scene.render.temperature_range
    return color_bytes(ramp_np_many(TEMPERATURE_STOPS, (np.asarray(temperature, np.float64) - lo) / (hi - lo)))


def color_bytes(rgb) -> np.ndarray:
    """Colours of floats in [0, 1] (..., 3) as uint8 bytes, rounded."""
    return np.clip(np.round(255.0 * np.asarray(rgb, dtype=np.float64)), 0, 255).astype(np.uint8)


def srgb_bytes(rgb) -> tuple[int, int, int]:
    """One colour of floats in [0, 1] as 3 bytes."""
    return tuple(int(v) for v in color_bytes(rgb))


def scene_parts(sim) -> list[Part]:
    """The scene's solids besides its particles now (files/cache_parts.py): the walls (none where the world is
    periodic), each heat source the pictures draw, in the colour they draw it (a power source has no temperature:
    hot if it heats, cold if it cools), and the molecular model's lid at its height (the piston above it)."""
    scene, dim = sim.scene, sim.dim
    lo, hi = np.zeros(3), np.zeros(3)
    lo[:dim], hi[:dim] = scene.world.lo, scene.world.hi
    if dim == 2:  # one spacing deep, as the particles lie on z = 0
        lo[2], hi[2] = -0.5 * scene.spacing, 0.5 * scene.spacing

    def box(a, b) -> tuple[tuple, tuple]:
        corner_lo, corner_hi = lo.copy(), hi.copy()
        corner_lo[:dim], corner_hi[:dim] = a, b
        return tuple(map(float, corner_lo)), tuple(map(float, corner_hi))

    parts = []
    if not scene.world.periodic:
        wall = srgb_bytes(np.asarray(scene.render.background) * WALL_GAIN + WALL_LIFT)  # the pictures' frame
        parts.append(Part("walls", tuple(map(float, lo)), tuple(map(float, hi)), wall, open=("+y", "+z")))
    heat = sim.terms.heat
    cold, hot = scene.render.temperature_range
    for k, source in enumerate(scene.heat.sources if scene.heat else []):
        if not source.visible:
            continue
        value = heat.sources.value(k) if heat is not None else float("nan")
        temperature = value if source.mode != "power" else math.nan
        shown = temperature if source.mode != "power" else (hot if value >= 0 else cold)
        color = tuple(int(v) for v in temperature_colors(sim, [shown])[0])
        parts.append(Part(f"plate_{k}", *box(source.lo, source.hi), color, float(temperature)))
    lid = sim.terms.lid
    if lid is not None:
        height = lid.height_of()
        bottom, top = np.array(scene.world.lo, float), np.array(scene.world.hi, float)
        bottom[1] = min(height, top[1])
        parts.append(Part("lid", *box(bottom, top), srgb_bytes(LID_COLOR)))
    return parts


class Cache:
    """A particle cache a script writes frame by frame (docs/export.md): `with sandbox.Cache("out/wax.usd") as
    cache: ... cache.write(sim)`. `fps`: time codes per second of a USD stage; `lines`: springs as VTK lines."""

    def __init__(self, path: str | Path, fps: float = 30.0, lines: bool = True) -> None:
        path = Path(path)
        self.claim = Claim("cache", index_path(path))
        self.claim.acquire()
        self.sequence = CacheSequence(self.claim, path, fps, lines)
        self.sequence.start()

    def write(self, sim, surface: bool = False) -> None:
        """Add the particles as they are now (the frame numbered sim.frames_done)."""
        self.sequence.write(cache_frame(sim, surface))

    def close(self) -> None:
        """Write the index and release the name."""
        try:
            self.sequence.publish()
        finally:
            self.claim.release()

    def __enter__(self) -> Cache:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_cache(sim, path: str | Path, frames: int, every: int = 1, surface: bool = False, fps: float = 30.0) -> Path:
    """Run `frames` frames, caching the state before them and after every `every`-th (see Cache); the index path."""
    one_world(sim, f"{path}: a particle cache")
    with Cache(path, fps) as cache:
        cache.write(sim, surface)
        run_frames(sim, frames, after=lambda k: (k + 1) % every == 0 and cache.write(sim, surface))
    return cache.claim.path
