"""The stepping plan's choices, from what each pass declares about itself: whether a scene's steps need the host
between them (then each step runs the long way, one launch per pass) and whether a team of threads may step it.

A pass with work between steps (seeding particles, a grid of its own, a solve iterated from the host, values that
change on a schedule) says so in a `host_work(scene)` static method that returns the reason or None; a pass that
rules out team stepping says so in `team_blocker(scene)`. A new pass declares the same way and joins the tuples
below: nothing else needs to know about it.
"""

from __future__ import annotations

from .physics.emitters import Emitters
from .physics.fields import VelocityField
from .physics.heat import Heat
from .physics.heat_implicit import ImplicitHeat
from .physics.smoke import SmokeGrid
from .scene_tables import Scene

HOST_WORK_PASSES = (Emitters, SmokeGrid, VelocityField, Heat, ImplicitHeat)
TEAM_BLOCKING_PASSES = (Heat,)


def host_work_reasons(scene: Scene) -> list[str]:
    """Why `scene`'s steps need the host between them (empty: they can run many to a launch), as each pass says."""
    return [reason for part in HOST_WORK_PASSES if (reason := part.host_work(scene))]


def host_work_between_steps(scene: Scene) -> bool:
    """Whether `scene`'s steps need the host between them, so that they cannot run many to a launch."""
    return bool(host_work_reasons(scene))


def can_step_as_a_team(scene: Scene) -> bool:
    """Whether team stepping (sandbox/team.py) can run `scene`'s steps, given half neighbour lists (the CPU's): the
    scene keeps neighbour lists, needs no host work between steps, and no pass rules a team out."""
    blocked = any(part.team_blocker(scene) for part in TEAM_BLOCKING_PASSES)
    return scene.world.neighbor_list and not (blocked or host_work_between_steps(scene))
