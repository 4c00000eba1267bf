"""Counting Taichi kernel launches from the host, on any backend.

Taichi's kernel profiler counts launches on the CPU and CUDA backends only; on Vulkan (Mesa's lavapipe, Taichi
1.7.4) turning it on crashes the process at the first launch. A launch from Python is either a call of a
`@ti.kernel` (free or on a data-oriented object) or a host read or write of one field element (`x[i]`,
`n[None] = 3`, one component of `v[i]`: Taichi launches a small accessor kernel for each), so counting those calls
counts every launch the host makes. On the CPU backend the count agrees with the profiler's (W1 at 10k particles
over 200 steps: 0.120 against 0.125 launches a step; the melting block 0.500 against 0.505).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

from ..core.taichi_compat import launch_paths


@dataclass
class Launches:
    """Launches seen inside count_launches(): `by_name` maps a kernel's qualified name (or `field read` / `field
    write`) to its count."""

    by_name: Counter = field(default_factory=Counter)

    @property
    def total(self) -> int:
        """Every launch counted."""
        return sum(self.by_name.values())


def _counting(original: Callable, launches: Launches, name_of: Callable) -> Callable:
    def counted(*args, **kwargs):
        launches.by_name[name_of(args)] += 1
        return original(*args, **kwargs)

    return counted


@contextmanager
def count_launches() -> Iterator[Launches]:
    """Count, until the block ends, every kernel launch the host makes: kernel calls and host reads and writes of
    field elements (each component of a vector or matrix element once, as Taichi launches an accessor for each)."""
    launches = Launches()
    # (owner, attribute, how a call is named): a class's method or a module's function
    patched = [
        (owner, name, (lambda args: args[0].func.__qualname__) if kind == "kernel" else (lambda args, k=kind: k))
        for owner, name, kind in launch_paths()
    ]
    originals = [(owner, name, vars(owner)[name]) for owner, name, _ in patched]
    try:
        for owner, name, name_of in patched:
            setattr(owner, name, _counting(vars(owner)[name], launches, name_of))
        yield launches
    finally:
        for owner, name, original in originals:
            setattr(owner, name, original)
