"""Taichi start-up: one place that calls ti.init, so the backend and float precision are chosen once per process.

Taichi keeps one runtime per process; asking for a different backend or precision resets it, which invalidates every
field allocated before (a Simulation built earlier must not be used after that).
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Iterator
from contextlib import contextmanager

import taichi as ti

from .errors import SandboxError

ARCHES = ("auto", "cpu", "cuda", "vulkan", "metal")
PRECISIONS = ("f32", "f64")

_current: tuple[str, str, bool] | None = None  # (arch, precision, kernel profiler on)


def _arch_value(name: str):
    return {"cpu": ti.cpu, "cuda": ti.cuda, "vulkan": ti.vulkan, "metal": ti.metal}[name]


def _lighten_kernel_debug_info() -> None:
    """Taichi formats, for every statement of every kernel it parses (at each process start, warm offline cache or
    not), the source excerpt a compile error would quote, wrapped by textwrap: a quarter of a second of a 10k box's
    warm start-up on the 2-core machine. This quotes the line and marks the node as Taichi does, without the
    wrapping. SANDBOX_TAICHI_DEBUG_INFO=full keeps Taichi's own."""
    try:
        from taichi.lang.ast.ast_transformer_utils import ASTTransformerContext
    except ImportError:  # another Taichi layout: leave it alone
        return
    if os.environ.get("SANDBOX_TAICHI_DEBUG_INFO") == "full" or not hasattr(ASTTransformerContext, "get_pos_info"):
        return

    taichis_own = ASTTransformerContext.get_pos_info
    if getattr(taichis_own, "lightened", False):
        return

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
        except (AttributeError, TypeError):  # a Taichi whose context differs: its own formatting
            return taichis_own(self, node)

    pos_info.lightened = True
    ASTTransformerContext.get_pos_info = pos_info


def init(arch: str = "cpu", precision: str = "f32", profile: bool | None = None) -> str:
    """Start (or restart) Taichi on `arch` with default float `precision`; returns the backend actually running.

    `auto` prefers CUDA and otherwise uses the CPU (a software Vulkan driver is slower than the CPU backend, so it
    is only used when asked for by name). A backend that is not available falls back to the CPU, as Taichi does.
    `profile`: Taichi's kernel profiler on (the benchmark counts kernel launches with it); None keeps what runs.
    """
    global _current
    if arch not in ARCHES:
        raise ValueError(f"unknown arch '{arch}'; expected one of {', '.join(ARCHES)}")
    if precision not in PRECISIONS:
        raise ValueError(f"unknown precision '{precision}'; expected one of {', '.join(PRECISIONS)}")
    if profile is None:  # keep the running runtime's choice
        profile = _current is not None and _current[2]
    if _current == (arch, precision, profile):
        return running_arch()
    _lighten_kernel_debug_info()
    fp = ti.f32 if precision == "f32" else ti.f64
    kwargs = dict(default_fp=fp, offline_cache=True, kernel_profiler=profile)
    if "TI_LOG_LEVEL" not in os.environ:  # Taichi warns when ti.init overrides the variable
        kwargs["log_level"] = ti.ERROR
    threads = os.environ.get("SANDBOX_CPU_THREADS")
    if threads:
        kwargs["cpu_max_num_threads"] = int(threads)
    if _current is not None:
        _forget_copiers()
        ti.reset()
    with contextlib.redirect_stdout(io.StringIO()):  # Taichi prints "[Taichi] Starting on arch=..." on stdout
        ti.init(arch=ti.cuda if arch == "auto" else _arch_value(arch), **kwargs)
    _current = (arch, precision, profile)
    if running_arch() == "cpu":
        from .threads import pin_workers

        pin_workers(int(ti.lang.impl.current_cfg().cpu_max_num_threads))
    return running_arch()


@contextmanager
def without_cfg_pass() -> Iterator[None]:
    """Kernels first launched inside compile without Taichi's control-flow-graph optimisation pass (store-to-load
    forwarding and dead-store elimination over the whole kernel), which takes most of the compile time of a kernel
    that runs many whole steps (the team's and the fused steps' launch: 1.9 -> 1.1 s and 2.9 -> 2.0 s of CPU with a
    cold cache, `/tmp` scratch scripts alternating the setting) while their steps run no slower (W1 at 10k, W2, W3
    within 2%). The renderer's kernels do lose by it (a 1280x720 frame 1.95 -> 2.49 ms), so it is not global.
    Taichi reads the setting when it compiles a kernel; a compiled kernel keeps its code, wherever launched later."""
    cfg = ti.lang.impl.current_cfg()
    before = cfg.cfg_optimization
    cfg.cfg_optimization = False
    try:
        yield
    finally:
        cfg.cfg_optimization = before


def reset() -> None:
    """Drop the Taichi runtime and every field in it; the next init() starts afresh.

    Taichi allows about 512 SNode trees per runtime and every field made after the first kernel launch is a tree of
    its own, so a process that builds many simulations (the test session, `sandbox study`, `sandbox bench`) resets
    between independent parts. Objects built before a reset must not be used after it.
    """
    global _current
    if _current is not None:
        _forget_copiers()
        ti.reset()
        _current = None


def _forget_copiers() -> None:
    from . import transfer

    transfer.forget()


def require(arch: str, precision: str) -> str:
    """init(), and a SandboxError when a backend asked for by name is not available here (`auto` falls back)."""
    running = init(arch, precision)
    if arch != "auto" and running != arch:
        raise SandboxError(
            f"--arch {arch}: the {arch} backend is not available on this machine (Taichi would run on {running}); "
            f"expected auto or {running}"
        )
    return running


def running_arch() -> str:
    """Name of the backend Taichi is running on now ('x64' and 'arm64' are reported as 'cpu')."""
    name = ti.lang.impl.current_cfg().arch.name
    return "cpu" if name in ("x64", "arm64") else name


def real_fields(*tables, also: tuple = ()) -> list:
    """Taichi fields of the running float precision, shaped and filled like each of `tables` (arrays or lists),
    filled by one copy kernel together with the (field, values) pairs in `also` (see transfer.py: a from_numpy per
    field costs a compiled kernel each)."""
    import numpy as np

    from . import transfer

    arrays = [np.asarray(t, dtype=np.float64) for t in tables]
    fields = [ti.field(float, shape=a.shape) for a in arrays]
    transfer.upload(list(zip(fields, arrays)) + list(also))
    return fields


def real_dtype():
    """The Taichi float type of the running precision (ti.f32 or ti.f64)."""
    assert _current is not None, "runtime.init() must be called first"
    return ti.f32 if _current[1] == "f32" else ti.f64
