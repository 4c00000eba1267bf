"""The live controls of a simulation in one namespaced table: values a user may change while it runs (gravity,
drag, the room's temperature, the pair force's scale ...), each named `<owner>.<name>`: "world.gravity",
"world.drag", "heat.ambient", "pair.scale". The model owns "world"; each term owns its key. The window, the
classroom (through app/controller.py), state files and the API all read and set them here, so two owners can never
silently overwrite each other's names (a plain dict.update would)."""

from __future__ import annotations

import numpy as np

from ..errors import SandboxError


def owners(model, terms) -> list[tuple[str, object]]:
    """(namespace, owner) for the model ("world") and each term (its key); ValueError for a namespace twice."""
    out = [("world", model)] + [(term.key, term) for term in terms]
    seen: set[str] = set()
    for name, _ in out:
        if name in seen:
            raise ValueError(f"two owners of live controls are named {name!r}; expected one per namespace")
        seen.add(name)
    return out


def gather(model, terms, world: int = 0) -> dict:
    """Every live control as plain numbers, by its namespaced name: world `world`'s (an owner with `world_controls`
    keeps them per world, core/worlds.py; a simulation of worlds holds no other owner of controls)."""
    values = {}
    for space, owner in owners(model, terms):
        own = owner.controls(world=world) if getattr(owner, "world_controls", False) else owner.controls()
        for name, value in own.items():
            values[f"{space}.{name}"] = value
    return values


def problem(model, terms, values: dict) -> str | None:
    """What is wrong with the first of `values` (controls by namespaced name, of this simulation's names and shapes)
    that its owner's check refuses, as "control KEY = VALUE: expected ...", or None. Each owner's `control_checks()`
    gives the scene key's check a control keeps (config/schema.key_check): a state file or a script can set no value
    that the scene file could not."""
    for space, owner in owners(model, terms):
        checks = owner.control_checks()
        for name, check in checks.items():
            key = f"{space}.{name}"
            if key not in values:
                continue
            value = values[key]
            flat = np.asarray(value, dtype=float).ravel().tolist() if np.ndim(value) else float(value)
            said = check(tuple(flat) if isinstance(flat, list) else flat)
            if said:
                return f"control {key} = {value!r}: {said}"
    return None


def apply(model, terms, values: dict, world: int | None = None) -> None:
    """Set the live controls from gather()'s table (the names already checked against this simulation's): world
    `world`'s where each world has its own, every world's with None."""
    for space, owner in owners(model, terms):
        prefix = f"{space}."
        mine = {key[len(prefix) :]: value for key, value in values.items() if key.startswith(prefix)}
        if mine and getattr(owner, "world_controls", False):
            owner.apply_controls(mine, world=world)
        elif mine:
            owner.apply_controls(mine)


class Controls:
    """The live controls of a model and its terms (`sim.controls`): `values()` reads them all by namespaced name,
    `set(values)` changes some, each name and shape checked before anything changes."""

    def __init__(self, model, terms, world: int | None = None) -> None:
        """The controls of every world (`world` None: set() sets all worlds alike, values() reads world 0's) or of
        world `world` alone (a simulation of many worlds, core/worlds.py)."""
        self.model, self.terms, self.world = model, terms, world

    def values(self) -> dict:
        """Every live control by name: {"world.gravity": [0, -9.81], "world.drag": 0, "heat.ambient": 20.0, ...},
        in the scene's units."""
        return gather(self.model, self.terms, self.world or 0)

    def set(self, values: dict) -> None:
        """Set some live controls by name (as values() names them); SandboxError naming an unknown one or a value
        of the wrong shape, before anything changes."""
        self.check(values)
        apply(self.model, self.terms, values, self.world)

    def check(self, values: dict) -> None:
        """SandboxError (one line) for the first of `values` that set() would refuse: a name this scene has not, a
        value of another shape or out of its owner's range."""
        current = self.values()
        for key, value in values.items():
            if key not in current:
                raise SandboxError(f"no live control {key!r}; this scene has {', '.join(current)}")
            if np.shape(value) != np.shape(current[key]) or not np.all(np.isfinite(value)):
                raise SandboxError(f"control {key} = {value!r}; expected finite numbers shaped like {current[key]!r}")
        said = problem(self.model, self.terms, values)
        if said:
            raise SandboxError(said)


class HeldControls(Controls):
    """The live controls of a world held out of its simulation (world_view.HeldWorld): checked as world `world`'s
    are, kept in a table until the world goes back."""

    def __init__(self, model, terms, world: int, values: dict) -> None:
        super().__init__(model, terms, world)
        self.held = dict(values)

    def values(self) -> dict:
        return {key: list(v) if isinstance(v, list) else v for key, v in self.held.items()}

    def set(self, values: dict) -> None:
        self.check(values)
        self.held.update(values)
