"""Every use of Taichi beyond its public API, in one place, each with a plain fallback.

The sandbox leans on seven things Taichi 1.7 has but does not document as API:

1. the control-flow-graph pass switch (`ti.cfg.cfg_optimization`), turned off around the first launch of the
   whole-step kernels (it takes most of their compile time and they run no slower without it);
2. `ti.data_oriented`'s per-instance `__getattribute__` and the `_is_wrapped_kernel` mark on kernel methods
   (oriented.py routes only kernel names through Taichi's lookup: a kernel method launches about 2x faster);
3. the source excerpt Taichi formats for every statement it parses (`ASTTransformerContext.get_pos_info`): a lighter
   formatter saves a quarter of a second of start-up;
4. the source lookups Taichi makes at every compile of every function (`kernel_impl.getsourcelines` and its textwrap
   calls): read once per function, they save a fifth of Taichi's Python-to-IR time;
5. the Python ndarray's handle to its C++ array (`Ndarray.arr`), cleared when the runtime is reset, because
   Taichi 1.7 frees an ndarray by address whenever Python collects it, in whatever runtime then runs;
6. the host's launch paths (`Kernel.__call__`, field element accessors), which launch_count.py wraps while it counts;
7. the AST transformer's `build_For`, which on one CPU thread marks each loop serialized as `ti.loop_config` does
   (Taichi's pool hands even a one-thread loop to its worker and waits).

On a Taichi version not in KNOWN_VERSIONS each falls back to the plain path and says so once (a RuntimeWarning):
the CFG pass stays on, classes are plain `ti.data_oriented`, Taichi formats its own excerpts and reads sources at
every compile, ndarrays are left as they are at a reset, counting launches is refused, and loops on one thread go
through the pool.
`tests/test_taichi_compat.py` checks that each fast path is active on the version the project pins.

The running configuration (backend, CPU worker threads, default float) is read through `ti.cfg`, which Taichi
exports.
"""

from __future__ import annotations

import functools
import importlib
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import taichi as ti

from ..errors import SandboxError

KNOWN_VERSIONS = ((1, 7),)  # (major, minor) of the Taichi releases whose internals this module knows
SUPPORTED = tuple(ti.__version__[:2]) in KNOWN_VERSIONS
_warned: set[str] = set()


def _plain_path(what: str) -> None:
    """Say once that `what` runs the plain way on this Taichi."""
    if what not in _warned:
        _warned.add(what)
        version = ".".join(map(str, ti.__version__))
        warnings.warn(f"Taichi {version} is not a version the sandbox knows: {what}", RuntimeWarning, stacklevel=3)


# ---------------------------------------------------------------------------- the running configuration
def running_arch() -> str:
    """Name of the backend Taichi is running on ('x64' and 'arm64' are reported as 'cpu')."""
    name = ti.cfg.arch.name
    return "cpu" if name in ("x64", "arm64") else name


def cpu_threads() -> int:
    """Taichi's CPU worker threads (the pool that runs parallel loops)."""
    return int(getattr(ti.cfg, "cpu_max_num_threads", 0) or os.cpu_count() or 1)


def default_fp_is_f64() -> bool:
    """Whether Taichi's default float (`float` in kernels and fields) is f64."""
    return ti.cfg.default_fp == ti.f64


# ---------------------------------------------------------------------------- 1. the CFG pass
@contextmanager
def without_cfg_pass() -> Iterator[None]:
    """Kernels first launched inside compile without Taichi's control-flow-graph optimisation pass (store-to-load
    forwarding and dead-store elimination over the whole kernel): most of the compile time of a kernel that runs
    whole steps, for no speed (`python benchmarks/cfg_pass_compile.py`). A compiled kernel keeps its code. The
    renderer's kernels do lose by it, so it is not global. Plain path: the pass stays on."""
    if not SUPPORTED or not hasattr(ti.cfg, "cfg_optimization"):
        _plain_path("the whole-step kernels compile with the CFG pass")
        yield
        return
    before = ti.cfg.cfg_optimization
    ti.cfg.cfg_optimization = False
    try:
        yield
    finally:
        ti.cfg.cfg_optimization = before


# ---------------------------------------------------------------------------- 2. data-oriented lookups
def is_kernel(value) -> bool:
    """Whether `value` (a class attribute, or a property's getter) is a Taichi kernel method."""
    return hasattr(value, "_is_wrapped_kernel")


