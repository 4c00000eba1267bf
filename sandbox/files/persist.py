"""Save a simulation's state to one file and put it back bit for bit.

The file is a NumPy `.npz` archive (no extra dependency, readable from any NumPy): a `meta` entry holds JSON (the
format, the sandbox and Taichi versions, the scene as its raw table and path, backend, precision, threads, the
integrator, the frame count, the live controls such as gravity), then one array per declared field and ndarray of the
State (core/state.py: `particles.x`, `springs.alive`, `neighbours.ids`, ...), and `host` holds JSON of its declared
host values (the clock, emitter counters, when the neighbour lists were built, ...).

What is saved is exactly the State's list of entries, the neighbour lists and a leapfrog integrator's synchronised
values included: they fix the order in which forces are summed, so a state without them would continue correctly
but not bit for bit. Putting a state back overwrites every entry of a simulation built from the same scene; a field
whose shape differs (another scene, another thread count) is an error, not a guess.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import taichi as ti

from .. import __version__
from ..config.scene import scene_from_dict
from ..core import controls as live_controls
from ..core import runtime, taichi_compat, transfer
from ..core.state import FIELD, NDARRAY, VALUE
from ..errors import OutputError, SandboxError, SimulationError
from ..integrators import REGISTRY
from .archive import ArchiveError, read_arrays
from .claim import partial_name
from .state_check import check_meta, check_state

FORMAT = "sandbox-state"
FORMAT_VERSION = 4  # 3: the live controls are namespaced ("world.gravity"); 4: heat sources' values are controls
MAX_META_BYTES = 16 << 20  # the meta table (the scene, the outputs' records) and the host values, each


@contextmanager
def _quiet_unrolling():
    """The one copy kernel unrolls a loop over the dozens of 0-d fields, which Taichi warns about at compile."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*unrolling more than", category=SyntaxWarning)
        yield


def _download(entries: list) -> dict[str, np.ndarray]:
    """The values of the field entries (one copy kernel for all that it can take)."""
    with _quiet_unrolling():
        return dict(zip((e.name for e in entries), transfer.download_all([e.get() for e in entries])))


class Saveable(Protocol):
    """What state files read and set of a simulation (the facade passes itself; nothing else of it is used): its
    model, state and terms, what a restore refreshes (`parts`), and its integrator, switched by name."""

    model: Any
    state: Any
    terms: Any
    parts: list
    integrator: Any
    scene: Any
    arch: str

    def set_integrator(self, name: str) -> None: ...


def controls(sim: Saveable) -> dict:
    """The live controls of the model and the terms ("world.gravity", "pair.scale", "heat.ambient" ...)."""
    return live_controls.gather(sim.model, sim.terms)


def save_state(sim: Saveable, path: str | Path, frame: int | None = None, outputs: dict | None = None) -> Path:
    """Write `sim`'s whole state to `path` (.npz added when missing) atomically (write_state_file). `frame`: the
    frame count to record (default: the frames the simulation has advanced); `outputs`: what a headless run's files
    held at this checkpoint (app/run_outputs.py), for its resume to continue them. Returns the path written."""
    entries = sim.state.entries()
    arrays = {f"field:{k}": v for k, v in _download([e for e in entries if e.kind == FIELD]).items()}
    arrays.update({f"ndarray:{e.name}": e.get().to_numpy() for e in entries if e.kind == NDARRAY})
    host = {e.name: e.get() for e in entries if e.kind == VALUE}
    state = sim.state
    meta = state_meta(sim, state.frames if frame is None else frame, state.time, state.live_count(), controls(sim))
    if outputs is not None:
        meta["outputs"] = outputs
    try:
        check_state(sim.model, sim.state, arrays, host, path)  # what would not load back is not written
    except SandboxError as exc:
        raise SimulationError(f"not saved: {exc}") from None
    return write_state_file(path, meta, arrays, host)


