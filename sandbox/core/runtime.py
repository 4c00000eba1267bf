"""Taichi start-up: one place that calls ti.init, so the backend and float precision are chosen once per process.

Taichi keeps one runtime per process; asking for a different backend or precision resets it, which invalidates every
field allocated before (a Simulation built earlier must not be used after that).
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import platform
import weakref
from pathlib import Path

import taichi as ti

from ..errors import SandboxError
from . import taichi_compat
from .cores import usable_cores
from .threads import pin_workers

ARCHES = ("auto", "cpu", "cuda", "vulkan", "metal")
PRECISIONS = ("f32", "f64")

_current: tuple[str, str, bool] | None = None  # (arch, precision, kernel profiler on)
_owns_process = False  # own_process() was called: process-wide tuning of Taichi is allowed
_reset_hooks: list = []  # called when the runtime is dropped (runtime.on_reset)
_generation = 0  # counts Taichi starts: what was built under an earlier one is gone
_ndarrays: weakref.WeakSet = weakref.WeakSet()  # ndarrays made by ndarray(): detached from their runtime at reset()


def _arch_value(name: str):
    return {"cpu": ti.cpu, "cuda": ti.cuda, "vulkan": ti.vulkan, "metal": ti.metal}[name]


def own_process() -> None:
    """The sandbox owns this process (its command line, its tests): from the next Taichi start on, Taichi's CPU
    workers are pinned one per core (threads.py), compile-error excerpts are formatted the lighter way and kernel
    sources are read once (taichi_compat). A program that embeds the sandbox beside its own Taichi code keeps Taichi's
    behaviour unless it calls this too."""
    global _owns_process
    _owns_process = True


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
    if _current is not None and _current[1:] == (precision, profile) and arch in ("auto", running_arch()):
        return running_arch()  # what runs is what was asked for (auto: whatever runs); a restart would drop it all
    if _owns_process:
        taichi_compat.lighten_kernel_debug_info()
        taichi_compat.cache_kernel_sources()
        taichi_compat.serialize_loops_on_one_thread()
    fp = ti.f32 if precision == "f32" else ti.f64
    kwargs = dict(default_fp=fp, offline_cache=True, kernel_profiler=profile)
    if "TI_LOG_LEVEL" not in os.environ:  # Taichi warns when ti.init overrides the variable
        kwargs["log_level"] = ti.ERROR
    kwargs["cpu_max_num_threads"] = cpu_threads_wanted()
    if _current is not None:
        _forget_copiers()
        ti.reset()
    with contextlib.redirect_stdout(io.StringIO()):  # Taichi prints "[Taichi] Starting on arch=..." on stdout
        ti.init(arch=ti.cuda if arch == "auto" else _arch_value(arch), **kwargs)
    _current = (arch, precision, profile)
    global _generation
    _generation += 1
    if _owns_process and running_arch() == "cpu":
        pin_workers(taichi_compat.cpu_threads())
    return running_arch()


without_cfg_pass = taichi_compat.without_cfg_pass

MAX_CPU_THREADS = 256


def cpu_threads_wanted() -> int:
    """Taichi's CPU worker threads: SANDBOX_CPU_THREADS where set (1 to MAX_CPU_THREADS; SandboxError otherwise: 0
    crashed Taichi, a huge count would start that many threads), else a worker per core this process may use
    (Taichi alone would start one per core of the machine, also those the process may not run on)."""
    text = os.environ.get("SANDBOX_CPU_THREADS", "").strip()
    if not text:
        return usable_cores()
    if not (text.isascii() and text.isdigit()) or not 1 <= int(text) <= MAX_CPU_THREADS:
        raise SandboxError(
            f"SANDBOX_CPU_THREADS={text[:40]!r}: expected a whole number of threads from 1 to {MAX_CPU_THREADS}"
        )
    return int(text)


def reset() -> None:
    """Drop the Taichi runtime and every field in it; the next init() starts afresh.

    Taichi allows about 512 SNode trees per runtime and every field made after the first kernel launch is a tree of
    its own, so a process that builds many simulations (the test session, `sandbox study`, `sandbox bench`) resets
    between independent parts. Objects built before a reset must not be used after it.
    """
    global _current
    if _current is not None:
        _forget_copiers()
        for array in list(_ndarrays):
            taichi_compat.detach_ndarray(array)
        _ndarrays.clear()
        ti.reset()
        _current = None


def ndarray(dtype, shape: tuple[int, ...]):
    """A Taichi ndarray of `dtype` and `shape` in the running runtime, which reset() detaches from it: Taichi 1.7
    frees an ndarray's memory by address when Python collects it, and one collected after a reset could free the
    array of the next runtime that took the same address."""
    array = ti.ndarray(dtype, shape=shape)
    _ndarrays.add(array)
    return array


def on_reset(hook) -> None:
    """Call `hook()` whenever the runtime is dropped (what was compiled for it, such as transfer's copy kernels,
    must be forgotten with it)."""
    if hook not in _reset_hooks:
        _reset_hooks.append(hook)


def _forget_copiers() -> None:
    for hook in _reset_hooks:
        hook()


def require(arch: str, precision: str) -> str:
    """init(), and a SandboxError when a backend asked for by name is not available here (`auto` falls back)."""
    running = init(arch, precision)
    if arch != "auto" and running != arch:
        raise SandboxError(
            f"--arch {arch}: the {arch} backend is not available on this machine (Taichi would run on {running}); "
            f"expected auto or {running}"
        )
    return running


running_arch = taichi_compat.running_arch


def generation() -> int:
    """Which Taichi start is running (0: none yet); fields made under an earlier one no longer exist."""
    return _generation if _current is not None else 0


def current() -> tuple[str, str, bool] | None:
    """(arch asked for, precision, kernel profiler on) of the running Taichi, or None before init()."""
    return _current


def real_dtype():
    """The Taichi float type of the running precision (ti.f32 or ti.f64)."""
    assert _current is not None, "runtime.init() must be called first"
    return ti.f32 if _current[1] == "f32" else ti.f64


@functools.cache
def _cpuinfo() -> str:
    """The start of /proc/cpuinfo (its first processor's lines); '' where there is none."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as info:
            return info.read(1 << 16)
    except OSError:
        return ""


def cpu_model() -> str:
    """The host CPU's model name (from /proc/cpuinfo, else what the platform says), for benchmark reports."""
    for line in _cpuinfo().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine() or "unknown CPU"


VECTOR_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512vl", "avx512_vnni", "amx_tile", "asimd", "sve")


def cpu_features() -> dict:
    """What a benchmark figure depends on beside the model: the CPU's vector extensions (those of VECTOR_FLAGS it
    has) and its data caches by level ({"L1d": "48K", "L2": "2048K", "L3": "...": one core's view, from sysfs)."""
    flags = set()
    for line in _cpuinfo().splitlines():
        if line.startswith(("flags", "Features")):
            flags = set(line.split(":", 1)[1].split())
            break
    caches = {}
    for index in sorted(Path("/sys/devices/system/cpu/cpu0/cache").glob("index*")):
        try:
            level, kind = (index / "level").read_text().strip(), (index / "type").read_text().strip()
            size = (index / "size").read_text().strip()
        except OSError:
            continue
        if kind in ("Data", "Unified"):
            caches[f"L{level}{'d' if kind == 'Data' else ''}"] = size
    return {"vectors": [f for f in VECTOR_FLAGS if f in flags], "caches": caches}


@functools.cache
def vector_gathers_pay() -> bool:
    """Whether loops that gather from scattered particles run faster vectorized on this CPU (Rates.blocked_rows): a
    tuning choice, never a change in what is computed beyond the order of a sum. Yes on Intel CPUs with AVX-512, no
    elsewhere (the measurements: docs/performance.md, "Why the code is shaped so"); SANDBOX_PAIR_BLOCKS=1 or 0
    decides."""
    chosen = os.environ.get("SANDBOX_PAIR_BLOCKS", "")
    if chosen in ("0", "1"):
        return chosen == "1"
    info = _cpuinfo()
    return "GenuineIntel" in info and " avx512f" in info
