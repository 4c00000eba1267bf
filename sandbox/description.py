"""What a simulation is made of, in words and bytes: the passes a step runs (`pipeline()`, from the stepping plan),
the fields allocated and their memory. A mixin of Simulation; `sandbox check` prints it."""

from .physics.grid import CellGrid


class Description:
    """Simulation's self-description."""

    def pipeline(self) -> list[str]:
        """The passes a step runs, in order, in words: the stepping plan's own lists (step/plan.py)."""
        return self.plan.lines()

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
