"""Sandbox tools: what the window's mouse and keys do to a running simulation, as plain functions (testable without
a screen). Positions and radii are in scene units; rates are per simulated second.

heat / cool     add (remove) heat at `rate` degrees per second at the brush centre, falling linearly to 0 at its edge
attract / repel a force towards (away from) the centre, per unit mass, falling linearly to the edge
drag            pull particles towards the centre and damp their velocity relative to it (picking something up)
impulse         an outward kick (an explosion), `speed` at the centre falling to 0 at the edge
erase           remove every particle within the brush (and the springs that held them)
spawn           add particles of a material on a lattice within the brush, where they do not overlap others

Brush kernels act on every active particle (only those inside the brush change); erase and spawn change the
particle count and run on the host (they are interactive, not per step), then tell the state its layout changed.
In a simulation of many worlds (core/worlds.py) a brush acts in one world (`world`), and erase and spawn are
refused: a world keeps its scene's particle count.
"""

import numpy as np
import taichi as ti

from ..config.schema import ABSOLUTE_ZERO
from ..core.oriented import data_oriented
from ..errors import SandboxError
from ..physics.phase import LIQUID, initial_enthalpy
from . import tool_table


@data_oriented
class Tools:
    """The brush tools bound to a simulation."""

    def __init__(self, sim, world: int | None = None):
        """The brushes of `sim`; where it holds several worlds, they act in world `world` alone (None: in all)."""
        self.sim = sim
        self.p = sim.state.particles
        self.dim = sim.dim
        self.centre = ti.Vector.field(sim.dim, float, shape=())  # the brush centre (a field: no recompiles)
        if self.p.worlds:  # the world a brush acts in, -1 for every world (a lone run's kernels read nothing)
            self.only = ti.field(ti.i32, shape=())
            self.set_world(world)

    def set_world(self, world: int | None) -> None:
        """Act in world `world` alone from now on (None: in every world; nothing in a simulation of one world)."""
        if self.p.worlds:
            self.only[None] = -1 if world is None else int(world)

    @ti.func
    def _reaches(self, i):
        """Whether particle i is in the world the brush acts in (always, in a lone run)."""
        yes = True
        if ti.static(self.p.worlds):
            yes = self.only[None] < 0 or self.p.world[i] == self.only[None]
        return yes

    def _at(self, centre) -> None:
        self.centre[None] = [float(c) for c in centre]

    # ------------------------------------------------------------------ brushes (kernels)
    def heat(self, centre, radius: float, rate: float, dt: float) -> None:
        """Raise temperatures by up to rate * dt degrees (negative: cool, never below absolute zero) within `radius`
        of `centre`."""
        if self.sim.terms.heat is None:
            raise SandboxError("this scene has no heat: the heat and cool tools are not available")
        self._at(centre)
        self._heat(float(radius), float(rate * dt))

    @ti.kernel
    def _heat(self, radius: float, amount: float):
        c = self.centre[None]
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            w = 1.0 - (self.p.x[i] - c).norm() / radius
            # heat c dT per unit mass: melting then holds the temperature while latent heat goes in
            if w > 0.0 and self._reaches(i):
                m = self.p.material[i]
                cap = self.sim.model.phase.capacity(self.p.h[i], m)
                coldest = self.sim.model.phase.enthalpy(ABSOLUTE_ZERO, m)
                self.sim.terms.heat.set_enthalpy(i, ti.max(self.p.h[i] + cap * amount * w, coldest))

    def push(self, centre, radius: float, strength: float, dt: float) -> None:
        """Change velocities by strength * dt (towards the centre when positive) within the brush."""
        self._at(centre)
        self._push(float(radius), float(strength * dt))

    @ti.kernel
    def _push(self, radius: float, dv: float):
        c = self.centre[None]
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            d = c - self.p.x[i]
            r = d.norm()
            w = 1.0 - r / radius
            if w > 0.0 and r > 1e-9 and self._reaches(i):
                self.p.v[i] += dv * w * d / r

    def drag(self, centre, radius: float, stiffness: float, dt: float) -> None:
        """Spring particles in the brush towards the centre, critically damped (a hand picking things up)."""
        self._at(centre)
        self._drag(float(radius), float(stiffness), float(dt))

    @ti.kernel
    def _drag(self, radius: float, k: float, dt: float):
        c = self.centre[None]
        for i in range(self.p.n[None]):
            if self.p.idle(i):
                continue
            d = c - self.p.x[i]
            w = 1.0 - d.norm() / radius
            if w > 0.0 and self._reaches(i):
                self.p.v[i] += dt * w * (k * d - 2.0 * ti.sqrt(k) * self.p.v[i])

    def impulse(self, centre, radius: float, speed: float) -> None:
        """An explosion: add up to `speed` outward from the centre, falling to 0 at the brush edge."""
        self._at(centre)
        self._push(float(radius), -float(speed))

    # ------------------------------------------------------------------ count-changing tools (host side)
    def erase(self, centre, radius: float) -> int:
        """Remove the particles within `radius` of `centre` and the springs attached to them; returns how many."""
        self._one_count("erase")
        p = self.p
        n = int(p.n[None])
        x = p.x.to_numpy()[:n]
        keep = np.linalg.norm(x - np.asarray(centre, dtype=float), axis=1) > radius
        removed = int(n - keep.sum())
        if removed == 0:
            return 0
        new_index = np.full(n, -1, dtype=np.int64)
        new_index[keep] = np.arange(int(keep.sum()))
        for name in p.names():
            field = getattr(p, name)
            data = field.to_numpy()
            kept = data[:n][keep]
            data[: len(kept)] = kept
            field.from_numpy(data)
        p.n[None] = int(keep.sum())
        p.clear(int(keep.sum()), n)  # the slots left hold nothing of the erased
        springs = self.sim.state.springs
        if springs is not None:
            i, j = springs.i.to_numpy(), springs.j.to_numpy()
            alive = springs.alive.to_numpy()
            ni, nj = new_index[i], new_index[j]
            dead = (ni < 0) | (nj < 0)
            alive[dead] = 0
            springs.alive.from_numpy(alive)
            springs.i.from_numpy(np.where(dead, 0, ni).astype(np.int32))
            springs.j.from_numpy(np.where(dead, 0, nj).astype(np.int32))
            springs.rebuild_bonds()
        self._changed()
        return removed

    def spawn(
        self, material: str, centre, radius: float, spacing: float | None = None, temperature: float | None = None
    ) -> int:
        """Add particles of `material` (one of the scene's) on a square/cubic lattice filling the brush, skipping
        sites closer than 0.9 spacing to an existing particle; they spawn as liquid (no springs). The spacing (length)
        defaults to the scene's particle spacing. Returns how many were added (limited by world.capacity)."""
        self._one_count("spawn")
        sim = self.sim
        if material not in sim.material_names:
            raise SandboxError(
                f"spawn: material {material!r} is not in this scene; expected one of " + ", ".join(sim.material_names)
            )
        mat_id = sim.material_names.index(material)
        mat = sim.scene.materials[material]
        spacing = spacing or sim.scene.spacing
        centre = np.asarray(centre, dtype=float)
        k = int(np.ceil(radius / spacing))
        axes = [np.arange(-k, k + 1) * spacing] * self.dim
        sites = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, self.dim) + centre
        sites = sites[np.linalg.norm(sites - centre, axis=1) <= radius]
        lo, hi = np.asarray(sim.scene.world.lo), np.asarray(sim.scene.world.hi)
        sites = sites[np.all((sites >= lo + 0.5 * spacing) & (sites <= hi - 0.5 * spacing), axis=1)]
        n = int(self.p.n[None])
        x = self.p.x.to_numpy()[:n]
        if n and len(sites):
            d2 = ((sites[:, None, :] - x[None, :, :]) ** 2).sum(axis=2).min(axis=1)
            sites = sites[d2 >= (0.9 * spacing) ** 2]
        sites = sites[: max(0, sim.capacity - n)]
        m = len(sites)
        if m == 0:
            return 0
        mass = mat.particle_mass if mat.particle_mass is not None else mat.density * spacing**self.dim
        ambient = sim.scene.heat.ambient if sim.scene.heat else 20.0
        values = {
            "x": sites,
            "v": np.zeros_like(sites),
            "mass": np.full(m, mass),
            "radius": np.full(m, 0.5 * spacing),
            "material": np.full(m, mat_id),
            "color": np.tile(sim.model.materials.colors[mat_id], (m, 1)),
            "group": np.full(m, len(sim.scene.groups)),  # the spawn tool's own group, after bodies and emitters
            "ident": np.arange(self.p.next_ident, self.p.next_ident + m),
        }
        if self.p.heat:
            t = np.full(m, ambient if temperature is None else temperature)
            values["h"], _ = initial_enthalpy(t, np.full(m, 0), [mat])
            values["T"] = t
        if self.p.refreeze:
            values["liquid"] = np.full(m, LIQUID)  # spawned as a melt: it freezes into a solid where it is cold
        self.p.put(n, values)  # every other field (age, lifetime, phase ...) at its declared default
        self.p.n[None] = n + m
        self.p.next_ident += m
        self._changed()
        return m

    def _one_count(self, tool: str) -> None:
        """SandboxError for a tool that changes the particle count in a simulation of several worlds."""
        if self.p.worlds:
            raise SandboxError(
                f"{tool} changes a world's particle count; each world of a simulation of {self.p.world_count} keeps "
                "its scene's (expected heat, cool, drag, attract, repel or impulse)"
            )

    def _changed(self) -> None:
        self.sim.state.particles_moved()  # what was built over the old layout (neighbour lists) rebuilds

    def apply(
        self, tool: str, centre, radius: float, dt: float, strength: float = 1.0, material: str | None = None
    ) -> None:
        """Apply `tool` (a name in tool_table.py) for one frame of `dt` seconds: what the mouse does while held. The
        blow-up guard takes the energy and heat a tool puts in by hand as part of the scene from then on."""
        try:
            use = tool_table.by_name(tool).use
        except KeyError:
            raise SandboxError(f"unknown tool {tool!r}; expected one of {', '.join(tool_table.names())}") from None
        self.sim.guard.accept_current_state()
        use(self, centre, radius, dt, strength, material or self.sim.material_names[0])
