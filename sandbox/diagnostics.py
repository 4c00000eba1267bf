"""Measurements of a running simulation and the blow-up guard's verdict on them.

`Measurements` is a mixin of Simulation: one kernel (`_measure`) sums energies, temperatures, counts and the largest
speed over the particles and springs into 0-d fields, `stats()` reads them as a `Stats`, asks the guard
(guard.py) whether the state is sane, and raises a SimulationError naming the step, the particle and the likely cause
when it is not.
"""

# No `from __future__ import annotations` in a module with kernels: Taichi reads their annotations as objects.
from dataclasses import dataclass

import numpy as np
import taichi as ti

from .core import runtime
from .errors import SimulationError
from .guard import ABSOLUTE_ZERO

STAT_COLUMNS = (
    "frame",
    "time",
    "kinetic_energy",
    "potential_energy",
    "total_energy",
    "spring_energy",
    "pair_energy",
    "gravity_energy",
    "kinetic_energy_per_particle",
    "potential_energy_per_particle",
    "total_energy_per_particle",
    "pressure",
    "wall_pressure",
    "mean_temperature",
    "molten_fraction",
    "heat_content",
    "broken_springs",
    "max_speed",
    "particles",
    "step_seconds",
)


def stat_values(frame: int, stats: "Stats", step_seconds: float) -> dict:
    """The STAT_COLUMNS of frame `frame` by name: its measurements `stats` and its steps' wall time (seconds)."""
    row = {"frame": frame, "step_seconds": step_seconds}
    row.update({k: getattr(stats, k) for k in STAT_COLUMNS if k not in row})
    return row


# Sums (and maxima) of one measurement, one 0-d field each, by name -> index in Measurements._acc
SUMS = {"ke": 0, "spring": 1, "pair": 2, "grav": 3, "tsum": 4, "vmax": 5, "phi": 6, "heat": 7, "mass": 8}
SUMS.update(tcold=9, thot=10)  # the largest -T and T (degrees; -1e30 without particles): the guard's temperatures
SUMS.update(pair_virial=11, spring_virial=12)  # sums over pairs and live springs of r_ij . F_ij, r_ij = x_i - x_j
COUNTS = {"alive": 0, "meltable": 1, "bad": 2}
# _measure also reads out, after the sums and counts: the walls' momentum gauge, the particle and the spring counts
IMPULSE_AT, N_AT, CREATED_AT = len(SUMS), len(COUNTS), len(COUNTS) + 1


@dataclass
class Stats:
    """Measurements of one instant. Energies are totals over the particles in scaled units (mass x length^2 /
    time^2); the pair energy is shifted to zero at the cutoff unless pair.shift = false. Temperatures in degrees."""

    time: float
    kinetic_energy: float
    spring_energy: float
    pair_energy: float
    gravity_energy: float
    mean_temperature: float
    molten_fraction: float  # mean melt fraction of the particles of meltable materials
    heat_content: float  # sum of m h: the heat (enthalpy) in the particles, conserved without sources
    broken_springs: int
    max_speed: float
    particles: int
    pressure: float = float("nan")  # virial pressure (sum m v^2 + sum r_ij . F_ij) / (dim V), V the box's volume
    # momentum the walls took per unit time and wall area since the gauge restarted (each frame); nan without walls
    # or before any time has passed
    wall_pressure: float = float("nan")

    @property
    def potential_energy(self) -> float:
        return self.spring_energy + self.pair_energy + self.gravity_energy

    @property
    def total_energy(self) -> float:
        return self.kinetic_energy + self.potential_energy

    @property
    def kinetic_energy_per_particle(self) -> float:
        return self.kinetic_energy / self.particles if self.particles else float("nan")

    @property
    def potential_energy_per_particle(self) -> float:
        return self.potential_energy / self.particles if self.particles else float("nan")

    @property
    def total_energy_per_particle(self) -> float:
        return self.total_energy / self.particles if self.particles else float("nan")


