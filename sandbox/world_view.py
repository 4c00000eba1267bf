"""One world of a simulation that holds many (core/worlds.py): `sim.world(k)` reads and steers world k as a lone
simulation of its scene is read and steered, while the simulation steps every world at once."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .core import controls as live_controls
from .errors import SandboxError
from .measure.stats import Stats
from .world_file import load_world, read_world_file, save_part, save_world
from .world_state import put_world, remove_world, reset_world, world_part, world_snapshot

# The scene keys a world of a simulation may hold of its own (Simulation's `starts`, `sandbox sweep`'s batches):
# what its particles start from and its live controls. Every other key is one for all its worlds.
WORLD_KEYS = (
    r"bodies\.\d+\.temperature",
    r"bodies\.\d+\.velocity",
    r"world\.gravity",
    r"world\.drag",
    r"heat\.ambient",
    r"heat\.sources\.\d+\.temperature",
    r"molecular\.walls\.\d+\.temperature",
    r"molecular\.heater\.power",
    r"molecular\.lid\.pressure",
)


def one_world(sim, what: str) -> None:
    """SandboxError where `sim` holds several worlds: `what` (a picture, a cache, ...) would draw or write them over
    each other (each world keeps the scene's own box)."""
    if sim.worlds > 1:
        raise SandboxError(
            f"{what} of a simulation of {sim.worlds} worlds would draw them over each other; expected one world "
            "(sim.world(k) reads one world's particles)"
        )


class WorldView:
    """World k of `sim`: its readouts (stats), its particles (by id, as a lone run numbers them), its live controls
    and its clock. Every world steps together; a world started again (reset) counts its time from then."""

    def __init__(self, sim, k: int) -> None:
        self.sim, self.index = sim, k

    time = property(
        lambda self: self.sim.state.world_times()[self.index], doc="simulated time since the world (re)started"
    )
    step_count = property(lambda self: self.sim.step_count, doc="steps the simulation has taken (every world's)")

    def reset(self) -> None:
        """Start this world again from the scene's initial state, its clock from 0; the other worlds run on as they
        were, and the live controls stay as they are (world_state.py)."""
        reset_world(self.sim, self.index)

    def remove(self) -> None:
        """Take this world out of use: the last world in use moves into its index (world_state.remove_world), so a
        holder of world views asks for them again by index."""
        remove_world(self.sim, self.index)

    def snapshot(self) -> dict:
        """This world's state now, as a lone run of its scene holds it (world_state.py): for restore()."""
        return world_snapshot(self.sim, self.index)

    def restore(self, snap: dict) -> None:
        """Put this world back as snapshot() saw it (its clock too); the other worlds run on untouched."""
        put_world(self.sim, self.index, snap)

    def save(self, path) -> Path:
        """Write this world's state file (a lone run's format: `sandbox.resume` opens it); returns the path written."""
        return save_world(self.sim, self.index, path)

    def load(self, path) -> None:
        """Put a state file of this scene (a lone run's or a world's) into this world alone, its live controls too;
        SandboxError (one line) where it does not fit, before anything changes."""
        load_world(self.sim, self.index, path)

    @property
    def controls(self) -> live_controls.Controls:
        """This world's live controls by namespaced name (values(), set({...})): each world holds its own (the owners
        a simulation of worlds may hold all keep them per world: assembly.refuse_worlds)."""
        return live_controls.Controls(self.sim.model, self.sim.terms, self.index)

    def stats(self, pair_energy: bool = True) -> Stats:
        """This world's energies, temperatures and counts now (Simulation.stats)."""
        return self.sim.stats(pair_energy, world=self.index)

    def slots(self) -> np.ndarray:
        """The storage slots of this world's live particles (its block's live ones), ordered by particle id."""
        first, n = self.sim.state.particles.block(self.index)
        ident = self.sim.particles.ident.to_numpy()[first : first + n]
        return first + np.argsort(ident, kind="stable")

    def field(self, name: str) -> np.ndarray:
        """Per-particle field `name` ("x", "v", "T", "mass", ...) of this world's live particles, by id: (N,) or
        (N, D)."""
        return getattr(self.sim.particles, name).to_numpy()[self.slots()]

    def positions(self) -> np.ndarray:
        """Live positions, (N, D), by particle id."""
        return self.field("x")

    def velocities(self) -> np.ndarray:
        """Live velocities, (N, D), by particle id."""
        return self.field("v")

    def temperatures(self) -> np.ndarray:
        """Live temperatures (degrees), (N,), by particle id."""
        return self.field("T")


class HeldWorld:
    """A world held out of its simulation (a paused classroom tab: the simulation steps its other worlds on): its
    state as a lone run holds it (world_state.world_part) and its live controls, read and changed as a WorldView's
    are (controls, reset, snapshot and restore for undo, save and load); `put(k)` puts it back as world k."""

    index = None

    def __init__(self, sim, part: dict, controls: dict) -> None:
        self.sim, self.part = sim, part
        self.controls = live_controls.HeldControls(sim.model, sim.terms, 0, controls)

    @classmethod
    def take(cls, sim, k: int) -> HeldWorld:
        """World k's state and controls now (the world stays in the simulation: the caller takes it out)."""
        return cls(sim, world_snapshot(sim, k), live_controls.Controls(sim.model, sim.terms, k).values())

    time = property(lambda self: float(self.part["clock.time"]), doc="simulated time since the world (re)started")

    def put(self, k: int) -> None:
        """Put this state and its own controls into world k of the simulation (world_state.put_world)."""
        put_world(self.sim, k, self.part)
        live_controls.Controls(self.sim.model, self.sim.terms, k).set(self.controls.values())

    def reset(self) -> None:
        """The scene's initial state, clock from 0; the controls stay (as WorldView.reset leaves them)."""
        self.part = world_part(self.sim, self.sim._initial, 0)

    def snapshot(self) -> dict:
        return {key: value.copy() if hasattr(value, "copy") else value for key, value in self.part.items()}

    def restore(self, snap: dict) -> None:
        self.part = {key: value.copy() if hasattr(value, "copy") else value for key, value in snap.items()}

    def save(self, path) -> Path:
        """Write the held state as a world's state file; returns the path written."""
        return save_part(self.sim, self.part, self.controls.values(), path)

    def load(self, path) -> None:
        """Hold a state file of this scene instead (checked as WorldView.load checks it)."""
        part, controls = read_world_file(self.sim, path, self.part, self.controls.values())
        self.part = part
        self.controls.held.update(controls)
