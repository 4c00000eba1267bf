"""The Model: what a scene fixes (its settings, materials, box, loop policy, the particles as built) and the few
values the user may change while it runs (gravity, drag), as opposed to the State (core/state.py): what a step
changes."""

import numpy as np
import taichi as ti

from ..config.materials import Material
from ..config.scene_tables import World
from ..config.schema import key_check
from . import transfer
from .oriented import data_oriented
from .transfer import real_fields
from .worlds import per_world, set_world_entry, world_entry


def material_column(materials: list[Material], material: np.ndarray, name: str) -> np.ndarray:
    """Property `name` of each particle's material, (N,), from material ids (N,); infinities held at 1e30 as in
    the MaterialTable fields, so NumPy and the kernels see the same numbers."""
    return np.array([min(getattr(m, name), 1e30) for m in materials])[material]


@data_oriented
class MaterialTable:
    """Per-material properties as small fields, indexed by a particle's material id."""

    def __init__(self, materials: list[Material]):
        n = len(materials)
        self.liquid_color = ti.Vector.field(3, ti.f32, shape=n)  # melt colour when drawing by phase, (n_mat, 3)
        liquid = np.array([m.liquid_color for m in materials], dtype=np.float32)
        # Float fields of the running precision, one entry per material, all filled by one copy kernel; NumPy copies
        # of the same numbers are kept for host-side set-up (heat conductance tables).
        self.host = {
            "density": [m.density for m in materials],  # mass / volume
            "specific_heat": [m.specific_heat for m in materials],  # heat / (mass degree), of the solid
            "liquid_heat": [m.liquid_specific_heat for m in materials],  # heat / (mass degree), of the liquid
            "gas_heat": [m.gas_specific_heat for m in materials],  # heat / (mass degree), of the vapour
            "conductivity": [m.conductivity for m in materials],  # heat / (time length degree)
            "soften": [min(m.soften_temperature, 1e30) for m in materials],  # degrees
            "melt": [min(m.melt_temperature, 1e30) for m in materials],  # solidus (degrees)
            "liquidus": [min(m.liquidus_temperature, 1e30) for m in materials],  # degrees
            "latent": [m.latent_heat for m in materials],  # heat / mass
            "boil": [min(m.boil_temperature, 1e30) for m in materials],  # degrees
            "vaporize": [m.vaporization_heat for m in materials],  # heat / mass
            "stiff_at_melt": [m.stiffness_at_melt for m in materials],  # fraction of k_s left at the solidus
            "break_fraction": [m.break_melt_fraction for m in materials],  # both ends this molten: bond breaks
            "undercool": [m.refreeze_undercooling for m in materials],  # degrees below the solidus to refreeze
            "stiffness": [m.stiffness for m in materials],  # k_s of bonds made by refreezing
            "damping": [m.damping for m in materials],  # k_d of bonds made by refreezing
        }
        self.host = {k: np.asarray(v, dtype=np.float64) for k, v in self.host.items()}
        fields = real_fields(*self.host.values(), also=((self.liquid_color, liquid),))
        for name, field in zip(self.host, fields):
            setattr(self, name, field)
        self.colors = np.array([m.color for m in materials], dtype=np.float32)  # (n_mat, 3)


@data_oriented
class Model:
    """What a scene fixes. Built once per simulation (sandbox/assembly.py); the terms, the rates and the renderer
    read it, nothing steps it. Live controls (gravity, linear drag) are 0-d fields, so changing one recompiles no
    kernel; `controls()` and `apply_controls()` carry them through state files."""

    world_controls = True  # gravity and drag are each world's own (core/worlds.py)

    def __init__(
        self, scene, arch: str, built, capacity: int, materials: list, table, phase, loops, domain, threads, worlds=1
    ):
        """`materials`: the scene's used Material records (config), by material id; `table`: their MaterialTable;
        `phase`: the enthalpy law over it (physics/phase.py), None without heat; `worlds`: copies of the scene held
        (core/worlds.py)."""
        self.scene = scene
        self.arch = arch
        self.dim = scene.dim
        self.built = built  # the particles and springs of one world as built from the scene (config/build.py), NumPy
        self.worlds = worlds  # copies of the scene held, each with its own particles and controls (core/worlds.py)
        self.capacity = capacity  # particle slots
        self.threads = threads  # the CPU backend's worker threads (1 elsewhere)
        self.material_names = scene.used_materials()
        self.material_list = materials  # config Material records, by material id
        self.materials = table
        self.phase = phase
        self.loops = loops  # LoopPolicy: which loops run in parallel
        self.lone_loops = loops  # ... and how one world alone would run them (assembly.py sets it for many worlds)
        self.lone_threads = threads  # ... on this many CPU threads
        self.domain = domain  # the box: separations, walls or periodic wrap
        self.gravity = per_world(worlds, float, self.dim)  # acceleration (length / time^2), per world
        self.drag = per_world(worlds, float)  # linear drag rate (1 / time), per world
        gravity = np.tile(np.asarray(scene.world.gravity, float), (worlds, 1)) if worlds > 1 else scene.world.gravity
        drag = np.full(worlds, float(scene.world.drag)) if worlds > 1 else scene.world.drag
        transfer.upload([(self.gravity, np.asarray(gravity, float)), (self.drag, drag)])

    def controls(self, world: int = 0) -> dict:
        """The live controls of world `world` as plain numbers (for state files)."""
        if self.worlds > 1:
            gravity, drag = (world_entry(field, self.worlds, world) for field in (self.gravity, self.drag))
            return {"gravity": gravity, "drag": drag}
        gravity, drag = transfer.download([self.gravity, self.drag])
        return {"gravity": [float(g) for g in gravity], "drag": float(drag)}

    def sliders(self) -> list:
        """None: gravity's strength and direction are the controller's sliders over the one vector control."""
        return []

    def control_checks(self) -> dict:
        """Gravity and drag keep the checks of the scene's keys (core/controls.problem)."""
        return {"gravity": key_check(World, "gravity"), "drag": key_check(World, "drag")}

    def apply_controls(self, values: dict, world: int | None = None) -> None:
        """Set the live controls from `controls()`'s numbers: world `world`'s, or every world's (None)."""
        if self.worlds > 1:
            for name in ("gravity", "drag"):
                if name in values:
                    set_world_entry(getattr(self, name), self.worlds, world, np.asarray(values[name], float))
            return
        pairs = [(self.gravity, np.asarray(values["gravity"], float))] if "gravity" in values else []
        pairs += [(self.drag, values["drag"])] if "drag" in values else []
        transfer.upload(pairs)

    def column(self, name: str, material_ids: np.ndarray) -> np.ndarray:
        """Material property `name` of particles with `material_ids` (NumPy, infinities held at 1e30)."""
        return material_column(self.material_list, material_ids, name)
