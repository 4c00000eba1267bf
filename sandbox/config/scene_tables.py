"""The scene's tables as typed, immutable dataclasses (one per TOML table, each key with its default, meaning and
check: `sandbox keys` prints them), the shipped choices they accept, and Scene, the validated whole. Reading and
validating a file is scene.py's job."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from .arguments import MAX_SUBSTEPS
from .lesson import Lesson, LessonClaim, UncheckedSentence  # noqa: F401 - part of the scene tables
from .materials import Material
from .molecular_table import WALL_SIDES, Heater, Lid, Molecular, ThermalWall  # noqa: F401 - part of the scene tables
from .render_table import CHART_SERIES, COLOR_BY, Render  # noqa: F401 - part of the scene tables
from .schema import at_least, between, celsius, non_negative, one_of, positive, spec, unit_interval

# The registry of integrator names, in the order the window cycles through them: every class registered in
# sandbox/integrators/ has its name here (a test checks), so validating a scene needs no Taichi import.
INTEGRATORS = ("symplectic_euler", "forward_euler", "velocity_verlet", "midpoint", "verlet", "rk4", "implicit_euler")
SHAPES = ("box", "disk", "sphere", "mask")
LATTICES = ("square", "hex", "cubic", "fcc")
SOURCE_MODES = ("exchange", "fixed", "power")  # heat source modes (physics/heat.py)
FIELD_KINDS = ("wind", "vortex", "source", "explosion", "noise")  # velocity field elements (physics/fields.py)
COUPLINGS = ("none", "kinematic", "drag")  # how a body or emitter's particles follow the velocity field


MAX_ITERATIONS = 100_000  # CG iteration caps: a step must end
MAX_BONDS = 64  # bonds per particle that refreezing may fill up to (spare spring slots: capacity x bonds / 2)
MAX_EXPONENT = 64  # a whole-number exponent is unrolled into multiplications when the kernels compile


def exponent(x: float) -> str | None:
    return None if 0 < x <= MAX_EXPONENT else f"expected a number above 0 and at most {MAX_EXPONENT}, got {x}"


@dataclass(frozen=True, kw_only=True)
class SceneInfo:
    name: str = spec("", doc="scene name (default: the file name)")
    description: str = spec("", doc="one paragraph shown by `sandbox list` and `sandbox check`")
    lesson: Lesson = spec(doc="[scene.lesson]: what happens, what to try, the physics", factory=Lesson)
    palette: list[str] = spec(
        doc="materials the window's spawn tool offers (m cycles them), besides those of the bodies and emitters",
        factory=list,
    )


@dataclass(frozen=True, kw_only=True)
class World:
    dim: int = spec(2, doc="2 or 3 dimensions", check=lambda d: None if d in (2, 3) else f"expected 2 or 3, got {d}")
    lo: tuple[float, ...] = spec(doc="lower corner of the domain box", length="dim")
    hi: tuple[float, ...] = spec(doc="upper corner of the domain box", length="dim")
    gravity: tuple[float, ...] = spec((), doc="gravitational acceleration vector (default zero)", length="dim")
    dt: float = spec(0.002, doc="time step (simulation seconds)", check=positive)
    substeps: int | str = spec(
        10,
        doc='steps per rendered frame, or "auto": chosen each frame from the stability '
        "bound (stiffest live spring, fastest particle, heat), each at most dt",
        check=lambda s: (
            None
            if s == "auto" or (isinstance(s, int) and 1 <= s <= MAX_SUBSTEPS)
            else f'expected an integer from 1 to {MAX_SUBSTEPS:,} or "auto", got {s!r}'
        ),
    )
    frame_time: float = spec(0.02, doc='with substeps = "auto": simulated seconds per frame', check=positive)
    integrator: str = spec("symplectic_euler", doc="time integrator", check=one_of(*INTEGRATORS))
    periodic: bool = spec(False, doc="periodic boundaries on every axis instead of walls")
    restitution: float = spec(0.3, doc="normal velocity kept after hitting a wall", check=unit_interval)
    friction: float = spec(0.1, doc="fraction of tangential velocity lost at a wall contact", check=unit_interval)
    drag: float = spec(0.0, doc="linear drag rate on every particle (1/time)", check=non_negative)
    precision: str = spec("f32", doc="float precision of the fields", check=one_of("f32", "f64"))
    capacity: int = spec(
        0,
        doc="particle capacity (0: the initial count plus half again, at least 1,024, to spawn into)",
        check=at_least(0),
    )
    max_particles: int = spec(
        5_000_000,
        doc="largest particle count (bodies, emitters, capacity) the scene may build; memory is checked as well",
        check=at_least(1),
    )
    implicit_tolerance: float = spec(1e-6, doc="implicit_euler: relative residual at which CG stops", check=positive)
    implicit_max_iterations: int = spec(
        200, doc="implicit_euler: CG iteration cap per step", check=between(1, MAX_ITERATIONS)
    )
    neighbor_list: bool = spec(True, doc="Verlet neighbour lists (false: scan the cell grid every step)")
    skin: float = spec(
        0.3, doc="neighbour-list skin (length): lists are rebuilt after a particle moves skin/2", check=positive
    )
    reorder: int | str = spec(
        "auto",
        doc="sort the particles' storage into cell order every this many neighbour-list rebuilds, so neighbours sit "
        'near in memory (0: never; "auto": every 20 when the scene starts with at least 5,000 particles)',
        check=lambda s: (
            None if s == "auto" or (isinstance(s, int) and s >= 0) else f'expected an integer >= 0 or "auto", got {s!r}'
        ),
    )
    advection: str = spec(
        "euler",
        doc="kinematic particles: x += dt v(x, t) by forward Euler, or by the midpoint rule",
        check=one_of("euler", "midpoint"),
    )


@dataclass(frozen=True, kw_only=True)
class PairForce:
    law: str = spec(
        "power",
        doc="the pair law (physics/pair_laws.py): power (alpha/(d+eps)^a - beta/d^b, the materials' pair_* keys) or "
        "morse (a well of depth, width and distance below, the same for every pair)",
        check=one_of("power", "morse"),
    )
    a: float = spec(2.0, doc="exponent of the attraction term alpha/(d+eps)^a (at most 64)", check=exponent)
    b: float = spec(4.0, doc="exponent of the repulsion term beta/d^b (at most 64)", check=exponent)
    cutoff: float = spec(2.5, doc="cutoff distance of the pair force (length)", check=positive)
    core: float = spec(
        0.6,
        doc="below core * r_eq the force is held at its value there (caps the singularity)",
        check=lambda c: None if 0 < c < 1 else f"expected a number in (0, 1), got {c}",
    )
    shift: bool = spec(
        True,
        doc="shift the pair energy to zero at the cutoff (false: the plain potential, as LAMMPS's lj/cut); "
        "forces are the same",
    )
    force_shift: bool = spec(
        False,
        doc="subtract the force at the cutoff, so that it falls continuously to zero there (the linear-force-shifted "
        "potential of NIST's Lennard-Jones tables; its energy is zero at the cutoff whatever shift says)",
    )
    depth: float = spec(1.0, doc="law = morse: the well's depth D (energy per unit mass product)", check=positive)
    width: float = spec(
        2.0, doc="law = morse: w in e^(-w (d - r0)) (1 / length): larger, a narrower well", check=positive
    )
    distance: float = spec(1.0, doc="law = morse: r0, where the well is deepest (length)", check=positive)


@dataclass(frozen=True, kw_only=True)
class HeatSource:
    name: str = spec("plate", doc="label shown in the picture")
    lo: tuple[float, ...] = spec(doc="lower corner of the source region", length="dim")
    hi: tuple[float, ...] = spec(doc="upper corner of the source region", length="dim")
    mode: str = spec(
        "exchange",
        doc="exchange (each particle inside receives conductance x (temperature - T)), fixed (particles inside are "
        "held at the temperature: a Dirichlet boundary) or power (a total heat rate shared by mass among them)",
        check=one_of(*SOURCE_MODES),
    )
    temperature: float | None = spec(
        None, doc="the source's temperature (degrees); required unless mode = power", check=celsius
    )
    power: float = spec(0.0, doc="mode = power: total heat per unit time into the region (negative: cooling)")
    conductance: float = spec(
        20.0, doc="heat flow per degree of difference into each particle in the region", check=non_negative
    )
    reach: float = spec(
        1.0, doc="particles within this distance of the region exchange heat with it", check=non_negative
    )
    schedule_times: tuple[float, ...] = spec(
        (), doc="times (increasing, from 0) at which the temperature (or power) changes to schedule_values"
    )
    schedule_values: tuple[float, ...] = spec((), doc="the temperature (or power) from each of schedule_times on")
    schedule_period: float = spec(
        0.0, doc="repeat the schedule with this period (0: hold the last value)", check=non_negative
    )
    visible: bool = spec(True, doc="2D: draw the region (in the colour bar's colour for its temperature)")


@dataclass(frozen=True, kw_only=True)
class Heat:
    ambient: float = spec(20.0, doc="ambient temperature (degrees)", check=celsius)
    ambient_exchange: float = spec(
        0.0, doc="heat flow per degree between each particle and the ambient", check=non_negative
    )
    radius: float = spec(
        2.5,
        doc="support radius of the heat-diffusion kernel, in particle spacings (so refinement converges)",
        check=positive,
    )
    radius_length: float = spec(
        0.0, doc="the support radius as a length instead; overrides radius when above 0", check=non_negative
    )
    stepper: str = spec(
        "explicit",
        doc="explicit (Euler; limited step) or implicit (backward Euler by CG)",
        check=one_of("explicit", "implicit"),
    )
    sources: list[HeatSource] = spec(doc="hot or cold regions", factory=list)
    refreeze: bool = spec(True, doc="molten particles that cool below their solidus bond again into a solid")
    refreeze_radius: float = spec(
        1.5,
        doc="refreezing bonds particles closer than this many particle spacings (at most the heat radius)",
        check=positive,
    )
    refreeze_max_bonds: int = spec(
        0, doc="bonds per particle that refreezing fills up to (0: 8 in 2D, 12 in 3D)", check=between(0, MAX_BONDS)
    )
    refreeze_interval: int = spec(10, doc="steps between refreezing passes", check=at_least(1))
    agitation_time: float = spec(
        0.0,
        doc="temperature as motion: the time (s) in which a molten particle's motion relaxes to its temperature "
        "(a pairwise thermostat that keeps momentum; 0: off, the motion does not follow the temperature)",
        check=non_negative,
    )
    agitation_scale: float = spec(
        0.01,
        doc="with agitation_time: the thermal energy kT per kelvin (pJ/K): a particle of 1 mg at 100 °C jiggles at "
        "sqrt(kT / m) = 1.9 mm/s per direction",
        check=positive,
    )


@dataclass(frozen=True, kw_only=True)
class FieldElement:
    kind: str = spec(
        doc="wind, vortex, source (negative strength: a sink), explosion or noise", check=one_of(*FIELD_KINDS)
    )
    center: tuple[float, ...] = spec(
        (), doc="vortex/source/explosion: centre (a point on the axis for a 3D vortex)", length="dim"
    )
    axis: tuple[float, ...] = spec((), doc="3D vortex: axis direction (default +z)", length=3)
    velocity: tuple[float, ...] = spec((), doc="wind: the uniform velocity", length="dim")
    strength: float = spec(
        0.0,
        doc="vortex: circulation (length^2/time); source: volume rate; explosion: peak speed; noise: typical speed",
    )
    radius: float = spec(1.0, doc="core radius: inside it the 1/r profile is smoothed away (length)", check=positive)
    falloff: float = spec(0.0, doc="vortex: Gaussian falloff radius (0: none)", check=non_negative)
    time: float = spec(0.0, doc="explosion: when it goes off (time)")
    decay: float = spec(0.5, doc="explosion: e-folding time of its speed", check=positive)
    scale: float = spec(8.0, doc="noise: length scale of the swirls", check=positive)
    speed: float = spec(0.2, doc="noise: how fast the pattern changes (noise cells per time)", check=non_negative)
    seed: int = spec(0, doc="noise: random seed", check=at_least(0))


@dataclass(frozen=True, kw_only=True)
class FieldCoupling:
    """How a body's or an emitter's particles follow the velocity field ([[fields]] and [smoke])."""

    field: str = spec(
        "none",
        doc="none, kinematic (carried by the velocity field) or drag (pulled towards it)",
        check=one_of(*COUPLINGS),
    )
    field_drag: float = spec(
        5.0, doc="field = drag: rate of relaxing towards the field velocity (1/time)", check=non_negative
    )


@dataclass(frozen=True, kw_only=True)
class SmokeSource:
    lo: tuple[float, ...] = spec(doc="lower corner of the region", length="dim")
    hi: tuple[float, ...] = spec(doc="upper corner of the region", length="dim")
    temperature: float = spec(doc="cells inside are held at this temperature (degrees)", check=celsius)
    velocity: tuple[float, ...] = spec(
        (), doc="inflow velocity imposed on the region's faces (default none)", length="dim"
    )


@dataclass(frozen=True, kw_only=True)
class Smoke:
    resolution: int = spec(64, doc="grid cells along the longest side of the domain", check=at_least(4))
    buoyancy: float = spec(0.5, doc="upward acceleration per degree above the ambient (against gravity)")
    ambient: float = spec(20.0, doc="ambient temperature of the air (degrees)", check=celsius)
    cooling: float = spec(0.3, doc="rate at which hot air relaxes to the ambient (1/time)", check=non_negative)
    tolerance: float = spec(1e-5, doc="pressure solve: relative residual at which CG stops", check=positive)
    max_iterations: int = spec(400, doc="pressure solve: CG iteration cap per step", check=between(1, MAX_ITERATIONS))
    interval: int = spec(
        1,
        doc="simulation steps per smoke step (stable fluids is stable at any step; the smoke steps interval x dt)",
        check=at_least(1),
    )
    sources: list[SmokeSource] = spec(doc="hot regions that drive the flow", factory=list)


@dataclass(frozen=True, kw_only=True)
class Emitter(FieldCoupling):
    name: str = spec("", doc="label (default emitter<N>)")
    material: str = spec(doc="material of the emitted particles")
    shape: str = spec(
        "point",
        doc="point, box, disk (2D), sphere (3D) or mask (2D, a PNG over lo..hi): where particles appear",
        check=one_of("point", "box", "disk", "sphere", "mask"),
    )
    mask: str = spec("", doc="mask: PNG file (inside the scene's folder or assets/); opaque/bright pixels are inside")
    surface: bool = spec(False, doc="box/disk/sphere: seed on the boundary (uniform by length/area), not inside")
    center: tuple[float, ...] = spec((), doc="point/disk/sphere: centre", length="dim")
    lo: tuple[float, ...] = spec((), doc="box: lower corner", length="dim")
    hi: tuple[float, ...] = spec((), doc="box: upper corner", length="dim")
    size: float = spec(0.0, doc="disk/sphere: radius of the region (length)", check=non_negative)
    count: int = spec(0, doc="particles emitted at the start", check=at_least(0))
    rate: float = spec(0.0, doc="particles per second (fractions carry over between steps)", check=non_negative)
    start: float = spec(0.0, doc="emit at the rate from this time on", check=non_negative)
    stop: float = spec(math.inf, doc="... until this time (inf: for ever)", infinite=True)
    bursts: tuple[float, ...] = spec((), doc="times of bursts of burst_count particles each")
    burst_count: int = spec(0, doc="particles per burst", check=at_least(0))
    refill_density: float = spec(
        0.0,
        doc="box/disk/sphere: every step, top up each cell of the region to this many particles per unit area "
        "(volume) where it has fewer (counted on a grid of cells holding 4 each); 0: off",
        check=non_negative,
    )
    velocity: tuple[float, ...] = spec((), doc="base velocity (default zero)", length="dim")
    cone: float = spec(
        0.0, doc="random direction within this full cone angle (degrees) around velocity", check=non_negative
    )
    speed_spread: float = spec(
        0.0, doc="speed (base and radial) varies uniformly by this fraction", check=unit_interval
    )
    radial_speed: float = spec(0.0, doc="added speed outward from the centre (explosions)")
    inherit_field: bool = spec(False, doc="add the velocity field's value at the birth position")
    jitter: float = spec(
        0.0, doc="random offset of each birth position (length), so particles do not stack", check=non_negative
    )
    temperature: float | None = spec(None, doc="temperature (default: the ambient)", check=celsius)
    particle_radius: float = spec(0.5, doc="radius of each particle (length); mass = density (2 r)^dim", check=positive)
    color: tuple[float, ...] = spec((), doc="colour [r, g, b] of the particles (default: the material's)")
    lifetime: float = spec(0.0, doc="seconds each particle lives (0: for ever)", check=non_negative)
    lifetime_spread: float = spec(0.0, doc="lifetime varies uniformly by this fraction", check=unit_interval)
    fade: bool = spec(True, doc="colour fades to black over the lifetime (additive: to nothing)")
    shrink: bool = spec(False, doc="drawn radius shrinks to zero over the lifetime")
    seed: int = spec(0, doc="random seed", check=at_least(0))
    draw: str = spec("splat", doc="splat, dot or sphere (3D)", check=one_of("splat", "dot", "sphere"))
    blend: str = spec("opaque", doc="opaque, alpha or additive", check=one_of("opaque", "alpha", "additive"))
    opacity: float = spec(1.0, doc="alpha of a translucent particle / brightness of an additive one", check=positive)


@dataclass(frozen=True, kw_only=True)
class Body(FieldCoupling):
    name: str = spec("", doc="label (default body<N>)")
    material: str = spec(doc="material name from the library or [materials]")
    shape: str = spec("box", doc="box, disk (2D), sphere (3D) or mask (2D, a PNG)", check=one_of(*SHAPES))
    lo: tuple[float, ...] = spec((), doc="box/mask: lower corner", length="dim")
    hi: tuple[float, ...] = spec((), doc="box/mask: upper corner", length="dim")
    center: tuple[float, ...] = spec((), doc="disk/sphere: centre", length="dim")
    radius: float = spec(0.0, doc="disk/sphere: radius", check=non_negative)
    mask: str = spec("", doc="mask: PNG file (inside the scene's folder or assets/); opaque/bright pixels are inside")
    lattice: str = spec(
        "", doc="square or hex (2D), cubic or fcc (3D); default square/cubic", check=one_of("", *LATTICES)
    )
    spacing: float = spec(1.0, doc="nearest-neighbour distance of the lattice (length)", check=positive)
    springs: bool = spec(True, doc="join neighbours by springs (a solid); false: a liquid from the start")
    spring_radius: float = spec(1.5, doc="join lattice neighbours closer than this many spacings", check=at_least(1.0))
    temperature: float | None = spec(None, doc="initial temperature (default: the ambient)", check=celsius)
    velocity: tuple[float, ...] = spec((), doc="initial velocity", length="dim")
    random_velocity: float = spec(0.0, doc="std. dev. of random initial velocity per component", check=non_negative)
    jitter: float = spec(0.0, doc="random displacement of lattice sites, as a fraction of spacing", check=unit_interval)
    seed: int = spec(0, doc="random seed for velocity and jitter", check=at_least(0))
    draw: str = spec(
        "",
        doc="splat (a disc of the particle's radius), dot (one pixel) or sphere (3D shaded); "
        "default splat in 2D, sphere in 3D",
        check=one_of("", "splat", "dot", "sphere"),
    )
    blend: str = spec(
        "opaque",
        doc="opaque, alpha (translucent; depth-sorted in 3D) or additive (emits light)",
        check=one_of("opaque", "alpha", "additive"),
    )
    opacity: float = spec(1.0, doc="alpha of a translucent body / brightness of an additive one", check=positive)


@dataclass(frozen=True, kw_only=True)
class SceneSections:
    """The tables of a scene file that a validated Scene keeps as they are (checked), declared once: the file's
    schema (_SceneFile) and the Scene both are these, and scene_from_dict copies them by these names."""

    world: World = spec(doc="[world]")
    pair: PairForce | None = spec(None, doc="[pair]")
    heat: Heat | None = spec(None, doc="[heat]")
    molecular: Molecular | None = spec(None, doc="[molecular]: atoms, temperature from motion, phases from structure")
    bodies: list[Body] = spec(doc="[[bodies]]", factory=list)
    emitters: list[Emitter] = spec(doc="[[emitters]]", factory=list)
    fields: list[FieldElement] = spec(doc="[[fields]]", factory=list)
    smoke: Smoke | None = spec(None, doc="[smoke]")
    render: Render = spec(doc="[render]", factory=Render)


@dataclass(frozen=True, kw_only=True)
class _SceneFile(SceneSections):
    """A scene file as read: its sections, [scene] (name, lesson, palette) and the materials it defines itself."""

    scene: SceneInfo = spec(doc="[scene]", factory=SceneInfo)
    materials: dict | None = spec(None, doc="[materials.NAME]: the scene's own materials, added to the library's")


@dataclass(frozen=True, kw_only=True)
class Scene(SceneSections):
    """A validated scene: what to build and how to run and draw it. Its sections are the file's, checked; `materials`
    holds the materials the scene uses (from the library or its own [materials.NAME]), by name."""

    name: str
    description: str
    path: Path
    materials: dict[str, Material] = field(repr=False)

    @property
    def dim(self) -> int:
        return self.world.dim

    palette: list[str] = field(default_factory=list)
    lesson: Lesson = field(default_factory=Lesson)
    spacing: float = 1.0  # the particle spacing (length): see particle_spacing
    source: dict = field(default_factory=dict, repr=False, compare=False)  # the raw table it was read from

    def used_materials(self) -> list[str]:
        """Names of the materials the bodies, emitters and palette use, in first-use order (material ids follow)."""
        return list(
            dict.fromkeys([b.material for b in self.bodies] + [e.material for e in self.emitters] + self.palette)
        )

    @property
    def heat_radius(self) -> float:
        """Support radius of the heat kernel (length): heat.radius_length, else heat.radius spacings; 0 without heat."""
        return heat_support(self.heat, self.spacing) if self.heat else 0.0

    @property
    def refreeze_radius(self) -> float:
        """Refreezing bonds particles closer than this (length): heat.refreeze_radius spacings."""
        return self.heat.refreeze_radius * self.spacing if self.heat else 0.0

    @property
    def groups(self) -> list:
        """The drawing/coupling groups: every body, then every emitter (a particle's `group` indexes this)."""
        return [*self.bodies, *self.emitters]


def heat_support(heat: Heat, spacing: float) -> float:
    """The heat kernel's support radius (length) at particle spacing `spacing` (length)."""
    return heat.radius_length or heat.radius * spacing


def particle_spacing(bodies: list, emitters: list) -> float:
    """A scene's particle spacing (length): its finest body lattice spacing; without bodies, its emitters' finest
    particle diameter; else 1. Lengths given in spacings (heat.radius, heat.refreeze_radius) scale with it."""
    if bodies:
        return min(b.spacing for b in bodies)
    if emitters:
        return min(2 * e.particle_radius for e in emitters)
    return 1.0
