"""Start one world of a simulation of many again (`sim.world(k).reset()`), while the others run on untouched.

World k owns one block of particle slots and one block of the built springs (core/worlds.py): its reset copies
the initial state back into those blocks (every per-particle entry of the state: positions, velocities, heat,
bonds ...; its built springs), kills the bonds it made by refreezing wherever they sit, zeroes its wall gauge and
forces its neighbour-list rows to be rebuilt at the next step (its reference positions put far away, so its world
alone is found stale: the other worlds' rows, and so their sums, are left as they were). The world's clock starts
again (WorldView.time); the live controls stay as they are, as Simulation.reset leaves them.
"""

from __future__ import annotations

import numpy as np

from .core import transfer
from .core.state import FIELD
from .core.worlds import set_world_entry
from .errors import SandboxError

FAR = 1e30  # a reference position no particle is within half a skin of


def reset_world(sim, k: int) -> None:
    """Put world k of `sim` back to its initial state (module docstring). SandboxError where the integrator keeps
    values of its own between steps (the leapfrog family's synchronised velocities): they are not yet put back."""
    state, initial = sim.state, sim._initial
    if any(e.name.startswith("integrator.") for e in state.entries()):
        raise SandboxError(
            f"world {k}: a world of a {sim.integrator.name} simulation cannot yet start again alone; expected an "
            "integrator that keeps nothing between steps (symplectic_euler, forward_euler, midpoint, rk4)"
        )
    worlds = sim.worlds
    each = state.live_count() // worlds
    rows = slice(k * each, (k + 1) * each)
    particle_entries = [e for e in state.entries(physical_only=True) if e.kind == FIELD and e.rows == "particles"]
    fields = [e.get() for e in particle_entries]
    now = transfer.download_all(fields)
    for entry, data in zip(particle_entries, now):
        data[rows] = initial[entry.name][rows]
    writes = list(zip(fields, now))
    springs = state.springs
    if springs is not None:
        writes += _springs_back(springs, initial, k, worlds, each)
    transfer.upload_all(writes)
    hood = sim.hood
    if hood is not None and hood.lists is not None:
        x_ref = hood.lists.x_ref.to_numpy()
        x_ref[rows] = FAR
        hood.lists.x_ref.from_numpy(x_ref)
    set_world_entry(sim.model.domain.impulse, worlds, k, 0.0)
    state.world_started[k] = state.time
    sim.broken = None


def _springs_back(springs, initial: dict, k: int, worlds: int, each: int) -> list:
    """(field, values) writes that put world k's built springs back and kill the bonds its particles made since."""
    built = springs.built_count // worlds
    block = slice(k * built, (k + 1) * built)
    names = ("i", "j", "rest", "ks", "kd", "factor", "alive")
    fields = [getattr(springs, name) for name in names]
    now = dict(zip(names, transfer.download_all(fields)))
    for name in names:
        now[name][block] = initial[f"springs.{name}"][block]
    mine = (now["i"] >= k * each) & (now["i"] < (k + 1) * each)
    elsewhere = np.ones(len(mine), bool)
    elsewhere[block] = False
    # bonds world k made by refreezing, in spare slots or in slots another world's broken bonds left: gone, as its
    # particles' bond lists were put back
    now["alive"][mine & elsewhere] = 0
    created = springs.created.to_numpy()
    created[k] = initial["springs.created"][k]
    return [(getattr(springs, name), now[name]) for name in names] + [(springs.created, created)]
