"""What the command line's commands share: finding a scene by name or path, the exit codes, and the stability
warnings printed before a run."""

from __future__ import annotations

from pathlib import Path

from ..config.resources import shipped_scene, shipped_scenes
from ..config.scene import load_scene
from ..config.schema import unknown
from ..errors import SandboxError


def _scene_path(name: str) -> Path:
    """A scene by path, or by name from the shipped scenes/ folder."""
    path = Path(name)
    if path.is_file() or path.suffix == ".toml":
        return path
    shipped = shipped_scene(name)
    if shipped is None and not path.exists():
        names = [p.stem for p in shipped_scenes()]
        raise SandboxError(unknown("scene", name, names) + " (or a path to a .toml file)")
    return shipped or path


def _load(args):
    return load_scene(_scene_path(args.scene), args.set)


EXIT_BAD_INPUT, EXIT_STOPPED, EXIT_WRITE_FAILED, EXIT_INTERRUPTED = 2, 3, 4, 130


def stability_warnings(sim) -> list[str]:
    """Steps above the stable limits of the chosen integrator (springs as built) and of explicit heat diffusion."""
    dt, warnings = sim.scene.world.dt, []
    springs = sim.terms.springs
    spring_limit = springs.stable_dt_initial(sim.integrator) if springs is not None else float("inf")
    if dt > spring_limit:
        warnings.append(f"dt {dt:g} is above the springs' stable limit {spring_limit:.3g} for {sim.integrator.name}")
    heat_limit = sim.terms.heat.dt_limit if sim.terms.heat is not None else float("inf")  # a NumPy probe: computed once
    if dt > heat_limit:
        warnings.append(f"dt {dt:g} is above the explicit heat limit {heat_limit:.3g}")
    return warnings
