"""The shape of a physics term, and the registry a scene's term list is built from.

A term is one piece of physics a scene can name (the pair force, springs, heat, walls, gravity, emitters, smoke, ...).
It is one class, registered with `@register`, that says when a scene has it (`wanted(parts)`), is built from the scene's
`Parts`, and declares what it provides by the flags and methods below. The rates (step/rates.py), the stepping plan
(step/plan.py), the measurements (measure/diagnostics.py), the stability bounds and the state file are all derived
from the list: a new term is a new class in a new module imported by physics/__init__.py, and every way of stepping
picks it up.

Its part of the rates, each a Taichi func inlined into the kernels of every way of stepping (long, fused, team):
    pair_channel = "force" | "heat"    row(i) -> ctx, loaded once per particle i;
                                       pair(ctx, i, j, d, r2, bonded) -> its force on i from j (a D-vector) or
                                       heat flow into i from j; finite for any pair within the neighbour reach,
                                       zero beyond its own range (j gets the opposite: the pairs are antisymmetric)
    excludes_bonded                    its pair() gives nothing for a pair joined by a live spring
    bonded                             bond(i, j, s, d) -> force on i from live spring s joining it to j
    particle_force                     force(i) -> force on particle i from it alone (gravity, drag)
    particle_heat                      heat(i) -> heat rate into i from outside the particles (sources, ambient)
    adjusts_force                      adjust_force(i, f) -> the force i feels, after every contribution
    prestep                            prestep_loops(): per-stage device work before the forces (spring updates)
    finishes                           finish(i, dt, rates): particle i's end-of-step work (walls, heat update)
Its host work (the long way runs it around each step; a scene with any never runs steps many to a launch):
    before_step(state), after_step(state), after_steps(state) (after each Simulation.step call),
    at_step(state, done) (at a step boundary, after fused batches too: refreezing)
and `host_work(scene)` says why in words. Terms are built, and each kind of hook runs, in the order of their named
stage (STAGES below: `stage`, or `<hook>_stage` where a term's hook must run elsewhere among the others: the heat
update after the walls have moved a particle), and within a stage in registration order.

Its other parts: `start(state)` (once the simulation is built), `stable_dt(integrator)`, `auto_dt(integrator)` (its
bounds on the step), `measures` with `measure_particle(i)`, `measure_spring(s)`, `measure_pairs(i)`,
`measure_value(w)` (its readouts, of world w: core/worlds.py), `declare(state)` (what it carries from step to
step), `controls()` and `apply_controls()` (values a user may change while it runs; with `world_controls`, each
world's own: `controls(world=k)`, `apply_controls(values, world=k)`), `after_restore(state)`, `words(where)` (what
it does where in a step, for `sandbox check`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

TERMS: list[type] = []  # every term class, in registration order


def register(cls: type) -> type:
    """Class decorator: make `cls` a term a scene can have (see the module docstring); ValueError for a stage that
    is not one of STAGES."""
    for name in dir(cls):
        said = getattr(cls, name) if name == "stage" or name.endswith("_stage") else STAGES[0]
        if said not in STAGES:
            raise ValueError(f"term {cls.key!r}: {name} {said!r}; expected one of {', '.join(STAGES)}")
    if cls not in TERMS:
        TERMS.append(cls)
    return cls


# The named stages of a step, in the order terms are built and their hooks run (module docstring). A term names its
# stage (`stage`), and where one of its hooks runs elsewhere, that hook's (`before_stage`, `after_stage`,
# `finish_stage`, `particle_force_stage`, ...); terms in the same stage run in the order they were registered.
STAGES = (
    "forces",  # body forces (gravity, then what is summed after it)
    "pairs",  # pair forces and flows
    "bonds",  # springs
    "heat",  # conduction, sources, the phase law
    "seeding",  # emitters seed new particles (before the smoke grid steps)
    "flow",  # the smoke grid
    "fields",  # velocity fields (after the smoke grid, whose velocity they add)
    "emitters",  # emitters (after the velocity field, which their particles may inherit)
    "coupling",  # drag towards a velocity field, sampled after the smoke grid has stepped
    "thermal_walls",  # heaters and coolers of the molecular model (before the walls, which they take over)
    "boundaries",  # walls
    "moving",  # kinematic bodies
    "heat_update",  # the heat update, after walls and kinematic particles have moved
    "solve",  # the implicit heat solve
    "advect",  # kinematic bodies carried on after the solve
    "thermostat",  # temperature as motion
    "refreeze",  # melts freezing into springs
    "ageing",  # lifetimes
)


def hook_order(term, hook: str) -> tuple[int, int]:
    """Where `term`'s hook of kind `hook` ("build", "before", "after", "finish", "particle_force", ...) runs among
    the others: its `<hook>_stage`, else its `stage`, in STAGES' order; within a stage, in registration order."""
    stage = getattr(term, f"{hook}_stage", term.stage)
    if stage not in STAGES:
        raise ValueError(f"term {term.key!r}: stage {stage!r}; expected one of {', '.join(STAGES)}")
    cls = term if isinstance(term, type) else type(term)
    return STAGES.index(stage), TERMS.index(cls) if cls in TERMS else len(TERMS)


