"""The blow-up guard: limits taken from the scene before its first step, checked on every measurement.

A run that goes unstable must stop with a named cause instead of drawing garbage, from the very first frame. The
limits therefore come from the scene as built, never from a measured (possibly already blown-up) frame:

- energy: the kinetic energy may not exceed RUNAWAY_FACTOR times the energy the scene can hold or be given: its
  initial kinetic energy, its springs stretched to twice their rest length, every particle at the pair potential's
  deepest point (core or well) with a full shell of neighbours, falling across the whole domain, and moving at the
  fastest speed the scene imposes (initial and emitted velocities, velocity fields, smoke buoyancy). The last three
  are per unit mass, so emitted particles bring their share.
- travel: no particle may cross more than half the domain's smallest side in one step;
- temperature: none below absolute zero, and (without power sources, whose heat has no fixed bound) none beyond the
  scene's own temperatures (initial, ambient, sources) by more than TEMPERATURE_FACTOR times their spread.

Tools in the window put energy and heat in by hand: `accept_current_state()` widens the limits to what is measured
next, so a student's push is not mistaken for an instability.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.schema import ABSOLUTE_ZERO

RUNAWAY_FACTOR = 100.0  # kinetic energy above this many times the scene's energy scale stops the run
TEMPERATURE_FACTOR = 1000.0  # temperatures this many spreads beyond the scene's own stop the run (no power sources)
SHELL = {2: 6, 3: 12}  # neighbours of a particle in a close-packed shell


@dataclass
class Limits:
    """What the guard allows. Energies in scaled units, speeds in length/time, temperatures in degrees."""

    fixed_energy: float  # initial kinetic energy + spring capacity
    specific_energy: float  # per unit mass: gravity across the domain, the imposed speed, the pair well
    step_travel: float  # largest distance a particle may move in one step (length)
    temperature_lo: float
    temperature_hi: float
    heat_bounded: bool  # False with power sources: only absolute zero bounds the temperature

    def energy_scale(self, mass: float) -> float:
        """The energy scale for a total mass `mass` (scaled units)."""
        return self.fixed_energy + mass * self.specific_energy


def _imposed_speed(scene) -> float:
    """The fastest speed the scene itself imposes on particles (length/time)."""
    dim = scene.dim
    speeds = [1.0]  # one length per time: a floor for scenes at rest
    for body in scene.bodies:
        speeds.append(float(np.linalg.norm(body.velocity)) + 3.0 * body.random_velocity * math.sqrt(dim))
    for e in scene.emitters:
        speeds.append((float(np.linalg.norm(e.velocity)) + abs(e.radial_speed)) * (1.0 + e.speed_spread))
    for f in scene.fields:
        if f.kind == "wind":
            speeds.append(float(np.linalg.norm(f.velocity)))
        elif f.kind in ("vortex", "source"):
            speeds.append(abs(f.strength) / (2.0 * math.pi * f.radius ** (dim - 1)))
        else:  # explosion: peak speed; noise: typical speed
            speeds.append(3.0 * abs(f.strength))
    if scene.smoke is not None:
        size = float(np.max(np.subtract(scene.world.hi, scene.world.lo)))
        hottest = max((s.temperature for s in scene.smoke.sources), default=scene.smoke.ambient)
        lift = abs(scene.smoke.buoyancy) * abs(hottest - scene.smoke.ambient)
        speeds.append(math.sqrt(2.0 * lift * size))
        speeds.extend(float(np.linalg.norm(s.velocity)) for s in scene.smoke.sources if s.velocity)
    return max(speeds)


def _scene_temperatures(scene, built) -> list[float]:
    temps = list(built.temperature) if built.count else []
    heat = scene.heat
    if heat is not None:
        temps.append(heat.ambient)
        for src in heat.sources:
            if src.mode != "power":
                temps.append(src.temperature)
                temps.extend(src.schedule_values)
    temps.extend(e.temperature for e in scene.emitters if e.temperature is not None)
    if scene.smoke is not None:
        temps.append(scene.smoke.ambient)
        temps.extend(s.temperature for s in scene.smoke.sources)
    return temps or [20.0]


def _pair_depth(pair) -> float:
    """Largest |U| per unit mass product of the pair potential, at its core or its well (0 without a pair force)."""
    if pair is None:
        return 0.0
    depth = 0.0
    n = pair.n_materials
    for p in range(n):
        for q in range(n):
            for r in (pair.r_core_np[p, q], pair.r_eq_np[p, q]):
                if math.isfinite(r) and r < pair.cutoff:
                    depth = max(depth, abs(pair.potential(r, p, q) - pair.shift_np[p, q]))
    return depth


def _heaviest_particle(scene, built) -> float:
    """The largest mass of one particle, built or to be emitted (scaled units)."""
    masses = [float(np.max(built.mass, initial=0.0))]
    for e in scene.emitters:
        mat = scene.materials[e.material]
        masses.append(mat.particle_mass or mat.density * (2.0 * e.particle_radius) ** scene.dim)
    return max(masses) or 1.0


def scene_limits(scene, built, pair) -> Limits:
    """The guard's limits for `scene` as built (`built`: the initial particles; `pair`: its PairForce or None)."""
    world = scene.world
    sides = np.subtract(world.hi, world.lo)
    size = float(np.max(sides))
    kinetic = float(0.5 * np.sum(built.mass * np.sum(built.v**2, axis=1))) if built.count else 0.0
    springs = float(0.5 * np.sum(built.stiffness * built.rest_length**2)) if built.spring_count else 0.0
    gravity = float(np.linalg.norm(world.gravity)) if world.gravity else 0.0
    speed = _imposed_speed(scene)
    heaviest = _heaviest_particle(scene, built)
    specific = gravity * size + 0.5 * speed**2 + 0.5 * SHELL[scene.dim] * _pair_depth(pair) * heaviest
    temps = _scene_temperatures(scene, built)
    lo, hi = float(min(temps)), float(max(temps))
    spread = max(hi - lo, 100.0)
    power = scene.heat is not None and any(s.mode == "power" for s in scene.heat.sources)
    return Limits(
        fixed_energy=kinetic + springs,
        specific_energy=specific,
        step_travel=0.5 * float(np.min(sides)),
        temperature_lo=lo - TEMPERATURE_FACTOR * spread,
        temperature_hi=hi + TEMPERATURE_FACTOR * spread,
        heat_bounded=not power,
    )


