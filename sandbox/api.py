"""The Python API's entry points (exported from `sandbox`): load a scene, resume a saved state, list what ships.

    import sandbox
    sim = sandbox.load("melting_block", set={"world.dt": 0.001})
    table = sim.run(60)                  # per-frame measurements (FrameTable; .to_pandas() with pandas)
    parts = sim.particles()              # NumPy arrays by particle id
    image = sim.picture(640, 360)        # (360, 640, 3) uint8
    sim.save("block.npz"); again = sandbox.resume("block.npz")

Taichi runs one backend at one precision per process. The first simulation chooses them (or `sandbox.use`); a
later one that asks for others gets a SandboxError while simulations of the first choice are alive, instead of
silently invalidating them.
"""

from __future__ import annotations

import copy
import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from .config.materials import load_library
from .config.resources import shipped_scene, shipped_scenes
from .config.scene import apply_override, parse_override, read_scene_table, scene_from_dict
from .config.schema import unknown
from .core import runtime
from .core.worlds import check_count
from .errors import SandboxError
from .files.persist import load_into, read_meta, saved_scene
from .simulation import Simulation

_alive: weakref.WeakSet = weakref.WeakSet()  # simulations made here, on the running runtime
_arch = "auto"  # the backend sandbox.use() chose


def scene_names() -> list[str]:
    """Names of the shipped scenes (for sandbox.load)."""

    return sorted(p.stem for p in shipped_scenes())


def material_names() -> list[str]:
    """Names of the materials in the library (a scene's bodies name them; scenes can add their own)."""

    return sorted(load_library())


def use(arch: str = "auto", precision: str = "f32") -> str:
    """Choose the Taichi backend (auto, cpu, cuda, vulkan, metal) and float precision (f32, f64) for this process,
    before building simulations; returns the backend running. SandboxError when simulations of another choice are
    alive, or a backend named is not available."""
    global _arch
    _check_switch(arch, precision)
    _arch = arch
    return runtime.require(arch, precision)


def _check_switch(arch: str, precision: str) -> None:
    running = runtime.current()
    if running is None or not list(_alive):
        return
    if precision != running[1] or (arch != "auto" and arch != runtime.running_arch()):
        raise SandboxError(
            f"Taichi already runs {runtime.running_arch()} at {running[1]} in this process for "
            f"{len(list(_alive))} live simulation(s); a scene asking for {arch} at {precision} needs a new process "
            "(or delete those simulations first)"
        )


def _overrides(set: Mapping[str, Any] | Sequence[str] | None) -> list[tuple[str, Any]]:
    if set is None:
        return []
    if isinstance(set, Mapping):
        return [(str(k), v) for k, v in set.items()]
    if isinstance(set, str):
        raise TypeError("set: expected a dict {'world.dt': 0.001} or a list of 'key=value' strings, not one string")
    return [parse_override(text) for text in set]


def load(
    scene: str | Path | Mapping,
    set: Mapping[str, Any] | Sequence[str] | None = None,  # noqa: A002 - the CLI's --set
    arch: str | None = None,
    worlds: int = 1,
) -> Simulation:
    """Build a simulation of `scene`: a shipped scene's name ("melting_block"), a scene file's path, or a scene
    table as a dict (the TOML's structure). `set`: overrides by dotted key ({"world.dt": 0.001,
    "bodies.0.temperature": 80}) or as 'key=value' strings like the CLI's --set. `arch`: the backend (default: the
    one chosen by sandbox.use, else auto). `worlds`: copies of the scene stepped together, each with its own
    particles and controls (sim.world(k); docs/worlds.md). SceneError names the file, key and expectation when the
    scene is invalid."""
    try:
        worlds = check_count(worlds)
    except ValueError as exc:
        raise SandboxError(str(exc)) from None

    if isinstance(scene, Mapping):
        data, path = copy.deepcopy(dict(scene)), Path.cwd() / "scene.toml"
    else:
        path = Path(scene)
        # a shipped scene's name, unless a file of that name is here (a folder of that name does not hide it)
        if not path.is_file() and isinstance(scene, str) and shipped_scene(scene) is not None:
            path = shipped_scene(scene)
        data = read_scene_table(path, unknown("scene", str(scene), scene_names()) + " (or a path to a .toml file)")
    for key, value in _overrides(set):
        apply_override(data, key, value)
    built = scene_from_dict(data, path)
    arch = arch or _arch
    _check_switch(arch, built.world.precision)
    sim = Simulation(built, arch=arch, worlds=worlds)
    _alive.add(sim)
    return sim


def resume(path: str | Path, arch: str | None = None) -> Simulation:
    """The simulation saved in `path` (sim.save, or the CLI's --checkpoint-every), ready to continue bit for bit.
    SandboxError when the file is not a state file, is damaged, or comes from another version of the sandbox."""
    meta = read_meta(path)
    _check_switch(arch or meta["arch"], meta["precision"])
    sim = resumed(path, arch, meta)
    _alive.add(sim)
    return sim


def resumed(path: str | Path, arch: str | None, meta: dict, scene=None) -> Simulation:
    """Build the simulation a state file describes (`meta`: its read_meta(); `scene`: the scene built from it, where
    the caller has it already) and put its saved state back. `arch`: the backend (default: the one it was saved on)."""
    scene = scene or saved_scene(meta, path)
    sim = Simulation(scene, arch=arch or meta["arch"])
    load_into(sim, path, meta)
    return sim