def state_meta(sim: Saveable, frame: int, time: float, particles: int, live: dict) -> dict:
    """A state file's meta table for `sim`'s scene at `frame` and simulated `time` (s), with `particles` live and the
    live controls `live`."""
    scene = sim.scene
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "sandbox": __version__,
        "taichi": ".".join(map(str, ti.__version__)),
        "scene": scene.source,
        "scene_path": str(scene.path),
        "scene_name": scene.name,
        "arch": sim.arch,
        "precision": scene.world.precision,
        "threads": _threads(sim.arch),
        "integrator": sim.integrator.name,
        "frame": frame,
        "time": time,
        "step": sim.state.step,
        "particles": particles,
        "controls": live,
    }


def write_state_file(path: str | Path, meta: dict, arrays: dict, host: dict) -> Path:
    """Write a state file (.npz added to `path` when missing) atomically: under a temporary name in the same folder,
    then renamed, so a crash while writing never leaves a broken file under `path`. Returns the path written;
    OutputError (one line) where it cannot be written."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    partial = partial_name(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(partial, "wb") as out:
            np.savez(out, meta=np.array(json.dumps(meta)), host=np.array(json.dumps(host)), **arrays)
            out.flush()
            os.fsync(out.fileno())
        os.replace(partial, path)
    except OSError as exc:
        raise OutputError(path, f"{exc.strerror or type(exc).__name__}; expected a writable folder") from None
    finally:
        partial.unlink(missing_ok=True)
    return path


def _threads(arch: str) -> int:
    return taichi_compat.cpu_threads() if arch == "cpu" else 1


def read_meta(path: str | Path) -> dict:
    """The `meta` table of a state file; SandboxError when the file is missing, not a state file or from another
    version of the sandbox."""
    path = Path(path)
    try:
        meta = json.loads(str(read_arrays(path, ["meta"], MAX_META_BYTES)["meta"]))
    except FileNotFoundError as exc:
        raise SandboxError(f"{path}: no such state file") from exc
    except ArchiveError as exc:
        raise SandboxError(
            f"{path}: not a readable sandbox state file: {exc}; expected an .npz written by sim.save() or "
            "--checkpoint-every"
        ) from None
    except (OSError, ValueError, KeyError, RecursionError) as exc:
        raise SandboxError(
            f"{path}: not a readable sandbox state file ({type(exc).__name__}); expected an .npz "
            "written by sim.save() or --checkpoint-every"
        ) from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise SandboxError(f"{path}: not a sandbox state file; expected one written by sim.save()")
    if meta.get("format_version") != FORMAT_VERSION or meta.get("sandbox") != __version__:
        raise SandboxError(
            f"{path}: state file of sandbox {meta.get('sandbox')!r} (format {meta.get('format_version')!r}); this is "
            f"sandbox {__version__} (format {FORMAT_VERSION}): a state resumes bit for bit only in the version that "
            "wrote it"
        )
    check_meta(meta, path)
    return meta


def saved_scene(meta: dict, path: str | Path):
    """The scene a state file's meta table holds, validated as a scene file is; a fault names the state file."""
    try:
        return scene_from_dict(meta["scene"], Path(meta["scene_path"]))
    except SandboxError as exc:
        raise SandboxError(f"{path}: the saved scene does not load: {exc}") from exc


def check_controls(saved: dict, current: dict, path: Path) -> None:
    """The file's live controls are those of this scene (the same names, each of the same shape)."""
    if set(saved) != set(current):
        raise SandboxError(f"{path}: the saved controls are {sorted(saved)}; expected this scene's {sorted(current)}")
    for key, value in current.items():
        if np.shape(saved[key]) != np.shape(value):
            raise SandboxError(f"{path}: control {key} is {saved[key]!r}; expected the shape of {value!r}")