def data_oriented_lookup(cls):
    """The `__getattribute__` that `ti.data_oriented` installed on `cls`, or None where it installs none or this
    Taichi is not known (the class then stays as Taichi made it)."""
    lookup = cls.__dict__.get("__getattribute__")
    if lookup is not None and not SUPPORTED:
        _plain_path("kernel methods launch through Taichi's attribute lookup")
        return None
    return lookup


# ---------------------------------------------------------------------------- 3. compile-error excerpts
def lighten_kernel_debug_info() -> bool:
    """Format the source excerpt of each parsed statement without textwrap (a quarter of a second of a 10k box's
    warm start-up): the line, and the node marked as Taichi marks it. Process-wide, so only where the sandbox owns
    the process (runtime.own_process). SANDBOX_TAICHI_DEBUG_INFO=full keeps Taichi's. Returns whether it is on."""
    if os.environ.get("SANDBOX_TAICHI_DEBUG_INFO") == "full":
        return False
    try:
        from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext
    except ImportError:
        ASTTransformerContext = None
    if not SUPPORTED or ASTTransformerContext is None or not hasattr(ASTTransformerContext, "get_pos_info"):
        _plain_path("compile errors are formatted by Taichi")
        return False
    taichis_own = ASTTransformerContext.get_pos_info
    if getattr(taichis_own, "lightened", False):
        return True

    def pos_info(self, node) -> str:
        try:
            where = f'File "{self.file}", line {node.lineno + self.lineno_offset}, in {self.func.func.__name__}:\n'
            if not 0 < node.lineno <= len(self.src):
                return where
            line = self.src[node.lineno - 1].rstrip()
            mark = ""
            if node.lineno == getattr(node, "end_lineno", None):
                start = self.indent + node.col_offset
                mark = " " * start + "^" * max(1, self.indent + node.end_col_offset - start)
            return f"{where}{line}\n{mark}\n"
        except (AttributeError, TypeError):  # a context that differs: Taichi's own formatting
            return taichis_own(self, node)

    pos_info.lightened = True
    ASTTransformerContext.get_pos_info = pos_info
    return True


def kernel_debug_info_lightened() -> bool:
    """Whether lighten_kernel_debug_info() is in effect."""
    try:
        from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext
    except ImportError:
        return False
    return getattr(ASTTransformerContext.get_pos_info, "lightened", False)


# ---------------------------------------------------------------------------- 4. kernel sources
def cache_kernel_sources() -> bool:
    """Read each kernel's and ti.func's source once per process: Taichi finds it again with `inspect` and rewraps each
    of its lines with textwrap at every compile of every function it inlines (a fifth of the time it takes to turn
    Python into its IR, which it does cached or not). Process-wide, so only where the sandbox owns the process
    (runtime.own_process). Returns whether it is on."""
    kernel_impl = importlib.import_module("taichi.lang.kernel_impl")
    if not SUPPORTED or not all(hasattr(kernel_impl, name) for name in ("getsourcefile", "getsourcelines", "textwrap")):
        _plain_path("kernel sources are read again at every compile")
        return False
    if kernel_sources_cached():
        return True
    kernel_impl.getsourcefile = _once_per_function(kernel_impl.getsourcefile)
    kernel_impl.getsourcelines = _once_per_function(kernel_impl.getsourcelines)
    kernel_impl.textwrap = _RememberingTextwrap(kernel_impl.textwrap)
    return True


def kernel_sources_cached() -> bool:
    """Whether cache_kernel_sources() is in effect."""
    kernel_impl = importlib.import_module("taichi.lang.kernel_impl")
    return getattr(getattr(kernel_impl, "getsourcelines", None), "cached", False)


def _once_per_function(find):
    """`find(function)`, remembered per code object (a function's source does not change while it runs); lists in
    the answer are copied, so a caller may change its own."""
    answers: dict = {}

    def remembered(function):
        code = getattr(function, "__code__", None)
        if code is None:
            return find(function)
        if code not in answers:
            answers[code] = find(function)
        answer = answers[code]
        return tuple(list(x) if isinstance(x, list) else x for x in answer) if isinstance(answer, tuple) else answer

    remembered.cached = True
    return remembered


