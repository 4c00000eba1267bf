"""Save a simulation's whole state to one file and resume it bit for bit.

The file is a NumPy `.npz` archive (no extra dependency, readable from any NumPy): a `meta` entry holds JSON (the
format, the sandbox and Taichi versions, the scene as its raw table and path, backend, precision, threads, the frame
count), then one array per Taichi field and ndarray the simulation owns, named by where it lives
(`particles.x`, `springs.alive`, `neighbours.ids`, ...), and `host` holds JSON of the plain numbers the Python side
keeps (clock, step count, emitter counters, when the neighbour lists were built, ...).

Everything is saved rather than a chosen list: the neighbour lists, cell order and half-list buffers decide the order
in which forces are summed, so a state without them would continue correctly but not bit for bit. Resuming builds
the simulation from the saved scene, then overwrites every field and number with the saved ones; a field whose shape
differs (another scene, another thread count) is an error, not a guess.
"""

from __future__ import annotations

import json
import os
import warnings
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import taichi as ti

from .. import __version__
from ..core import runtime, taichi_compat, transfer
from ..errors import SandboxError

FORMAT = "sandbox-state"
FORMAT_VERSION = 1
# configuration, or of this process
SKIPPED = {"scene", "built", "_initial", "loops", "arch", "runtime_generation", "plan"}
_HOST_TYPES = (bool, int, float, str, type(None))


def _is_field(value) -> bool:
    return isinstance(value, ti.Field)


def _is_ndarray(value) -> bool:
    return isinstance(value, ti.lang._ndarray.Ndarray)


def _is_part(value) -> bool:
    """An object whose attributes are walked (a component of the simulation): the sandbox's own, or a Taichi
    data-oriented object from elsewhere (a body-force term registered by a user)."""
    module = type(value).__module__
    if module.startswith("sandbox."):
        return not module.startswith(("sandbox.config.",))
    return getattr(type(value), "_data_oriented", False) is True


def _host_value(value) -> bool:
    if isinstance(value, _HOST_TYPES):
        return True
    return isinstance(value, list | tuple) and all(isinstance(v, bool | int | float) for v in value)


def walk(sim) -> tuple[dict, dict, dict]:
    """Everything a simulation holds, by dotted path: (fields, ndarrays as (owner, attribute), host values as
    (owner, attribute)). Each field is listed once, under the first path that reaches it."""
    fields: dict = {}
    ndarrays: dict = {}
    host: dict = {}
    seen = {id(sim)}
    queue = [(sim, "sim")]
    while queue:
        obj, path = queue.pop(0)
        for name, value in vars(obj).items():
            if name in SKIPPED or name.startswith("__"):
                continue
            where = f"{path}.{name}" if path != "sim" else name
            if isinstance(value, list | tuple) and value and (_is_field(value[0]) or _is_part(value[0])):
                for k, item in enumerate(value):  # a list of fields, or of components (the body-force terms)
                    if id(item) in seen:
                        continue
                    if _is_field(item):
                        seen.add(id(item))
                        fields[f"{where}.{k}"] = item
                    elif _is_part(item):
                        seen.add(id(item))
                        queue.append((item, f"{where}.{k}"))
            elif _is_field(value):
                if id(value) not in seen:
                    seen.add(id(value))
                    fields[where] = value
            elif _is_ndarray(value):
                if id(value) not in seen:
                    seen.add(id(value))
                    ndarrays[where] = (obj, name)
            elif _is_part(value):
                if id(value) not in seen:
                    seen.add(id(value))
                    queue.append((value, where))
            elif _host_value(value):
                host[where] = (obj, name)
    return fields, ndarrays, host


@contextmanager
def _quiet_unrolling():
    """The one copy kernel unrolls a loop over the dozens of 0-d fields, which Taichi warns about at compile."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*unrolling more than", category=SyntaxWarning)
        yield


def _download(sim, fields: dict) -> dict[str, np.ndarray]:
    """Every field's values. The particle and spring fields go through the copy kernel snapshot() compiled when the
    simulation was built (the same list, so no compile), the rest through one more (and per-field for the few a copy
    kernel cannot take: 3D grids)."""
    from ..state import SPRING_ARRAYS

    snapped = [getattr(sim.particles, name) for name in sim.field_names()]
    if sim.springs is not None:
        snapped += [getattr(sim.springs, name) for name in SPRING_ARRAYS]
    by_id = {id(f): name for name, f in fields.items()}
    first = [by_id[id(f)] for f in snapped if id(f) in by_id]
    rest = [name for name, f in fields.items() if transfer.batchable(f) and name not in set(first)]
    out = {}
    with _quiet_unrolling():
        for names in (first, rest):
            out.update(zip(names, transfer.download([fields[name] for name in names])))
    for name, f in fields.items():
        if name not in out:
            out[name] = f.to_numpy()
    return out


def save_state(sim, path: str | Path, frame: int | None = None) -> Path:
    """Write `sim`'s whole state to `path` (.npz added when missing) atomically: written under a temporary name in
    the same folder and renamed, so a crash while writing never leaves a broken file under `path`. `frame`: the
    frame count to record (default: the frames the simulation has advanced). Returns the path written."""
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    fields, ndarrays, host = walk(sim)
    arrays = {f"field:{k}": v for k, v in _download(sim, fields).items()}
    arrays.update({f"ndarray:{k}": getattr(owner, name).to_numpy() for k, (owner, name) in ndarrays.items()})
    scene = sim.scene
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "sandbox": __version__,
        "taichi": ".".join(map(str, ti.__version__)),
        "scene": scene.source,
        "scene_path": str(scene.path),
        "scene_name": scene.name,
        "arch": sim.arch,
        "precision": scene.world.precision,
        "threads": taichi_compat.cpu_threads() if sim.arch == "cpu" else 1,
        "integrator": sim.integrator.name,
        "frame": sim.frames_done if frame is None else frame,
        "time": sim.time,
        "step": sim.step_count,
        "particles": int(sim.particles.n[None]),
    }
    host_values = {k: getattr(owner, name) for k, (owner, name) in host.items()}
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.stem}.partial.npz")
    try:
        with open(partial, "wb") as out:
            np.savez(out, meta=np.array(json.dumps(meta)), host=np.array(json.dumps(host_values)), **arrays)
            out.flush()
            os.fsync(out.fileno())
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def read_meta(path: str | Path) -> dict:
    """The `meta` table of a state file; SandboxError when the file is missing, not a state file or from another
    version of the sandbox."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
    except FileNotFoundError as exc:
        raise SandboxError(f"{path}: no such state file") from exc
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError, json.JSONDecodeError) as exc:
        raise SandboxError(
            f"{path}: not a readable sandbox state file ({type(exc).__name__}); expected an .npz "
            "written by sim.save() or --checkpoint-every"
        ) from exc
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise SandboxError(f"{path}: not a sandbox state file; expected one written by sim.save()")
    if meta.get("format_version") != FORMAT_VERSION or meta.get("sandbox") != __version__:
        raise SandboxError(
            f"{path}: state file of sandbox {meta.get('sandbox')} (format {meta.get('format_version')}); this is "
            f"sandbox {__version__} (format {FORMAT_VERSION}): a state resumes bit for bit only in the version that "
            "wrote it"
        )
    return meta


