"""The stepping plan's choices, from what each pass declares about itself: whether a scene's steps need the host
between them (then each step runs the long way, one launch per pass) and whether a team of threads may step it.

A pass with work between steps (seeding particles, a grid of its own, a solve iterated from the host, values that
change on a schedule) says so in a `host_work(scene)` static method that returns the reason or None; a pass that
rules out team stepping says so in `team_blocker(scene)`. A new pass declares the same way and joins the tuples
below: nothing else needs to know about it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..config.scene_tables import Scene
from ..physics.emitters import Emitters
from ..physics.fields import VelocityField
from ..physics.heat import Heat
from ..physics.heat_implicit import ImplicitHeat
from ..physics.smoke import SmokeGrid

HOST_WORK_PASSES = (Emitters, SmokeGrid, VelocityField, Heat, ImplicitHeat)
TEAM_BLOCKING_PASSES = (Heat,)


def host_work_reasons(scene: Scene) -> list[str]:
    """Why `scene`'s steps need the host between them (empty: they can run many to a launch), as each pass says."""
    return [reason for part in HOST_WORK_PASSES if (reason := part.host_work(scene))]


def host_work_between_steps(scene: Scene) -> bool:
    """Whether `scene`'s steps need the host between them, so that they cannot run many to a launch."""
    return bool(host_work_reasons(scene))


def can_step_as_a_team(scene: Scene) -> bool:
    """Whether team stepping (step/team.py) can run `scene`'s steps, given half neighbour lists (the CPU's): the
    scene keeps neighbour lists, needs no host work between steps, and no pass rules a team out."""
    blocked = any(part.team_blocker(scene) for part in TEAM_BLOCKING_PASSES)
    return scene.world.neighbor_list and not (blocked or host_work_between_steps(scene))


@dataclass(frozen=True)
class HostPass:
    """A pass the host launches around the integrator's step (the long way), with what it does in words."""

    text: str  # for pipeline(); "" where another line already says it
    run: Callable[[], None]


class StepPlan:
    """What one step of `sim` runs, in order, and how it is launched. The long way runs `before`, the integrator
    (whose rates evaluation is described by the rates lines) and `after`; pipeline() prints these same lists, so the
    description cannot drift from what runs. Built once the simulation's passes exist."""

    def __init__(self, sim):
        self.sim = sim
        self.before = _passes_before(sim)
        self.after = _passes_after(sim)

    def lines(self) -> list[str]:
        """The passes a step runs, in order, in words (Simulation.pipeline)."""
        sim = self.sim
        texts = [p.text for p in self.before if p.text]
        if sim.neighbours is not None:
            texts.append(sim.neighbours.describe(sim.grid))
            if sim.reorder is not None:
                texts.append(f"particle storage sorted into cell order every {sim.reorder.every} list rebuilds")
        elif sim.grid is not None:
            texts.append(f"neighbour grid: counting sort into a {sim.grid.describe()}, every step")
        if sim.springs is not None:
            texts.append(sim.springs.describe(sim.heat is not None, sim.refreezer is not None))
        texts.append(_rates_line(sim))
        walls = "periodic wrap" if sim.scene.world.periodic else "walls (restitution, friction)"
        heat = ", enthalpy update (temperature and melt fraction from it)" if sim.has_explicit_heat else ""
        texts.append(f"integrator {sim.integrator.name}, then {walls}{heat}")
        texts += [p.text for p in self.after if p.text]
        reasons = host_work_reasons(sim.scene)
        if reasons:
            texts.append("launch: one launch per pass, one step at a time: " + "; ".join(reasons))
        if sim.fuses_steps:
            from ..integrators import REGISTRY

            fused = "/".join(name for name, cls in REGISTRY.items() if cls.stages)
            team = f", run by a team of {sim.team.workers} threads meeting at barriers" if sim.team else ""
            texts.append(
                "launch: every pass of a step, and many steps, in one kernel launch (the list rebuild decided on the "
                f"device{team}) with {fused}; other integrators one launch per pass"
            )
        if sim.refreezer is not None:
            texts.append(
                f"every {sim.scene.heat.refreeze_interval} steps: refreezing (new bonds within "
                f"{sim.refreezer.radius:g} between frozen particles where one was molten)"
            )
        return texts


def _passes_before(sim) -> list[HostPass]:
    """The host's passes before the integrator's step, in order."""
    out = []
    if sim.reorder is not None:  # described with the neighbour lists
        out.append(HostPass("", lambda: sim.reorder.apply() if sim.reorder.due() else None))
    if sim.heat is not None and sim.heat.scheduled:
        out.append(HostPass("scheduled heat sources set to the step's start time", lambda: sim.heat.set_time(sim.time)))
    if sim.emitters is not None:
        names = ", ".join(e.name for e in sim.scene.emitters)
        out.append(HostPass(f"emitters: {names} (rate, bursts)", lambda: sim.emitters.before_step(sim.time, sim.dt)))
    if sim.smoke is not None:
        every = sim.scene.smoke.interval
        text = f"smoke: stable fluids on a {sim.smoke.describe()} (buoyancy, advection, CG projection)"

        def smoke_step():
            if sim.step_count % every == 0:
                sim.smoke.step(sim.dt * every)

        out.append(HostPass(text, smoke_step))
    if sim.has_kinematic:  # described with its advection below
        out.append(HostPass("", sim._kinematic_begin))
    if sim.has_field_drag:  # the drag force's target, held through the step
        text = "velocity field sampled at field-coupled particles (their drag target)"
        out.append(HostPass(text, lambda: sim._sample_field(sim.time)))
    return out


def _passes_after(sim) -> list[HostPass]:
    """The host's passes after the integrator's step, in order."""
    out = []
    if sim.implicit_heat is not None:
        text = "implicit heat: backward Euler by preconditioned CG, then the enthalpy update"
        out.append(HostPass(text, sim._implicit_heat_step))
    if sim.has_kinematic:
        text = f"kinematic advection through the velocity field ({sim.scene.world.advection})"
        out.append(HostPass(text, lambda: sim._advect_kinematic(sim.dt, sim.time)))
    if sim.has_lifetimes:
        text = "ageing; the dead retired by compaction after each step() call"
        out.append(HostPass(text, lambda: sim._age(sim.dt)))
    return out


def _rates_line(sim) -> str:
    """The rates launch and the terms it sums."""
    terms = []
    if sim.pair is not None:
        terms.append(f"pair force (a={sim.pair.a:g}, b={sim.pair.b:g}, cutoff {sim.pair.cutoff:g})")
    if sim.heat is not None:
        terms.append(f"heat diffusion (kernel support {sim.heat.support:g}, {sim.heat.n_sources} sources)")
    if sim.springs is not None:
        terms.append("spring-damper forces (gathered per particle)")
    for term in sim.body_forces:
        terms += term.describe()
    pairs = " (each neighbour pair once, applied to both)" if sim.half_pairs else ""
    return f"fused rates kernel{pairs}: " + ", ".join(terms)