class _RememberingTextwrap:
    """The textwrap module, with fill() and dedent() remembering their answers (they are pure functions of text)."""

    def __init__(self, module):
        self._module = module
        self.fill = functools.lru_cache(maxsize=None)(module.fill)
        self.dedent = functools.lru_cache(maxsize=4096)(module.dedent)

    def __getattr__(self, name: str):
        return getattr(self._module, name)


# ---------------------------------------------------------------------------- 5. ndarrays across a reset
def detach_ndarray(array) -> None:
    """Cut a Python ndarray from the C++ array it names, before ti.reset() frees that array: Taichi's
    `Ndarray.__del__` frees by address in whatever runtime then runs, and a new array can have the old one's address
    (an ndarray collected after a reset left the next test's neighbour lists unreadable). Afterwards its deletion
    does nothing (the reset freed its memory) and any use of it fails."""
    if not SUPPORTED or not hasattr(array, "arr"):
        _plain_path("an ndarray collected after a reset may free a newer one")
        return
    array.arr = None


# ---------------------------------------------------------------------------- 6. launch paths
def launch_paths() -> list[tuple[object, str, str]]:
    """(owner, attribute, what a call counts as) for every host path that launches a kernel: kernel calls, and
    host reads and writes of one field element (one per component of a vector or matrix element). Raises
    SandboxError on a Taichi this module does not know."""
    if not SUPPORTED:
        raise SandboxError("counting kernel launches needs Taichi 1.7 (its launch paths are not public API)")
    kernel_impl = importlib.import_module("taichi.lang.kernel_impl")
    fields = importlib.import_module("taichi.lang.field")  # `taichi.lang.field` the attribute is ti.field
    matrix = importlib.import_module("taichi.lang.matrix")
    return [
        (kernel_impl.Kernel, "__call__", "kernel"),
        (fields.ScalarField, "__getitem__", "field read"),
        (fields.ScalarField, "__setitem__", "field write"),
        (matrix, "_read_host_access", "field read"),
        (matrix, "_write_host_access", "field write"),
    ]


def has_field_info() -> bool:
    """Whether this Taichi's GGUI offers get_field_info (field_info below)."""
    try:
        from taichi.ui.utils import get_field_info  # noqa: F401, PLC0415 - GGUI's module: imported only by a window
    except ImportError:
        return False
    return True


def field_info(array):
    """GGUI's description of a field or array for the canvas's lower-level set_image (what canvas.set_image passes
    after its conversion kernel): taichi.ui.utils.get_field_info."""
    from taichi.ui.utils import get_field_info  # noqa: PLC0415 - GGUI's module: imported only by a window

    return get_field_info(array)


# ---------------------------------------------------------------------------- 7. loops on one CPU thread
def serialize_loops_on_one_thread() -> bool:
    """Compile every loop as `ti.loop_config(serialize=True)` would while Taichi runs one CPU worker thread: its
    thread pool hands even a one-thread loop to that worker and waits for it: on the 2-core Xeon three loops of 100
    items took 218 us so and 13 us run in place, of 100,000 items 348 and 117 us (`python
    benchmarks/loop_overhead.py --threads 1`). One thread is what a classroom host runs on (serve_host.py).
    Nothing changes on more threads (the pool is then worth its hand-off) or on a GPU; a loop's iterations run in
    the same order either way. Process-wide, only where the sandbox owns the process
    (runtime.own_process). Returns whether it is on."""
    try:
        from taichi.lang.ast.ast_transformer import ASTTransformer
    except ImportError:
        ASTTransformer = None
    build_for = getattr(ASTTransformer, "build_For", None)
    if not SUPPORTED or build_for is None:
        _plain_path("loops on one CPU thread go through Taichi's thread pool")
        return False
    if loops_serialized_on_one_thread():
        return True
    taichis_own = build_for

    def build_for_in_place(ctx, node):
        if ti.cfg.arch == ti.cpu and ti.cfg.cpu_max_num_threads == 1:  # what ti.loop_config(serialize=True) does
            ctx.ast_builder.parallelize(1)
            ctx.ast_builder.strictly_serialize()
        return taichis_own(ctx, node)

    build_for_in_place.in_place = True
    ASTTransformer.build_For = staticmethod(build_for_in_place)
    return True


def loops_serialized_on_one_thread() -> bool:
    """Whether serialize_loops_on_one_thread() is in effect."""
    try:
        from taichi.lang.ast.ast_transformer import ASTTransformer
    except ImportError:
        return False
    return getattr(getattr(ASTTransformer, "build_For", None), "in_place", False)
