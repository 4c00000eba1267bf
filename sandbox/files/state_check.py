"""A state file checked before any of it reaches a simulation: its meta table, and every entry the State declares
(core/state.py) present, of its dtype and shape, finite, and within its declared range on the rows that are live;
then the rules between entries that the kernels rely on (a live spring joins live particles, a neighbour row lists
no more than its width). Anything else is one SandboxError naming the file and what is wrong: a crafted or damaged
file never indexes out of bounds and never runs with garbage."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import taichi as ti

from ..core.ranges import Range
from ..core.runtime import ARCHES, PRECISIONS
from ..core.state import FIELD, NDARRAY, VALUE, WORLDS
from ..errors import SandboxError

_NUMPY = {ti.f32: np.float32, ti.f64: np.float64, ti.i32: np.int32, ti.u32: np.uint32, ti.i8: np.int8, ti.u8: np.uint8}
META = {  # key: (type, what it must be)
    "scene": (dict, "the scene's table"),
    "scene_path": (str, "a path"),
    "scene_name": (str, "a name"),
    "arch": (str, "a backend"),
    "precision": (str, "f32 or f64"),
    "threads": (int, "a thread count"),
    "integrator": (str, "an integrator's name"),
    "frame": (int, "a frame count"),
    "time": (float, "a time"),
    "step": (int, "a step count"),
    "particles": (int, "a particle count"),
    "controls": (dict, "the live controls"),
}


def check_meta(meta: dict, path: Path) -> None:
    """The meta table's keys present and of their types and ranges."""
    for key, (kind, what) in META.items():
        if key not in meta:
            raise SandboxError(f"{path}: the state file has no {key!r} in its meta table; expected {what}")
        value = meta[key]
        ok = isinstance(value, kind) and not isinstance(value, bool)
        if kind is float:
            ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not ok:
            raise SandboxError(f"{path}: meta {key} is {value!r}; expected {what}")
        if kind in (int, float) and value < 0:
            raise SandboxError(f"{path}: meta {key} is {value}; expected {what} >= 0")
    if meta["arch"] not in ARCHES or meta["precision"] not in PRECISIONS or meta["threads"] < 1:
        raise SandboxError(
            f"{path}: meta arch {meta['arch']!r}, precision {meta['precision']!r}, threads {meta['threads']}; expected "
            f"one of {', '.join(ARCHES)}, one of {', '.join(PRECISIONS)} and at least one thread"
        )
    if not isinstance(meta.get("physical_only", False), bool):
        raise SandboxError(f"{path}: meta physical_only is {meta['physical_only']!r}; expected true or false")
    if not isinstance(meta.get("outputs", {}), dict):
        raise SandboxError(f"{path}: meta outputs is {meta['outputs']!r}; expected the table of a run's outputs")
    for key, value in meta["controls"].items():
        flat = np.asarray(value, dtype=object).ravel()
        if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in flat):
            raise SandboxError(f"{path}: control {key} is {value!r}; expected finite numbers")


def check_state(model, state, saved: dict, host: dict, path: Path, physical_only: bool = False) -> None:
    """Every declared entry of `state` (of `model`'s scene; the physical ones with `physical_only`: a world's file)
    in the file's arrays `saved` and host values `host`: raise SandboxError for the first one that is missing or does
    not fit."""
    springs = state.springs
    env = {"capacity": model.capacity, "springs": springs.count if springs is not None else 0}
    _check_entries(model, state.entries(physical_only), lambda e: e.get(), env, saved, host, path)


def check_world_state(model, entries: list, like: dict, saved: dict, host: dict, path: Path) -> None:
    """A state file put into one world of a simulation of many (world_state.py): each of `entries` present and
    shaped like its value in `like` (the world's state as a lone run holds it), then checked as check_state checks
    a lone run's; SandboxError for the first that is missing or does not fit."""
    env = {"capacity": len(like["particles.x"]), "springs": len(like.get("springs.alive", ()))}
    _check_entries(model, entries, lambda e: like[e.name], env, saved, host, path)


def _check_entries(model, entries: list, current, env: dict, saved: dict, host: dict, path: Path) -> None:
    """check_state's checks of `entries`, each against `current(entry)` (a field, an array or a host value); `env`
    holds the capacity and spring slots they are checked within."""
    env.update(materials=len(model.material_names), groups=len(model.scene.groups) + 1)
    for e in entries:
        if e.kind == VALUE:
            _check_value(e, current(e), host, path)
        else:
            _check_array(e, current(e), saved, path)
    env["n"] = int(saved["field:particles.n"])
    _in_range("particles.n", np.asarray(env["n"]), Range(lo=0, atmost="capacity"), env, path)
    env["next_ident"] = host["particles.next_ident"]
    has_springs = "field:springs.span" in saved and any(e.name == "springs.span" for e in entries)
    span = int(saved["field:springs.span"]) if has_springs else 0
    live = {"particles": env["n"], "springs": span, WORLDS: None, "": None}
    for e in entries:
        if e.kind == VALUE:
            _in_range(e.name, np.asarray(host[e.name], dtype=float), e.valid, env, path)
        elif e.name != "neighbours.ids":
            values = saved[f"{e.kind}:{e.name}"]
            rows = live[e.rows]
            _in_range(e.name, values if rows is None else values[:rows], e.valid, env, path)
    if has_springs:
        _check_springs(saved, env["n"], span, path)
    if "ndarray:neighbours.ids" in saved and any(e.name == "neighbours.ids" for e in entries):
        _check_lists(saved, host, env, path)


