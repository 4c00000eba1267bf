"""The live controls of a simulation in one namespaced table: values a user may change while it runs (gravity,
drag, the room's temperature, the pair force's scale ...), each named `<owner>.<name>`: "world.gravity",
"world.drag", "heat.ambient", "pair.scale". The model owns "world"; each term owns its key. The window, the
classroom (through app/controller.py), state files and the API all read and set them here, so two owners can never
silently overwrite each other's names (a plain dict.update would)."""

from __future__ import annotations


def owners(model, terms) -> list[tuple[str, object]]:
    """(namespace, owner) for the model ("world") and each term (its key); ValueError for a namespace twice."""
    out = [("world", model)] + [(term.key, term) for term in terms]
    seen: set[str] = set()
    for name, _ in out:
        if name in seen:
            raise ValueError(f"two owners of live controls are named {name!r}; expected one per namespace")
        seen.add(name)
    return out


def gather(model, terms) -> dict:
    """Every live control as plain numbers, by its namespaced name."""
    values = {}
    for space, owner in owners(model, terms):
        for name, value in owner.controls().items():
            values[f"{space}.{name}"] = value
    return values


def apply(model, terms, values: dict) -> None:
    """Set the live controls from gather()'s table (the names already checked against this simulation's)."""
    for space, owner in owners(model, terms):
        prefix = f"{space}."
        mine = {key[len(prefix) :]: value for key, value in values.items() if key.startswith(prefix)}
        if mine:
            owner.apply_controls(mine)