@dataclass(frozen=True)
class Measure:
    """One readout a term adds: a sum ("sum"), a maximum ("max") or an integer count ("count") over particles
    ("particles": measure_particle(i)), live or dead springs ("springs": measure_spring(s)) or each particle's pairs
    ("pairs": measure_pairs(i)). The term's measure_* func returns one value per measure of that kind, in order."""

    name: str
    kind: str  # "sum", "max", "count"
    over: str  # "particles", "springs", "pairs", or "value" (measure_value(w): read as it is, world w's)
    start: float = 0.0  # where a sum or maximum starts (a maximum of temperatures: below any)


@dataclass(frozen=True)
class Slider:
    """A slider a term offers over one of its live controls (controls()): `key` names it to every front-end (the
    window, the page, the teacher's broadcast), `words` say what it sets, `control` is the control's name (an entry
    `index` of a vector control), `lo` to `hi` its range and `step` its step in the control's units, and `kind` the
    unit kind it is shown in (measure/units.shown: "kT", "power", "pressure", ...; any other string is a unit shown
    as it is: "C", "x")."""

    key: str
    words: str
    control: str
    lo: float
    hi: float
    kind: str
    step: float
    index: int | None = None


@dataclass
class Parts:
    """What a term is built from: the model, the state, the neighbour structure (None without pair terms), and the
    terms built before it (by key)."""

    model: object
    state: object
    neighbours: object
    terms: dict = field(default_factory=dict)

    @property
    def scene(self):
        return self.model.scene


class Term:
    """A term with nothing to add: every hook off. Subclasses set the flags of what they provide."""

    key = ""  # its name in the term list (sim.terms.<key>)
    stage = "coupling"  # where it is built and its hooks run among the others' (STAGES)

    pair_channel = ""
    excludes_bonded = False
    bonded = False
    particle_force = False
    particle_heat = False
    adjusts_force = False
    prestep = False
    finishes = False
    measures: tuple = ()

    @staticmethod
    def wanted(parts) -> bool:
        """Whether the scene being built has this term: `parts` (Parts) holds the scene (parts.scene), the model,
        the state and the terms built before this one (parts.terms, by key), since some terms exist only beside
        others (the drag of a velocity field only with the field)."""
        return False

    @staticmethod
    def host_work(scene) -> str | None:
        """Why this term needs the host between `scene`'s steps (then each step runs the long way), or None."""
        return None

    @staticmethod
    def team_blocker(scene) -> str | None:
        """Why a team of threads cannot step `scene` with this term (step/team.py), or None."""
        return None

    def start(self, state) -> None:
        """Work once the whole simulation is built (emitters seed their initial particles)."""

    def before_step(self, state) -> None:
        """Host work before each step (the long way)."""

    def after_step(self, state) -> None:
        """Host work after each step (the long way)."""

    def after_steps(self, state) -> None:
        """Host work after each Simulation.step call, however many steps it took."""

    def at_step(self, state, done: int) -> bool:
        """Host work at a step boundary, after the `done` steps just taken (one, or a fused batch, which ends where
        next_due says); returns True when it changed the springs."""
        return False

    def next_due(self, state) -> int:
        """Steps from now until at_step has work (a fused batch ends there); a large number when never."""
        return 1 << 30

    def stable_dt(self, integrator) -> float:
        """The largest stable step this term allows with `integrator` (inf: no bound)."""
        return math.inf

    def auto_dt(self, integrator) -> float:
        """The step substeps = "auto" may take for this term now (inf: no bound)."""
        return math.inf

    def declare(self, state) -> None:
        """Declare what this term carries from step to step (state.declare)."""

    def controls(self) -> dict:
        """Values a user may change while it runs, as plain numbers (saved with the state)."""
        return {}

    def apply_controls(self, values: dict) -> None:
        """Set what controls() returned."""

    def sliders(self) -> list[Slider]:
        """The sliders this term offers over its live controls, in the order a panel shows them (none by default)."""
        return []

    def control_checks(self) -> dict:
        """The check each control keeps (name: a schema check, config/schema.key_check for one a scene key sets),
        applied to every value set from a slider, the API or a state file (core/controls.problem)."""
        return {}

    def after_restore(self, state) -> None:
        """The state was put back (reset, undo, load): refresh what follows from it."""

    def words(self, where: str) -> list[str]:
        """What this term does at `where` in a step, in words (`sandbox check` prints the plan with them): "before"
        and "after" (its host passes), "prestep", "rates" and "finish" (its part of the rates), "boundary"."""
        return []

    def nbytes(self) -> int:
        """Bytes of field memory this term holds of its own."""
        return 0


class TermList(tuple):
    """A scene's terms in their order; each also by its key (`terms.springs`), None where the scene has none."""

    def __getattr__(self, key: str):
        for term in self:
            if term.key == key:
                return term
        if any(cls.key == key for cls in TERMS):
            return None
        raise AttributeError(f"no term {key!r}; the registered ones are {', '.join(cls.key for cls in TERMS)}")