def _check_value(e, current, host: dict, path: Path) -> None:
    if e.name not in host:
        raise SandboxError(f"{path}: the state file has no {e.name}; expected one saved with it")
    value = host[e.name]
    if isinstance(current, bool):
        ok = isinstance(value, bool)
    elif isinstance(current, int | float):
        ok = _same_kind(value, current)
    elif isinstance(current, list | tuple):
        ok = isinstance(value, list) and len(value) == len(current)
        ok = ok and all(_same_kind(v, c) for v, c in zip(value, current))
    else:
        ok = False
    if not ok:
        raise SandboxError(f"{path}: {e.name} is {value!r}; expected a value like {current!r}")


def _same_kind(value, current) -> bool:
    """A number of the kind `current` is: an integer where it holds one, a finite-or-not real where it holds a
    real."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    return isinstance(value, int) or not isinstance(current, int)


def _check_array(e, current, saved: dict, path: Path) -> None:
    """The file's array of entry `e` shaped and typed as `current` (a Taichi field, or a NumPy array)."""
    key = f"{e.kind}:{e.name}"
    if key not in saved:
        raise SandboxError(f"{path}: the state file has no {e.name}; expected one saved with this scene")
    values = saved[key]
    if isinstance(current, np.ndarray):
        want, dtype = current.shape, current.dtype
    elif e.kind == FIELD:
        want = tuple(current.shape) + ((current.n,) if isinstance(current, ti.MatrixField) else ())
        dtype = _NUMPY.get(current.dtype)
    else:  # NDARRAY: as many rows as the current one; its width may have grown
        want = (current.shape[0], values.shape[1] if values.ndim == 2 else -1)
        dtype = np.int32
    if values.shape != want or values.dtype != dtype:
        raise SandboxError(
            f"{path}: {e.name} is {values.dtype} of shape {values.shape}; expected {np.dtype(dtype)} of shape {want}"
        )
    if e.kind == NDARRAY and values.shape[1] < 1:
        raise SandboxError(f"{path}: {e.name} has no columns; expected at least one")


def _in_range(name: str, values: np.ndarray, valid: Range, env: dict, path: Path) -> None:
    """Raise when `values` break the range `valid` (counts named in it read from `env`)."""
    if values.size == 0:
        return
    if np.issubdtype(values.dtype, np.floating):
        if valid.finite and not np.isfinite(values).all():
            raise SandboxError(f"{path}: {name} holds a value that is not finite; expected finite numbers")
        values = values.astype(np.float64)  # compared in f64: a bound like 1e-300 would round to 0 in f32
    bounds = [
        (valid.lo, ">=", values.min() >= valid.lo if valid.lo is not None else True),
        (valid.hi, "<=", values.max() <= valid.hi if valid.hi is not None else True),
    ]
    if valid.below is not None:
        bounds.append((f"{valid.below} = {env[valid.below]}", "<", values.max() < env[valid.below]))
    if valid.atmost is not None:
        bounds.append((f"{valid.atmost} = {env[valid.atmost]}", "<=", values.max() <= env[valid.atmost]))
    for bound, relation, ok in bounds:
        if not ok:
            worst = values.min() if relation == ">=" else values.max()
            raise SandboxError(f"{path}: {name} holds {worst}; expected values {relation} {bound}")


def _check_springs(saved: dict, n: int, span: int, path: Path) -> None:
    """A live spring joins two live particles."""
    alive = saved["field:springs.alive"][:span] != 0
    for end in ("i", "j"):
        ends = saved[f"field:springs.{end}"][:span][alive]
        if ends.size and ends.max() >= n:
            raise SandboxError(f"{path}: a live spring ends at particle {ends.max()}; expected one of the {n} live")


def _check_lists(saved: dict, host: dict, env: dict, path: Path) -> None:
    """The neighbour lists: as wide as their width says, no row counting past it while they are in use, every entry
    a particle slot or a marked spring."""
    ids = saved["ndarray:neighbours.ids"]
    if ids.shape[1] != host["neighbours.width"]:
        raise SandboxError(f"{path}: neighbours.ids is {ids.shape[1]} wide; expected neighbours.width")
    listed = int(saved["field:neighbours.n_listed"])
    count = saved["field:neighbours.count"][:listed]
    if host["neighbours.usable"] and count.size and count.max() > ids.shape[1]:
        raise SandboxError(f"{path}: a neighbour row counts {count.max()}; expected at most the lists' width")
    used = np.arange(ids.shape[1])[None, :] < np.minimum(count, ids.shape[1])[:, None]
    entries = ids[:listed][used]
    if entries.size and (entries.min() < -env["springs"] or entries.max() >= env["capacity"]):
        raise SandboxError(f"{path}: the neighbour lists name a particle or spring that does not exist")
