"""What a simulation is made of, in words and bytes: the passes a step runs (`pipeline()`), the fields allocated and
their memory. A mixin of Simulation; `sandbox check` prints it."""

from .integrators import REGISTRY
from .physics.grid import CellGrid
from .step_plan import host_work_reasons


class Description:
    """Simulation's self-description."""

    def pipeline(self) -> list[str]:
        """The passes a step runs, in order."""
        passes = []
        if self.emitters is not None:
            passes.append(f"emitters: {', '.join(e.name for e in self.scene.emitters)} (rate, bursts)")
        if self.smoke is not None:
            passes.append(f"smoke: stable fluids on a {self.smoke.describe()} (buoyancy, advection, CG projection)")
        if self.has_field_drag:
            passes.append("velocity field sampled at field-coupled particles (their drag target)")
        if self.neighbours is not None:
            passes.append(
                f"{'half' if self.half_pairs else 'full'} neighbour lists (reach {self.neighbours.reach:g} + skin "
                f"{self.neighbours.skin:g}, width {self.neighbours.width}), rebuilt from a counting-sort "
                f"{self.grid.describe()} when a particle has moved half the skin"
            )
            if self.reorder is not None:
                passes.append(f"particle storage sorted into cell order every {self.reorder.every} list rebuilds")
        elif self.grid is not None:
            passes.append(f"neighbour grid: counting sort into a {self.grid.describe()}, every step")
        if self.springs is not None:
            what = "thermoelastic softening and breaking by melt fraction" if self.heat else "overstretch breaking"
            slots = f" ({self.springs.count} slots, room to refreeze)" if self.refreezer is not None else ""
            passes.append(f"spring update ({what}) over {self.springs.built_count} springs{slots}")
        forces = []
        if self.pair is not None:
            forces.append(f"pair force (a={self.pair.a:g}, b={self.pair.b:g}, cutoff {self.pair.cutoff:g})")
        if self.heat is not None:
            forces.append(f"heat diffusion (kernel support {self.heat.support:g}, {self.heat.n_sources} sources)")
        if self.springs is not None:
            forces.append("spring-damper forces (gathered per particle)")
        if any(self.scene.world.gravity):
            forces.append("gravity")
        if self.scene.world.drag:
            forces.append("drag")
        pairs = " (each neighbour pair once, applied to both)" if self.half_pairs else ""
        passes.append(f"fused rates kernel{pairs}: " + ", ".join(forces))
        walls = "periodic wrap" if self.scene.world.periodic else "walls (restitution, friction)"
        heat = ""
        if self.heat is not None:
            heat = ", enthalpy update (temperature and melt fraction from it)" if self.has_explicit_heat else ""
        passes.append(f"integrator {self.integrator.name}, then {walls}{heat}")
        if self.implicit_heat is not None:
            passes.append("implicit heat: backward Euler by preconditioned CG, then the enthalpy update")
        if self.has_kinematic:
            passes.append(f"kinematic advection through the velocity field ({self.scene.world.advection})")
        if self.has_lifetimes:
            passes.append("ageing; the dead retired by compaction after each step() call")
        reasons = host_work_reasons(self.scene)
        if reasons:
            passes.append("launch: one launch per pass, one step at a time: " + "; ".join(reasons))
        if self.fuses_steps:
            fused = "/".join(name for name, cls in REGISTRY.items() if cls.stages)
            team = f", run by a team of {self.team.workers} threads meeting at barriers" if self.team else ""
            passes.append(
                "launch: every pass of a step, and many steps, in one kernel launch (the list rebuild decided on the "
                f"device{team}) with {fused}; other integrators one launch per pass"
            )
        if self.refreezer is not None:
            passes.append(
                f"every {self.scene.heat.refreeze_interval} steps: refreezing (new bonds within "
                f"{self.refreezer.radius:g} between frozen particles where one was molten)"
            )
        return passes

    def field_names(self) -> list[str]:
        """Names of the per-particle fields allocated for this scene."""
        return self.particles.names()

    def memory_bytes(self) -> dict[str, int]:
        """Bytes of field memory by part."""
        fbytes = 8 if self.scene.world.precision == "f64" else 4
        out = {"particles": self.particles.nbytes()}
        if self.springs is not None:
            out["springs"] = self.springs.count * (3 * 4 + 4 * fbytes) + self.capacity * self.springs.max_bonds * 4
        if self.grid is not None:
            out["grid"] = CellGrid.footprint_bytes(self.capacity, self.grid.n_cells, self.dim)
        if self.neighbours is not None:
            out["neighbour lists"] = self.neighbours.nbytes()
        if self.half_pairs:
            out["half-list buffers"] = self.n_pair_rows * self.capacity * (self.dim + (1 if self.heat else 0)) * fbytes
        if self.reorder is not None:
            out["reorder scratch"] = self.reorder.nbytes()
        return out