class BlowupGuard:
    """Checks each measurement against the scene's limits; `problem()` names what is wrong, or returns None."""

    def __init__(self, limits: Limits):
        self.limits = limits
        self._accept_next = False

    def accept_current_state(self) -> None:
        """Widen the limits to the next measurement (after a tool put energy or heat in by hand)."""
        self._accept_next = True

    def problem(self, acc: dict, bad_particles: int, dt: float, has_heat: bool) -> tuple[str, str] | None:
        """What is wrong with a measurement (`acc`: the sums of Simulation._measure), or None: (kind, description)
        with kind "state", "temperature" or "motion". `bad_particles`: particles with a non-finite or huge
        coordinate; `dt`: the step (time)."""
        if bad_particles or not all(math.isfinite(v) for v in acc.values()):
            return "state", "non-finite state"
        lim = self.limits
        coldest, hottest = -acc.get("tcold", -1e30), acc.get("thot", -1e30)
        if self._accept_next:
            self._accept_next = False
            lim.fixed_energy = max(lim.fixed_energy, acc["ke"])
            if has_heat:
                lim.temperature_lo = min(lim.temperature_lo, coldest)
                lim.temperature_hi = max(lim.temperature_hi, hottest)
        if has_heat and coldest < ABSOLUTE_ZERO - 1e-3:
            return "temperature", f"temperature {coldest:.4g} C, below absolute zero"
        if has_heat and lim.heat_bounded and not (lim.temperature_lo <= coldest and hottest <= lim.temperature_hi):
            worst = hottest if hottest > lim.temperature_hi else coldest
            return "temperature", (
                f"runaway temperature {worst:.4g} C (the scene's temperatures allow "
                f"{lim.temperature_lo:.4g} .. {lim.temperature_hi:.4g} C)"
            )
        travel = acc["vmax"] * dt
        if travel > lim.step_travel:
            return "motion", (
                f"a particle moved {travel:.3g} in one step (speed {acc['vmax']:.3g}), more than half the domain "
                f"({lim.step_travel:.3g})"
            )
        scale = lim.energy_scale(acc["mass"])
        if acc["ke"] > RUNAWAY_FACTOR * scale:
            return "motion", (
                f"runaway kinetic energy {acc['ke']:.3g} (over {RUNAWAY_FACTOR:g} x the scene's energy scale "
                f"{scale:.3g})"
            )
        return None


