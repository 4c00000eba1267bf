"""Batched copies between host arrays and Taichi fields: one kernel launch for many fields.

Taichi's `field.from_numpy` and `field.to_numpy` compile a copy kernel for each field (measured on the 2-core
machine: about 50 ms each with a cold offline cache, 15 ms warm). Building a simulation copies some forty fields
(particles, springs, material and pair tables) and its initial snapshot copies most of them back, so those copies
were most of the start-up time. Here one kernel, specialised to a list of fields, copies them all through one flat
float array and one flat int array. Kernels are cached per list of fields (and sizes), so a repeated pattern (every
snapshot, every reset) compiles once.

The copy kernels compile without Taichi's CFG pass (taichi_compat.without_cfg_pass), as do the other kernels that run
at most once a frame (the measurements, refreezing): building a scene compiles about a tenth faster with an empty
cache, and each of those launches runs within a few hundredths of a millisecond of its speed with the pass.
"""

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import taichi as ti

from . import runtime
from .oriented import data_oriented

_INTS = (ti.i32, ti.i8, ti.i16, ti.u8, ti.u16, ti.u32)  # through int32 staging (u32 as its bits: exact everywhere)
_cache: dict = {}  # key -> _Copier; the copier holds its fields, so their ids stay unique while it is cached
_staged: list | None = None  # inside batched(): the (field, values) pairs waiting for the block's end


def _is_int(field) -> bool:
    return field.dtype in _INTS


def _is_vector(field) -> bool:
    return isinstance(field, ti.MatrixField)


def _float_staging():
    """float64 staging where the backend has it (CPU, CUDA), else float32."""
    return np.float64 if runtime.running_arch() in ("cpu", "cuda") else np.float32


