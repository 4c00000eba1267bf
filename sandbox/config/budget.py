"""How big a scene will be, estimated from its geometry before anything is allocated (no Taichi, no arrays).

A scene that would hold more particles than `world.max_particles`, or need more memory than the machine has free,
is refused with one line naming the body and the count, instead of ending in a MemoryError or the kernel's OOM
killer halfway through building.
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..errors import SceneError

LATTICE_CELL = {"square": 1.0, "hex": math.sqrt(3) / 2, "cubic": 1.0, "fcc": math.sqrt(2) / 2}  # volume / spacing^D
PARTICLE_BYTES = 400  # every per-particle field, the cell grid's share and the snapshot copy (about 308 measured)
LIST_BYTES = {2: 200, 3: 600}  # neighbour-list row of one particle (4 bytes an entry)
SPRING_BYTES = 40  # every per-spring field
SMOKE_BYTES = 8 * 14  # per smoke cell: velocities, temperature and the pressure solve's vectors
MEMORY_SHARE = 0.8  # of the memory available now that a scene may ask for


def emitter_population(e) -> int:
    """Most particles an emitter keeps alive at once (capacity planning): all it ever emits if they never die."""
    bursts = len(e.bursts) * e.burst_count
    refill = 0
    if e.refill_density:
        if e.shape == "box":
            measure = float(np.prod(np.asarray(e.hi) - np.asarray(e.lo)))
        else:
            measure = math.pi * e.size**2 if e.shape == "disk" else 4 / 3 * math.pi * e.size**3
        refill = int(2 * e.refill_density * measure)  # the region full, and room for what flows out
    if e.lifetime <= 0:
        horizon = 0.0 if e.rate == 0 else (e.stop - e.start if math.isfinite(e.stop) else 600.0)
        return int(e.count + bursts + refill + e.rate * horizon) + 16
    longest = e.lifetime * (1 + e.lifetime_spread)
    return int(e.count + min(bursts, e.burst_count * (1 + longest)) + refill + e.rate * longest * 1.1) + 16


def body_particles(body, dim: int) -> int:
    """About how many lattice sites the body holds (its volume over the volume of one lattice cell)."""
    if body.shape in ("disk", "sphere"):
        volume = math.pi * body.radius**2 if dim == 2 else 4.0 / 3.0 * math.pi * body.radius**3
    else:
        volume = float(np.prod(np.subtract(body.hi, body.lo)))
    return int(volume / (LATTICE_CELL[body.lattice] * body.spacing**dim)) + 1


def _bonds_per_particle(body, dim: int, sites: int) -> int:
    """Springs a particle inside the body has: lattice offsets within spring_radius spacings (counted exactly up to
    4 spacings, by the ball's volume beyond), and never more than the body's other sites; 0 without springs."""
    if not body.springs:
        return 0
    r = body.spring_radius
    if r > 4:
        ball = math.pi * r**2 if dim == 2 else 4.0 / 3.0 * math.pi * r**3
        return int(min(ball / LATTICE_CELL[body.lattice], sites - 1))
    reach = int(math.ceil(r)) + 1
    offsets = sum(1 for off in np.ndindex(*(2 * reach + 1,) * dim) if 0 < math.dist(off, (reach,) * dim) <= r + 1e-9)
    return min(offsets, sites - 1)


MAX_PERIODIC_CELLS = 1 << 26


def available_memory() -> int | None:
    """Bytes of memory available now (Linux's MemAvailable), or None where it cannot be read."""
    try:
        with open("/proc/meminfo") as info:
            for line in info:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_size(
    file: str, world, bodies: list, emitters: list, has_neighbours: bool, smoke, reach_hint: float = 1.0
) -> None:
    """Refuse a scene too big to build: more particles than world.max_particles (per body, then in all), a periodic
    box of more than MAX_PERIODIC_CELLS cells of `reach_hint` (the pair cutoff, length), or an estimated footprint
    above MEMORY_SHARE of the memory available now. Raises SceneError."""
    dim, limit = world.dim, world.max_particles
    counts = []
    for i, body in enumerate(bodies):
        n = body_particles(body, dim)
        if n > limit:
            raise SceneError(
                file,
                f"bodies[{i}]",
                f"about {n:,} particles at spacing {body.spacing:g}; expected at most world.max_particles = {limit:,} "
                "(a larger spacing or a smaller body, or raise world.max_particles)",
            )
        counts.append(n)
    living = [emitter_population(e) for e in emitters]
    total = sum(counts) + sum(living)
    if total > limit:
        where, what = "bodies", "bodies and emitters"
        if sum(living) > sum(counts):  # mostly emitted: name the emitter that holds the most at once
            k = int(np.argmax(living))
            where, what = f"emitters[{k}]", f"{living[k]:,} of them living at once from this emitter"
        raise SceneError(
            file, where, f"about {total:,} particles in all ({what}); expected at most world.max_particles = {limit:,}"
        )
    if world.capacity > limit:
        raise SceneError(file, "world.capacity", f"{world.capacity:,} slots; expected at most {limit:,}")
    if world.periodic and has_neighbours:  # a periodic grid keeps every cell of the box (nothing bounds it later)
        reach = max(reach_hint, 1e-9)
        cells = math.prod(max(1, int((h - l) / reach)) for l, h in zip(world.lo, world.hi))
        if cells > MAX_PERIODIC_CELLS:
            raise SceneError(
                file,
                "world.hi",
                f"a periodic box of about {cells:,} cells of the interaction reach {reach:g}; expected at most "
                f"{MAX_PERIODIC_CELLS:,} (a smaller box or a longer cutoff)",
            )
    slots = max(world.capacity, total + total // 2)
    springs = sum(n * _bonds_per_particle(b, dim, n) // 2 for n, b in zip(counts, bodies))
    cells = 0
    if smoke is not None:
        extent = np.subtract(world.hi, world.lo)
        cells = int(np.prod(np.ceil(extent / (extent.max() / smoke.resolution))))
    need = slots * (PARTICLE_BYTES + (LIST_BYTES[dim] if has_neighbours else 0))
    need += springs * SPRING_BYTES + cells * SMOKE_BYTES
    free = available_memory()
    if free is not None and need > MEMORY_SHARE * free:
        biggest = int(np.argmax(counts)) if counts else None
        if cells * SMOKE_BYTES >= need // 2:
            where = "smoke.resolution"
        elif biggest is not None and counts[biggest] >= total // 2:
            where = f"bodies[{biggest}]"
        else:
            where = "world"
        raise SceneError(
            file,
            where,
            f"needs about {need / 2**30:.1f} GiB ({total:,} particles, {springs:,} springs, {cells:,} smoke cells), "
            f"more than the {free / 2**30:.1f} GiB of memory available; expected a smaller scene",
        )