def explain_blowup(state, terms, integrator, kind: str, what: str) -> str:
    """blowup_message() for `state` (its particles and clock) stepped by `integrator` through `terms` (a TermList:
    the springs' and heat's step limits)."""
    n = state.live_count()
    p = state.particles
    x, v = p.x.to_numpy()[:n], p.v.to_numpy()[:n]
    temperatures = p.T.to_numpy()[:n] if p.heat else None
    springs, heat = terms.springs, terms.heat
    spring_limit = springs.stable_dt_initial(integrator) if springs is not None else math.inf
    heat_limit = heat.stable_dt(integrator) if heat is not None else math.inf
    clock = (state.step, state.time, state.dt)
    integrator = (integrator.name, integrator.stable_h_omega)
    return blowup_message(kind, what, x, v, temperatures, clock, integrator, (spring_limit, heat_limit))


def blowup_message(kind: str, what: str, x, v, temperatures, clock: tuple, integrator, limits: tuple) -> str:
    """The one line a blow-up stops with: what (`what`, of `kind` state, temperature or motion) at which step in
    which particle, and the likeliest cause. x, v: the live particles' positions and velocities (N, D);
    temperatures: theirs (N,), or None without heat; clock: (step, time, dt); integrator: its name and stable h w
    (for the cause); limits: (the springs' stable step as built, the explicit heat step limit, inf without)."""
    step, time, dt = clock
    name, _ = integrator
    spring_limit, heat_limit = limits
    bad = np.flatnonzero(
        ~(
            np.isfinite(x).all(axis=1)
            & np.isfinite(v).all(axis=1)
            & (np.abs(x) < 1e30).all(axis=1)
            & (np.abs(v) < 1e30).all(axis=1)
        )
    )
    heat_limit_passed = dt > heat_limit
    if len(bad):
        who = f"particle {int(bad[0])}"
    elif kind == "temperature":
        below = temperatures.min() < ABSOLUTE_ZERO
        worst = (
            int(np.argmin(temperatures)) if below else int(np.argmax(np.abs(temperatures - np.median(temperatures))))
        )
        who = f"particle {worst} (at {temperatures[worst]:.4g} C)"
    else:
        who = f"particle {int(np.argmax(np.linalg.norm(v, axis=1)))} (the fastest)"
    if kind == "temperature":
        cause = (
            f"dt {dt:g} is above the explicit heat limit {heat_limit:.3g}"
            if heat_limit_passed
            else "heat flowed without bound (check the sources' power, conductivities and specific heats)"
        )
    elif spring_limit == 0.0:
        cause = f"{name} is unstable on undamped springs at any step; use symplectic_euler or implicit_euler"
    elif spring_limit < dt:
        cause = f"dt {dt:g} is above the stable limit {spring_limit:.3g} for the stiffest spring with {name}"
    elif heat_limit_passed:
        cause = f"dt {dt:g} is above the explicit heat limit {heat_limit:.3g}"
    else:
        cause = "a force grew without bound (check stiffness, masses and the pair-force core)"
    return f"{what} at step {step} (t = {time:.4g}) in {who}: {cause}"