@data_oriented
class _Copier:
    """Copies the leading `rows` of each field (all of its other axes) to or from flat staging arrays."""

    def __init__(self, fields: list, rows: list[int]):
        self.items = []  # (field, is_int, offset, rows, columns, components, 0-d)
        offsets = {False: 0, True: 0}
        for field, n in zip(fields, rows):
            shape = tuple(field.shape)
            zero_d = len(shape) == 0  # a 0-d field is one row
            if not (zero_d and n == 1) and (len(shape) not in (1, 2) or not 0 <= n <= shape[0]):
                raise ValueError(f"cannot batch-copy {n} rows of a field of shape {shape}")
            cols = shape[1] if len(shape) == 2 else 0
            comps = field.n if _is_vector(field) else 0
            is_int = _is_int(field)
            self.items.append((field, is_int, offsets[is_int], n, cols, comps, zero_d))
            offsets[is_int] += n * max(cols, 1) * max(comps, 1)
        self.n_float, self.n_int = offsets[False], offsets[True]
        # One loop copies everything: each top-level loop is a task that LLVM compiles on its own (about 15 ms each),
        # so items are grouped by rows and columns, and row k of every group is copied in iteration k.
        by_shape: dict[tuple[int, int], list] = {}
        for item in self.items:
            by_shape.setdefault((item[3], item[4]), []).append(item)
        # in chunks: Taichi warns about a ti.static loop of more than UNROLL_WARNING iterations
        groups = [(n, cols, chunk) for (n, cols), items in by_shape.items() for chunk in _chunks(items)]
        self.groups = _chunks(groups)
        self.longest = max((n * max(cols, 1) for n, cols, _ in groups), default=0)

    @ti.func
    def _index(self, k, cols: ti.template()):
        """Field index of flat row k: [k] for a 1D field, [k // cols, k % cols] for a 2D one."""
        if ti.static(cols):
            return ti.Vector([k // cols, k % cols])
        else:
            return ti.Vector([k])

    @ti.kernel
    def _copy(self, floats: ti.types.ndarray(ndim=1), ints: ti.types.ndarray(ndim=1), up: ti.template()):
        """Staging to fields (`up`) or fields to staging: row k of every group is copied in iteration k."""
        for k in range(self.longest):
            for chunk in ti.static(self.groups):
                for n, cols, items in ti.static(chunk):
                    if k < n * max(cols, 1):
                        idx = self._index(k, cols)
                        for field, is_int, off, _rows, _cols, comps, zero_d in ti.static(items):
                            staging = ti.static(ints if is_int else floats)
                            base = off + k * max(comps, 1)
                            if ti.static(up):
                                self._put(field, idx, zero_d, comps, staging, base)
                            else:
                                self._get(field, idx, zero_d, comps, staging, base)

    @ti.func
    def _put(self, field: ti.template(), idx, zero_d: ti.template(), comps: ti.template(), src: ti.template(), base):
        """field[idx] (field[None] when 0-d) = src[base:base + comps] (one value for a scalar field)."""
        if ti.static(zero_d and comps == 0):
            field[None] = ti.cast(src[base], field.dtype)
        elif ti.static(zero_d):
            for c in ti.static(range(comps)):
                field[None][c] = ti.cast(src[base + c], field.dtype)
        elif ti.static(comps == 0):
            field[idx] = ti.cast(src[base], field.dtype)
        else:
            for c in ti.static(range(comps)):
                field[idx][c] = ti.cast(src[base + c], field.dtype)

    @ti.func
    def _get(self, field: ti.template(), idx, zero_d: ti.template(), comps: ti.template(), dst: ti.template(), base):
        """dst[base:base + comps] = field[idx] (field[None] when 0-d; one value for a scalar field)."""
        if ti.static(zero_d and comps == 0):
            dst[base] = field[None]
        elif ti.static(zero_d):
            for c in ti.static(range(comps)):
                dst[base + c] = field[None][c]
        elif ti.static(comps == 0):
            dst[base] = field[idx]
        else:
            for c in ti.static(range(comps)):
                dst[base + c] = field[idx][c]

    def shapes(self) -> list[tuple[int, ...]]:
        """The host shape of each item: (rows[, columns][, components])."""
        out = []
        for _, _, _, n, cols, comps, zero_d in self.items:
            out.append(((n,) if not zero_d else ()) + ((cols,) if cols else ()) + ((comps,) if comps else ()))
        return out


UNROLL_WARNING = 32  # Taichi warns (SyntaxWarning) about a ti.static loop of more iterations than this


def _chunks(items: list) -> tuple:
    """`items` as consecutive tuples of at most UNROLL_WARNING each."""
    return tuple(tuple(items[i : i + UNROLL_WARNING]) for i in range(0, len(items), UNROLL_WARNING))


def _copier(fields: list, rows: list[int]) -> _Copier:
    key = (tuple(id(f) for f in fields), tuple(rows))
    copier = _cache.get(key)
    if copier is None:
        copier = _cache[key] = _Copier(fields, rows)
    return copier


@contextmanager
def batched() -> Iterator[None]:
    """Within the block, upload() queues its copies and they all run as one kernel when the block ends (each copy
    kernel is a compile at start-up: a simulation's build uploads its tables from half a dozen places). Code in the
    block must not read, in a kernel or from Python, a field it uploads. Nothing is copied if the block raises."""
    global _staged
    if _staged is not None:  # nested: the outer block copies
        yield
        return
    _staged = []
    try:
        yield
        pairs = _staged
    finally:
        _staged = None
    upload(pairs)


def upload(pairs: list) -> None:
    """Copy each (field, values) pair: values fill the field's leading len(values) rows, with the field's other axes
    and vector components as trailing axes; the rest of the field is left as it is. Inside batched(): queued."""
    if not pairs:
        return
    if _staged is not None:
        if {id(f) for f, _ in _staged} & {id(f) for f, _ in pairs}:  # a field again: its earlier values go first
            upload_now, _staged[:] = list(_staged), []
            _upload(upload_now)
        _staged.extend((f, np.array(v)) for f, v in pairs)  # a copy: the caller may change its array
        return
    _upload(pairs)


def _upload(pairs: list) -> None:
    fields = [f for f, _ in pairs]
    arrays = [np.asarray(v) for _, v in pairs]
    copier = _copier(fields, [len(a) if f.shape else 1 for f, a in zip(fields, arrays)])
    floats = np.zeros(max(copier.n_float, 1), _float_staging())
    ints = np.zeros(max(copier.n_int, 1), np.int32)
    for (field, is_int, off, *_), array, shape in zip(copier.items, arrays, copier.shapes()):
        if array.shape != shape:
            raise ValueError(f"values of shape {array.shape} for a field expecting {shape}")
        flat = array.reshape(-1)
        if field.dtype == ti.u32:
            flat = flat.astype(np.uint32).view(np.int32)  # the same bits: exact, where float32 staging is not
        (ints if is_int else floats)[off : off + flat.size] = flat
    with runtime.without_cfg_pass():  # see the module docstring
        copier._copy(floats, ints, True)


def download(fields: list, rows: list[int] | None = None) -> list[np.ndarray]:
    """The leading `rows` (default: all) of each field, as NumPy arrays shaped (rows[, columns][, components]) in the
    field's own precision. Each distinct `rows` compiles its own copy kernel: pass counts that do not change (not a
    live count that emitters change: copy the whole field and slice it)."""
    if not fields:
        return []
    rows = rows if rows is not None else [f.shape[0] if f.shape else 1 for f in fields]
    copier = _copier(list(fields), list(rows))
    floats = np.empty(max(copier.n_float, 1), _float_staging())
    ints = np.empty(max(copier.n_int, 1), np.int32)
    with runtime.without_cfg_pass():
        copier._copy(floats, ints, False)
    out = []
    for (field, is_int, off, *_), shape in zip(copier.items, copier.shapes()):
        size = int(np.prod(shape))
        flat = (ints if is_int else floats)[off : off + size]
        out.append(flat.reshape(shape).astype(_numpy_dtype(field)))
    return out


def _numpy_dtype(field):
    return {
        ti.f32: np.float32,
        ti.f64: np.float64,
        ti.i32: np.int32,
        ti.i8: np.int8,
        ti.i16: np.int16,
        ti.u8: np.uint8,
        ti.u16: np.uint16,
        ti.u32: np.uint32,
    }[field.dtype]


def batchable(field) -> bool:
    """Whether upload() and download() can copy this field (0-d, 1D or 2D, of a dtype they stage exactly)."""
    return len(field.shape) <= 2 and field.dtype in (ti.f32, ti.f64, ti.u32, *_INTS)


def download_all(fields: list) -> list[np.ndarray]:
    """Copies of `fields`: one copy kernel for those it can take (batchable), to_numpy for the rest (3D grids)."""
    batch = [f for f in fields if batchable(f)]
    copies = dict(zip(map(id, batch), download(batch)))
    return [copies[id(f)] if id(f) in copies else f.to_numpy() for f in fields]


def upload_all(pairs: list) -> None:
    """upload() of (field, values) pairs in one copy kernel where it can take them, from_numpy for the rest."""
    upload([(f, v) for f, v in pairs if batchable(f)])
    for f, values in pairs:
        if not batchable(f):
            f.from_numpy(values)


def forget() -> None:
    """Drop the cached copy kernels (with the runtime they were compiled for: runtime.reset())."""
    _cache.clear()


def real_fields(*tables, also: tuple = ()) -> list:
    """Taichi fields of the running float precision, shaped and filled like each of `tables` (arrays or lists),
    filled by one copy kernel together with the (field, values) pairs in `also` (a from_numpy per field costs a
    compiled kernel each)."""
    arrays = [np.asarray(t, dtype=np.float64) for t in tables]
    fields = [ti.field(float, shape=a.shape) for a in arrays]
    upload(list(zip(fields, arrays)) + list(also))
    return fields


runtime.on_reset(forget)
