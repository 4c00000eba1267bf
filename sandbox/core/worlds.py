"""Worlds: K copies of one scene held by one simulation and stepped by the same kernels, one launch a pass for all.

Each particle carries the index of its world (`particles.world`, allocated only where K > 1); nothing crosses
worlds: the cell grid keys its cells by (world, cell) (physics/grid.py), so no pair, heat flow or new bond joins two
worlds, and a spring only ever joins particles built in one. Positions stay in the scene's own box, world by world:
walls, heat sources and periodic wraps act as in a lone run.

A live control that each world sets for itself (gravity, drag, the air's and the heat sources' temperatures) is a
field of K entries where K > 1 and the lone run's 0-d field where K = 1: `per_world` makes it, `at` reads it in a
kernel and `world_of` says which entry a particle reads, so a simulation of one world compiles exactly the kernels it
did before worlds existed (its fast paths stay bit for bit).
"""

import numpy as np
import taichi as ti

MAX_WORLDS = 4096  # worlds one simulation may hold (a batch's fields grow with it; a class is 30)


def per_world(count: int, dtype, dim: int | None = None):
    """A control field for `count` worlds: shape () where count is 1 (the lone run's), else (count,); a vector of
    `dim` entries per world where `dim` is given."""
    shape = () if count == 1 else (count,)
    return ti.field(dtype, shape=shape) if dim is None else ti.Vector.field(dim, dtype, shape=shape)


@ti.func
def at(field: ti.template(), w):
    """World w's entry of a `per_world` field (the one entry of a lone run's, whatever w)."""
    if ti.static(len(field.shape) == 0):
        return field[None]
    else:
        return field[w]


@ti.func
def put_at(field: ti.template(), w, value):
    """Set world w's entry of a `per_world` field (the one entry of a lone run's, whatever w)."""
    if ti.static(len(field.shape) == 0):
        field[None] = value
    else:
        field[w] = value


def per_world_table(count: int, dtype, entries: int):
    """A control or gauge of `entries` items (heat sources, walls) for `count` worlds: shape (entries,) where count
    is 1 (the lone run's), else (count, entries)."""
    return ti.field(dtype, shape=entries if count == 1 else (count, entries))


@ti.func
def entry(table: ti.template(), w, k):
    """Item k of world w in a `per_world_table` (item k of a lone run's, whatever w)."""
    if ti.static(len(table.shape) == 1):
        return table[k]
    else:
        return table[w, k]


@ti.func
def clear_table(table: ti.template()):
    """Every item of every world of a `per_world_table` to 0 (range loops: it runs nested in fused steps too)."""
    if ti.static(len(table.shape) == 1):
        for k in range(table.shape[0]):
            table[k] = 0
    else:
        for w, k in ti.ndrange(table.shape[0], table.shape[1]):
            table[w, k] = 0


@ti.func
def add_to_entry(table: ti.template(), w, k, value):
    """Add `value` to item k of world w in a `per_world_table`."""
    if ti.static(len(table.shape) == 1):
        table[k] += value
    else:
        table[w, k] += value


@ti.func
def add_at(field: ti.template(), w, value):
    """Add `value` to world w's entry of a `per_world` field (a lone run's 0-d field: summed per thread)."""
    if ti.static(len(field.shape) == 0):
        field[None] += value
    else:
        ti.atomic_add(field[w], value)


@ti.func
def world_of(particles: ti.template(), i):
    """The world particle i belongs to: 0 in a lone run (no field is read)."""
    if ti.static(particles.worlds):
        return particles.world[i]
    else:
        return 0


def host_values(field, count: int) -> np.ndarray:
    """Every world's value of a `per_world` field as a NumPy array of `count` rows ((count,) or (count, dim))."""
    if count == 1:
        return np.asarray(field[None].to_numpy() if hasattr(field[None], "to_numpy") else field[None])[None]
    return field.to_numpy()


def world_entry(field, count: int, k: int):
    """World k's value of a `per_world` field (a float, or a list for a vector field)."""
    value = host_values(field, count)[k]
    return [float(v) for v in value] if np.ndim(value) else float(value)


def set_world_entry(field, count: int, k: int | None, value) -> None:
    """Set world k's value of a `per_world` field (k None: every world's)."""
    if count == 1:  # the lone run's 0-d field: one element written
        field[None] = value.tolist() if isinstance(value, np.ndarray) else value
        return
    data = field.to_numpy()
    if k is None:
        data[:] = value
    else:
        data[k] = value
    field.from_numpy(data)


def check_count(worlds) -> int:
    """`worlds` as a count of worlds; ValueError naming what was expected."""
    if isinstance(worlds, bool) or not isinstance(worlds, (int, np.integer)) or not 1 <= int(worlds) <= MAX_WORLDS:
        raise ValueError(f"worlds = {worlds!r}: expected a whole number from 1 to {MAX_WORLDS}")
    return int(worlds)
