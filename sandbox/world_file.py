"""One world's state file (`sim.world(k).save(path)`, `sim.world(k).load(path)`): the world's state as a lone run
of its scene holds it (world_state.py), in the state-file format (files/persist.py), so a world's file opens with
`sandbox.resume` like any other, and a lone run's state file, or another world's, loads into any world of a
simulation of the scene.

A world's file holds what a step reads (`physical_only`: positions, velocities, heat, bonds, clock, gauges, live
controls), not the neighbour lists of the batch it came from: they are built again where it is loaded, so the run
from it is that state's, its first sums in the rebuilt lists' order.
"""

from __future__ import annotations

from pathlib import Path

from .core import controls as live_controls
from .core.state import FIELD, NDARRAY, VALUE
from .errors import SandboxError, SimulationError
from .files.persist import check_controls, read_meta, read_state_file, state_meta, write_state_file
from .files.state_check import check_world_state
from .world_state import OWN, put_world, world_snapshot


def _world_entries(sim) -> list:
    """The entries a world's file holds: the physical ones less the batch's own (world_state.OWN)."""
    return [e for e in sim.state.entries(physical_only=True) if e.name not in OWN]


def save_world(sim, k: int, path: str | Path) -> Path:
    """Write world k's state to `path` (.npz added when missing) atomically; returns the path written (OutputError,
    SimulationError: one line)."""
    return save_part(sim, world_snapshot(sim, k), live_controls.Controls(sim.model, sim.terms, k).values(), path)


def save_part(sim, part: dict, controls: dict, path: str | Path) -> Path:
    """Write a world's state `part` (world_state.world_part's) with its live `controls` (by namespaced name) to
    `path` as a world's state file; returns the path written."""
    entries = _world_entries(sim)
    arrays = {f"{e.kind}:{e.name}": part[e.name] for e in entries if e.kind in (FIELD, NDARRAY)}
    host = {e.name: part[e.name] for e in entries if e.kind == VALUE}
    meta = state_meta(sim, sim.state.frames, float(part["clock.time"]), int(part["particles.n"]), controls)
    meta.update(physical_only=True)
    try:
        check_world_state(sim.model, entries, part, arrays, host, Path(path))  # what would not load is not written
    except SandboxError as exc:
        raise SimulationError(f"not saved: {exc}") from None
    return write_state_file(path, meta, arrays, host)


def load_world(sim, k: int, path: str | Path) -> None:
    """Put a state file of this scene (a lone run's, or a world's) into world k: checked before anything changes
    (SandboxError, one line, naming the file); its state and its own live controls go into world k alone."""
    world = live_controls.Controls(sim.model, sim.terms, k)
    part, controls = read_world_file(sim, path, world_snapshot(sim, k), world.values())
    put_world(sim, k, part)
    live_controls.apply(sim.model, sim.terms, controls, k)


def read_world_file(sim, path: str | Path, like: dict, current: dict) -> tuple[dict, dict]:
    """A state file of `sim`'s scene read as one world's state: (the part, as world_state.world_part gives it; the
    world's own live controls by namespaced name), checked against `like` (a world's part now) and the world's
    controls `current`; SandboxError (one line, naming the file) for anything that does not fit."""
    path = Path(path)
    meta = read_meta(path)
    if meta["scene"] != sim.scene.source:
        raise SandboxError(
            f"{path}: saved from the scene {meta.get('scene_name')!r} as it was then; expected one saved from this "
            f"{sim.scene.name!r}"
        )
    if meta["integrator"] != sim.integrator.name:
        raise SandboxError(
            f"{path}: saved stepping with {meta['integrator']}; expected {sim.integrator.name}, which every world of "
            "this simulation steps with"
        )
    saved, host = read_state_file(path, sim.state)
    _check_world_controls(sim, current, meta["controls"], path)
    entries = _world_entries(sim)
    check_world_state(sim.model, entries, like, saved, host, path)
    part = {e.name: saved[f"{e.kind}:{e.name}"] for e in entries if e.kind in (FIELD, NDARRAY)}
    part.update({e.name: host[e.name] for e in entries if e.kind == VALUE})
    return part, meta["controls"]


def _check_world_controls(sim, current: dict, saved: dict, path: Path) -> None:
    """The file's live controls are this scene's, each shaped as world k's, passing their owners' checks."""
    check_controls(saved, current, path)
    said = live_controls.problem(sim.model, sim.terms, saved)
    if said:
        raise SandboxError(f"{path}: {said}")