def load_into(sim: Saveable, path: str | Path, meta: dict | None = None) -> None:
    """Put a state file saved from `sim`'s own scene back into `sim` (the window's load key, and resume): the state,
    clock, controls and integrator as saved. SandboxError when the file is of another scene, backend or thread count
    (checked before anything in `sim` changes) or does not fit it."""
    path = Path(path)
    meta = meta or read_meta(path)
    if meta["scene"] != sim.scene.source:
        raise SandboxError(
            f"{path}: saved from the scene {meta.get('scene_name')!r} as it was then; expected one saved from this "
            f"{sim.scene.name!r}"
        )
    whole = not meta.get("physical_only", False)  # a world's file holds what a step reads, not its lists
    threads = _threads(sim.arch)
    if whole and (sim.arch != meta["arch"] or threads != meta["threads"]):
        raise SandboxError(
            f"{path}: saved on {meta['arch']} with {meta['threads']} thread(s), resumed on {sim.arch} with {threads}: "
            f"the sums run in another order there; expected the same backend and thread count "
            f"(SANDBOX_CPU_THREADS={meta['threads']})"
        )
    saved, host = read_state_file(path, sim.state)
    check_controls(meta["controls"], controls(sim), path)
    said = live_controls.problem(sim.model, sim.terms, meta["controls"])
    if said:
        raise SandboxError(f"{path}: {said}")
    if meta["integrator"] not in REGISTRY:
        raise SandboxError(f"{path}: integrator {meta['integrator']!r}; expected one of {', '.join(REGISTRY)}")
    before = sim.integrator.name
    sim.set_integrator(meta["integrator"])  # before checking: its own entries are part of the state
    try:
        check_state(sim.model, sim.state, saved, host, path, physical_only=not whole)
    except SandboxError:
        sim.set_integrator(before)  # nothing of the file reached the simulation
        raise
    _put_back(sim.state, saved, host, physical_only=not whole)
    if not whole:  # what was built over the old state (the neighbour lists) is built again
        sim.state.particles_moved()
    live_controls.apply(sim.model, sim.terms, meta["controls"])
    for part in sim.parts:
        part.after_restore(sim.state)


def read_state_file(path: Path, state) -> tuple[dict, dict]:
    """A state file's arrays (by "field:name" and "ndarray:name") and host values, read within the bytes a file of
    `state`'s scene may hold; SandboxError (one line) for a damaged one. Nothing is checked against the state."""
    try:
        saved = read_arrays(path, limit=_archive_limit(state))
        host = json.loads(str(saved["host"]))
    except ArchiveError as exc:
        raise SandboxError(f"{path}: {exc}") from None
    except (OSError, ValueError, KeyError, RecursionError) as exc:
        raise SandboxError(f"{path}: the state file is damaged ({type(exc).__name__})") from exc
    if not isinstance(host, dict):
        raise SandboxError(f"{path}: the state file's host values are not a table; expected one written by save()")
    return saved, host


def _archive_limit(state) -> int:
    """Bytes a state file of `state`'s scene may hold uncompressed: four times what its entries hold now (the
    neighbour lists may have widened), plus room for the meta and host tables."""
    now = 0
    for e in state.entries():
        if e.kind != VALUE:
            current = e.get()
            items = math.prod(current.shape) * (current.n if isinstance(current, ti.MatrixField) else 1)
            now += items * 8  # no entry's type is wider than 8 bytes
    return 4 * now + 2 * MAX_META_BYTES


def _put_back(state, saved: dict, host: dict, physical_only: bool = False) -> None:
    """Every entry of `state` (the physical ones with `physical_only`) from the file's (checked) arrays and host
    values."""
    entries = state.entries(physical_only)
    pairs = [(e.get(), saved[f"{FIELD}:{e.name}"]) for e in entries if e.kind == FIELD]
    with _quiet_unrolling():
        transfer.upload_all(pairs)
    for e in entries:
        if e.kind == NDARRAY:
            values, current = saved[f"{NDARRAY}:{e.name}"], e.get()
            if tuple(current.shape) != values.shape:  # the lists were widened during the run
                e.set(runtime.ndarray(current.dtype, values.shape))
            e.get().from_numpy(values)
        elif e.kind == VALUE:
            value = host[e.name]
            e.set(tuple(value) if isinstance(e.get(), tuple) else value)
