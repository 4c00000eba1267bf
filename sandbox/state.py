"""The simulation's state from the host: snapshots (every particle and spring field, the clock, emitter counters),
restoring one exactly, reset, and NumPy readouts of the live particles. A mixin of Simulation."""

import numpy as np

from .core import transfer
from .core.model import ENTHALPY_LAW, material_column

SPRING_ARRAYS = ("i", "j", "rest", "ks", "kd", "alive", "factor", "bonds")  # what refreezing changes (and `created`)


class StateAccess:
    """Simulation's snapshots and readouts."""

    def snapshot(self) -> dict[str, np.ndarray]:
        """Copies of every state field, particles and springs (for reset, and tests)."""
        self.check_alive()
        p = self.particles
        snap = {"time": self.time, "step": self.step_count, "next_ident": p.next_ident}
        snap["frames"] = self.frames_done
        if self.emitters is not None:
            snap["emitters"] = (list(self.emitters.serial), list(self.emitters.carry), list(self.emitters.emitted))
        names = self.field_names()
        fields = [p.n] + [getattr(p, name) for name in names]
        if self.springs is not None:
            fields += [self.springs.created, self.springs.span] + [getattr(self.springs, n) for n in SPRING_ARRAYS]
        # one copy kernel for all of them (a host read of a 0-d field compiles a reader kernel of its own)
        n, *arrays = transfer.download(fields)
        snap["n"] = int(n)
        snap.update(zip(names, arrays))
        if self.springs is not None:
            created, span, *spring_arrays = arrays[len(names) :]
            snap["spring_created"], snap["spring_span"] = int(created), int(span)
            snap.update((f"spring_{name}", a) for name, a in zip(SPRING_ARRAYS, spring_arrays))
        return snap

    def restore(self, snap: dict) -> None:
        """Put the state back exactly as `snapshot()` saw it."""
        p = self.particles
        p.next_ident = snap["next_ident"]
        pairs = [(p.n, snap["n"])] + [(getattr(p, name), snap[name]) for name in self.field_names()]
        if self.springs is not None:
            pairs += [(getattr(self.springs, name), snap[f"spring_{name}"]) for name in SPRING_ARRAYS]
            pairs += [(self.springs.created, snap["spring_created"]), (self.springs.span, snap["spring_span"])]
        transfer.upload(pairs)
        self.time = snap["time"]
        self.step_count = snap["step"]
        self.frames_done = snap["frames"]
        if self.emitters is not None:
            serial, carry, emitted = snap["emitters"]
            self.emitters.serial, self.emitters.carry, self.emitters.emitted = list(serial), list(carry), list(emitted)
        if self.heat is not None:
            self.heat.set_time(self.time)
        if self.neighbours is not None:
            self.neighbours.invalidate()
        self.restart_wall_gauge()

    def mark_initial(self) -> None:
        """Make the current state the one reset() returns to."""
        self._initial = self.snapshot()
        self._spring_omega0 = self._snapshot_omega_max(self._initial)

    def reset(self) -> None:
        """Back to the scene's initial state."""
        self.restore(self._initial)

    def positions(self) -> np.ndarray:
        """Active positions, (N, D) NumPy copy."""
        return self.particles.x.to_numpy()[: int(self.particles.n[None])]

    def velocities(self) -> np.ndarray:
        return self.particles.v.to_numpy()[: int(self.particles.n[None])]

    def temperatures(self) -> np.ndarray:
        return self.particles.T.to_numpy()[: int(self.particles.n[None])]

    def set_temperatures(self, temperatures: np.ndarray) -> None:
        """Set the active particles' temperatures (degrees, (N,)); enthalpies and liquid flags follow."""
        n = int(self.particles.n[None])
        full = self.particles.T.to_numpy()
        full[:n] = temperatures
        self.particles.T.from_numpy(full)
        self.sync_temperatures()

    def melt_fractions(self) -> np.ndarray:
        """Melt fraction phi in [0, 1] of the active particles, (N,) (0 without heat)."""
        n = int(self.particles.n[None])
        if self.heat is None:
            return np.zeros(n)
        from .physics.phase import temperature_np

        ids = self.particles.material.to_numpy()[:n]
        mats = [self.scene.materials[name] for name in self.material_names]
        law = [material_column(mats, ids, name) for name in ENTHALPY_LAW]
        return temperature_np(self.particles.h.to_numpy()[:n], *law)[1]

    def forces(self) -> np.ndarray:
        """Forces of the last evaluation, (N, D)."""
        return self.particles.f.to_numpy()[: int(self.particles.n[None])]