class Measurements:
    """Simulation's measurements: _build_measurements() in its constructor, then stats() whenever asked."""

    def _build_measurements(self) -> None:
        acc = ti.f64 if self.arch in ("cpu", "cuda") else ti.f32
        # Sums (and the largest speed) for stats(), one 0-d field each: Taichi accumulates a 0-d field per thread
        # and adds once per thread at the end of a loop, but turns `field[k] += ...` into one contended atomic per
        # iteration. _measure copies them into the host arrays _acc and _count (kernel arguments: reading fields back
        # would compile a copy kernel each).
        self._sums = [ti.field(acc, shape=()) for _ in SUMS]
        self._counts = [ti.field(ti.i32, shape=()) for _ in COUNTS]
        self._acc = np.zeros(len(SUMS) + 1, np.float64 if acc == ti.f64 else np.float32)  # SUMS, IMPULSE_AT
        self._count = np.zeros(len(COUNTS) + 2, np.int32)  # counts for stats(): COUNTS, N_AT, CREATED_AT
        lo, hi = self.scene.world.lo, self.scene.world.hi
        self._box_volume = float(np.prod(np.subtract(hi, lo)))  # the pressure's V (area in 2D)
        self._gauge_since = 0.0  # the time the wall gauge restarted

    def restart_wall_gauge(self) -> None:
        """Zero the walls' momentum gauge: stats().wall_pressure averages from now (advance_frame restarts it)."""
        self.domain.impulse[None] = 0.0
        self._gauge_since = self.time

    def _wall_pressure(self) -> float:
        """The walls' gauge: momentum into them per unit time and wall area since it restarted (nan without walls
        or elapsed time)."""
        elapsed = self.time - self._gauge_since
        if not self.domain.wall_area or elapsed <= 0.0:
            return float("nan")
        return float(self._acc[IMPULSE_AT]) / (elapsed * self.domain.wall_area)  # as _measure last read it

    @ti.kernel
    def _measure(self, pair_energy: ti.template(), acc_out: ti.types.ndarray(), count_out: ti.types.ndarray()):
        p = self.particles
        acc, count = ti.static(self._sums, self._counts)
        for k in ti.static(range(len(SUMS))):
            acc[k][None] = 0
        for k in ti.static(range(len(COUNTS))):
            count[k][None] = 0
        acc[SUMS["tcold"]][None] = -1e30  # maxima start below any temperature, not at 0
        acc[SUMS["thot"]][None] = -1e30
        self.loops.light()
        for i in range(p.n[None]):
            v2 = p.v[i].dot(p.v[i])
            acc[SUMS["ke"]][None] += 0.5 * p.mass[i] * v2
            acc[SUMS["mass"]][None] += p.mass[i]
            acc[SUMS["grav"]][None] += -p.mass[i] * self.gravity[None].dot(p.x[i])
            ti.atomic_max(acc[SUMS["vmax"]][None], ti.sqrt(v2))
            finite = 1
            for a in ti.static(range(self.dim)):
                if not (ti.abs(p.x[i][a]) < 1e30 and ti.abs(p.v[i][a]) < 1e30):
                    finite = 0
            if finite == 0:
                count[COUNTS["bad"]][None] += 1
            if ti.static(self.has_heat):
                acc[SUMS["tsum"]][None] += p.T[i]
                ti.atomic_max(acc[SUMS["tcold"]][None], -p.T[i])
                ti.atomic_max(acc[SUMS["thot"]][None], p.T[i])
                acc[SUMS["heat"]][None] += p.mass[i] * p.h[i]
                if self.materials.melt[p.material[i]] < 1e29:
                    count[COUNTS["meltable"]][None] += 1
                    acc[SUMS["phi"]][None] += self.phase.fraction(p.h[i], p.material[i])
        if ti.static(self.has_springs):
            self.loops.light()
            for s in range(self.springs.span[None]):
                acc[SUMS["spring"]][None] += self.springs.energy(s)
                if self.springs.alive[s]:
                    count[COUNTS["alive"]][None] += 1
                    a, b = self.springs.i[s], self.springs.j[s]
                    d = self.domain.separation(p.x[a], p.x[b])
                    acc[SUMS["spring_virial"]][None] += -d.dot(self.springs.force(a, b, s, d))
        if ti.static(self.has_pair and pair_energy):
            self.loops.pairs()
            for i in range(p.n[None]):
                e = 0.0
                w = 0.0  # the pair virial: -d . F_i for d = x_j - x_i
                c = self.grid.cell_of(p.x[i])
                for o in range(self.grid.n_offsets):
                    nc, shift = self.grid.neighbour_cell(c, self.grid.offset(o))
                    if nc >= 0:
                        start = self.grid.cell_start[nc]
                        for k in range(start, start + self.grid.cell_count[nc]):
                            j = self.grid.sorted_ids[k]
                            if j > i:
                                d = self.grid.x_sorted[k] + shift - p.x[i]
                                r2 = d.dot(d)
                                if r2 < self.pair.cutoff**2:
                                    e += self.pair.energy(i, j, r2)
                                    w -= d.dot(self.pair.force(i, j, d, r2))
                if ti.static(self.has_springs):
                    for k in range(self.springs.max_bonds):
                        s = self.springs.bonds[i, k]
                        if s < 0:
                            break
                        j = self.springs.other_end(i, s)
                        if self.springs.alive[s] and j > i:
                            d = self.domain.separation(p.x[i], p.x[j])
                            r2 = d.dot(d)
                            if r2 < self.pair.cutoff**2:
                                e -= self.pair.energy(i, j, r2)
                                w += d.dot(self.pair.force(i, j, d, r2))
                acc[SUMS["pair"]][None] += e
                acc[SUMS["pair_virial"]][None] += w
        for k in ti.static(range(len(SUMS))):
            acc_out[k] = acc[k][None]
        for k in ti.static(range(len(COUNTS))):
            count_out[k] = count[k][None]
        acc_out[IMPULSE_AT] = self.domain.impulse[None]
        count_out[N_AT] = p.n[None]
        if ti.static(self.has_springs):
            count_out[CREATED_AT] = self.springs.created[None]

    def stats(self, pair_energy: bool = True) -> Stats:
        """Energies, temperatures and counts now. Raises SimulationError if any particle is not finite.
        pair_energy=False skips the pair energy's neighbour scan (the costliest part) and reports the last one
        measured: the window does so on most frames."""
        self.check_alive()
        pair_energy = pair_energy or self._last_pair_energy is None or not self.has_pair
        if pair_energy and self.grid is not None:
            self.grid.rebuild()
        with runtime.without_cfg_pass():  # run at most once a frame: see transfer.py's docstring
            self._measure(pair_energy, self._acc, self._count)
        acc_values, cnt_values = self._acc, self._count
        acc = {k: float(acc_values[i]) for k, i in SUMS.items()}
        if pair_energy:
            self._last_pair_energy = acc["pair"], acc["pair_virial"]
        else:
            acc["pair"], acc["pair_virial"] = self._last_pair_energy
        cnt = {k: int(cnt_values[i]) for k, i in COUNTS.items()}
        n = int(cnt_values[N_AT])
        problem = self.guard.problem(acc, cnt["bad"], self.dt, self.heat is not None)
        if problem:
            self._raise_blowup(*problem)
        return Stats(
            time=self.time,
            kinetic_energy=acc["ke"],
            spring_energy=acc["spring"],
            pair_energy=acc["pair"],
            gravity_energy=acc["grav"],
            mean_temperature=acc["tsum"] / n if (self.heat is not None and n) else float("nan"),
            molten_fraction=acc["phi"] / cnt["meltable"] if cnt["meltable"] else 0.0,
            heat_content=acc["heat"] if self.heat is not None else float("nan"),
            broken_springs=int(cnt_values[CREATED_AT]) - cnt["alive"] if self.springs is not None else 0,
            max_speed=acc["vmax"],
            particles=n,
            pressure=(2.0 * acc["ke"] + acc["pair_virial"] + acc["spring_virial"]) / (self.dim * self._box_volume),
            wall_pressure=self._wall_pressure(),
        )

    def _raise_blowup(self, kind: str, what: str) -> None:
        """Raise the SimulationError for the guard's finding (`kind`: state, temperature or motion), naming the step,
        the particle and the likeliest cause."""
        n = int(self.particles.n[None])
        x = self.particles.x.to_numpy()[:n]
        v = self.particles.v.to_numpy()[:n]
        bad = np.flatnonzero(
            ~(
                np.isfinite(x).all(axis=1)
                & np.isfinite(v).all(axis=1)
                & (np.abs(x) < 1e30).all(axis=1)
                & (np.abs(v) < 1e30).all(axis=1)
            )
        )
        heat_limit_passed = self.has_explicit_heat and self.dt > self._heat_limit
        if len(bad):
            who = f"particle {int(bad[0])}"
        elif kind == "temperature":
            temps = self.particles.T.to_numpy()[:n]
            below = temps.min() < ABSOLUTE_ZERO
            worst = int(np.argmin(temps)) if below else int(np.argmax(np.abs(temps - np.median(temps))))
            who = f"particle {worst} (at {temps[worst]:.4g} C)"
        else:
            who = f"particle {int(np.argmax(np.linalg.norm(v, axis=1)))} (the fastest)"
        limit = self.stable_dt_initial
        name = self.integrator.name
        if kind == "temperature":
            cause = (
                f"dt {self.dt:g} is above the explicit heat limit {self._heat_limit:.3g}"
                if heat_limit_passed
                else "heat flowed without bound (check the sources' power, conductivities and specific heats)"
            )
        elif limit == 0.0:
            cause = f"{name} is unstable on undamped springs at any step; use symplectic_euler or implicit_euler"
        elif limit < self.dt:
            cause = f"dt {self.dt:g} is above the stable limit {limit:.3g} for the stiffest spring with {name}"
        elif heat_limit_passed:
            cause = f"dt {self.dt:g} is above the explicit heat limit {self._heat_limit:.3g}"
        else:
            cause = "a force grew without bound (check stiffness, masses and the pair-force core)"
        raise SimulationError(f"{what} at step {self.step_count} (t = {self.time:.4g}) in {who}: {cause}")