def load_state(path: str | Path, arch: str | None = None, meta: dict | None = None, scene=None):
    """Build the simulation a state file describes and put its saved state back; returns the Simulation.
    `arch`: the backend (default: the one it was saved on); `meta`, `scene`: the file's read_meta() and the scene
    built from it, where the caller has them already. SandboxError when the file cannot be resumed here."""
    from ..config.scene import scene_from_dict
    from ..simulation import Simulation

    path = Path(path)
    meta = meta or read_meta(path)
    scene = scene or scene_from_dict(meta["scene"], Path(meta["scene_path"]))
    sim = Simulation(scene, arch=arch or meta["arch"])
    _restore_from(sim, path, meta)
    return sim


def load_into(sim, path: str | Path) -> None:
    """Put a state file saved from `sim`'s own scene back into `sim` (the window's load key): the state, clock and
    integrator as saved. SandboxError when the file is of another scene, backend or thread count (checked before
    anything in `sim` changes) or does not fit it."""
    path = Path(path)
    meta = read_meta(path)
    if meta["scene"] != sim.scene.source:
        raise SandboxError(
            f"{path}: saved from the scene {meta.get('scene_name')!r} as it was then; expected one saved from this "
            f"{sim.scene.name!r}"
        )
    _restore_from(sim, path, meta)


def _restore_from(sim, path: Path, meta: dict) -> None:
    """Check that `sim` runs where the file was saved, read it and put its state back."""
    threads = taichi_compat.cpu_threads() if sim.arch == "cpu" else 1
    if sim.arch != meta["arch"] or threads != meta["threads"]:
        raise SandboxError(
            f"{path}: saved on {meta['arch']} with {meta['threads']} thread(s), resumed on {sim.arch} with {threads}: "
            f"the sums run in another order there; expected the same backend and thread count "
            f"(SANDBOX_CPU_THREADS={meta['threads']})"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            saved = {key: data[key] for key in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise SandboxError(f"{path}: the state file is damaged ({type(exc).__name__})") from exc
    sim.set_integrator(meta["integrator"])
    _put_back(sim, saved, path)


def _put_back(sim, saved: dict, path: Path) -> None:
    fields, ndarrays, host = walk(sim)
    expected = {f"field:{k}" for k in fields} | {f"ndarray:{k}" for k in ndarrays}
    present = {k for k in saved if k.startswith(("field:", "ndarray:"))}
    if expected != present:
        missing = sorted(expected - present)[:3]
        extra = sorted(present - expected)[:3]
        raise SandboxError(f"{path}: the state does not fit its scene (missing {missing}, unexpected {extra})")
    batch, single = [], []
    for name, f in fields.items():
        values = saved[f"field:{name}"]
        want = tuple(f.shape) + ((f.n,) if isinstance(f, ti.MatrixField) else ())
        if values.shape != want:
            raise SandboxError(f"{path}: field {name} has shape {values.shape}; expected {want}")
        (batch if transfer.batchable(f) else single).append((f, values))
    with _quiet_unrolling():
        transfer.upload(batch)
    for f, values in single:
        f.from_numpy(values)
    for name, (owner, attribute) in ndarrays.items():
        values = saved[f"ndarray:{name}"]
        current = getattr(owner, attribute)
        if tuple(current.shape) != values.shape:  # the lists were widened during the run
            current = runtime.ndarray(current.dtype, values.shape)
            setattr(owner, attribute, current)
        current.from_numpy(values)
    values = json.loads(str(saved["host"]))
    for name, (owner, attribute) in host.items():
        if name in values:
            value = values[name]
            setattr(owner, attribute, tuple(value) if isinstance(getattr(owner, attribute), tuple) else value)
    if sim.heat is not None:
        sim.heat.set_time(sim.time)
