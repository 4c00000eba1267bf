"""Scene files: TOML → a typed, validated, immutable Scene. Opening a scene never runs code.

A scene is data: [scene], [world], optional [pair] and [heat] (a scene without them builds no pair or heat pass),
[[bodies]], [render] and optional [materials.NAME] tables. Every error names the file, the key and what was expected;
`sandbox keys` prints the full reference of keys with defaults and meanings.
"""

from __future__ import annotations

import copy
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .arguments import MAX_FRAMES, MAX_SIDE, MAX_SUBSTEPS
from .budget import check_size
from .errors import SceneError
from .materials import ASSETS_DIR, Material, resolve_materials
from .schema import at_least, between, celsius, non_negative, one_of, parse_table, positive, spec, unit_interval

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

# Kept equal to integrators.REGISTRY (a test checks), so validating a scene needs no Taichi import.
INTEGRATORS = ("symplectic_euler", "forward_euler", "midpoint", "verlet", "velocity_verlet", "rk4", "implicit_euler")
SHAPES = ("box", "disk", "sphere", "mask")
LATTICES = ("square", "hex", "cubic", "fcc")
COLOR_BY = ("temperature", "material", "speed", "phase")
SOURCE_MODES = ("exchange", "fixed", "power")  # heat source modes (physics/heat.py)
FIELD_KINDS = ("wind", "vortex", "source", "explosion", "noise")  # velocity field elements (physics/fields.py)
COUPLINGS = ("none", "kinematic", "drag")  # how a body or emitter's particles follow the velocity field
CHART_SERIES = (  # Stats fields a render.chart can plot (render/chart.py)
    "mean_temperature",
    "molten_fraction",
    "heat_content",
    "kinetic_energy",
    "potential_energy",
    "total_energy",
    "max_speed",
)


MAX_ITERATIONS = 100_000  # CG iteration caps: a step must end
MAX_BONDS = 64  # bonds per particle that refreezing may fill up to (spare spring slots: capacity x bonds / 2)
MAX_EXPONENT = 64  # a whole-number exponent is unrolled into multiplications when the kernels compile


def exponent(x: float) -> str | None:
    return None if 0 < x <= MAX_EXPONENT else f"expected a number above 0 and at most {MAX_EXPONENT}, got {x}"


@dataclass(frozen=True, kw_only=True)
class Lesson:
    """[scene.lesson]: a short lesson in a teacher's words, shown by `sandbox list` and at the top of the window."""

    happens: str = spec("", doc="what happens in the scene, in a sentence or two")
    explore: str = spec("", doc="what to try: keys, tools, --set values")
    physics: str = spec("", doc="the physics it shows")

    def parts(self) -> list[tuple[str, str]]:
        """(label, text) for each part given: "What happens", "Try", "The physics"."""
        parts = (("What happens", self.happens), ("Try", self.explore), ("The physics", self.physics))
        return [(label, text) for label, text in parts if text]


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
    lo: tuple[float, ...] = spec(doc="lower corner of the domain box")
    hi: tuple[float, ...] = spec(doc="upper corner of the domain box")
    gravity: tuple[float, ...] = spec((), doc="gravitational acceleration vector (default zero)")
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


@dataclass(frozen=True, kw_only=True)
class HeatSource:
    name: str = spec("plate", doc="label shown in the picture")
    lo: tuple[float, ...] = spec(doc="lower corner of the source region")
    hi: tuple[float, ...] = spec(doc="upper corner of the source region")
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
    visible: bool = spec(True, doc="2D: draw the region (in its glow colour)")


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


@dataclass(frozen=True, kw_only=True)
class FieldElement:
    kind: str = spec(
        doc="wind, vortex, source (negative strength: a sink), explosion or noise", check=one_of(*FIELD_KINDS)
    )
    center: tuple[float, ...] = spec((), doc="vortex/source/explosion: centre (a point on the axis for a 3D vortex)")
    axis: tuple[float, ...] = spec((), doc="3D vortex: axis direction (default +z)")
    velocity: tuple[float, ...] = spec((), doc="wind: the uniform velocity")
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
    lo: tuple[float, ...] = spec(doc="lower corner of the region")
    hi: tuple[float, ...] = spec(doc="upper corner of the region")
    temperature: float = spec(doc="cells inside are held at this temperature (degrees)", check=celsius)
    velocity: tuple[float, ...] = spec((), doc="inflow velocity imposed on the region's faces (default none)")


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
    center: tuple[float, ...] = spec((), doc="point/disk/sphere: centre")
    lo: tuple[float, ...] = spec((), doc="box: lower corner")
    hi: tuple[float, ...] = spec((), doc="box: upper corner")
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
    velocity: tuple[float, ...] = spec((), doc="base velocity (default zero)")
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
    lo: tuple[float, ...] = spec((), doc="box/mask: lower corner")
    hi: tuple[float, ...] = spec((), doc="box/mask: upper corner")
    center: tuple[float, ...] = spec((), doc="disk/sphere: centre")
    radius: float = spec(0.0, doc="disk/sphere: radius", check=non_negative)
    mask: str = spec("", doc="mask: PNG file (inside the scene's folder or assets/); opaque/bright pixels are inside")
    lattice: str = spec(
        "", doc="square or hex (2D), cubic or fcc (3D); default square/cubic", check=one_of("", *LATTICES)
    )
    spacing: float = spec(1.0, doc="nearest-neighbour distance of the lattice (length)", check=positive)
    springs: bool = spec(True, doc="join neighbours by springs (a solid); false: a liquid from the start")
    spring_radius: float = spec(1.5, doc="join lattice neighbours closer than this many spacings", check=at_least(1.0))
    temperature: float | None = spec(None, doc="initial temperature (default: the ambient)", check=celsius)
    velocity: tuple[float, ...] = spec((), doc="initial velocity")
    random_velocity: float = spec(0.0, doc="std. dev. of random initial velocity per component", check=non_negative)
    jitter: float = spec(0.0, doc="random displacement of lattice sites, as a fraction of spacing", check=unit_interval)
    seed: int = spec(0, doc="random seed for velocity and jitter")
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
class Render:
    width: int = spec(1280, doc="image width (pixels)", check=between(16, MAX_SIDE))
    height: int = spec(720, doc="image height (pixels)", check=between(16, MAX_SIDE))
    fps: float = spec(30.0, doc="frames per second of the video", check=positive)
    frames: int = spec(300, doc="frames in a headless run", check=between(1, MAX_FRAMES))
    color_by: str = spec("temperature", doc="temperature, material, speed or phase", check=one_of(*COLOR_BY))
    temperature_range: tuple[float, ...] = spec((20.0, 200.0), doc="[cold, hot] ends of the glow colour map")
    speed_range: float = spec(10.0, doc="speed drawn brightest when colouring by speed", check=positive)
    background: tuple[float, ...] = spec((0.06, 0.07, 0.09), doc="background colour [r, g, b]")
    particle_scale: float = spec(1.0, doc="drawn radius as a multiple of the particle radius", check=positive)
    camera_position: tuple[float, ...] = spec((), doc="3D: camera position (default: in front of the domain)")
    camera_target: tuple[float, ...] = spec((), doc="3D: the point looked at (default: domain centre)")
    fov: float = spec(40.0, doc="3D: vertical field of view in degrees", check=positive)
    light_direction: tuple[float, ...] = spec((0.4, 0.8, 0.5), doc="3D: direction towards the light")
    specular: float = spec(0.25, doc="3D: strength of the specular highlight on spheres", check=non_negative)
    motion_blur: bool = spec(False, doc="draw each particle as a streak from its position a shutter ago")
    shutter: float = spec(1.0, doc="motion blur: the fraction of a frame the shutter is open", check=unit_interval)
    motion_path: str = spec(
        "line",
        doc="motion blur: a straight streak (line) or a curve through the position at the frame's middle substep "
        "(spline: a quadratic, so orbits and bounces bend)",
        check=one_of("line", "spline"),
    )
    exposure: float = spec(1.0, doc="additive light: tone map 1 - exp(-exposure * light)", check=positive)
    draw_springs: bool = spec(False, doc="2D: draw live springs as lines")
    legend: bool = spec(False, doc="draw a colour bar for the colour map, with its range and unit, in a corner")
    clock: bool = spec(False, doc="videos and pictures: print the simulated time (t = 2.40 s) in the bottom-left")
    ground: bool = spec(True, doc="3D: a faint grid on the floor of the domain so depth reads")
    chart: list[str] = spec(
        doc="measurements to plot against time in a corner (window and video), e.g. "
        '["mean_temperature", "molten_fraction"]; one of: ' + ", ".join(CHART_SERIES),
        factory=list,
        check=lambda names: next(
            (
                f"unknown series {n!r}; expected one of: {', '.join(CHART_SERIES)}"
                for n in names
                if n not in CHART_SERIES
            ),
            None,
        ),
    )


@dataclass(frozen=True, kw_only=True)
class _SceneFile:
    scene: SceneInfo = spec(doc="[scene]", factory=SceneInfo)
    world: World = spec(doc="[world]")
    pair: PairForce | None = spec(None, doc="[pair]")
    heat: Heat | None = spec(None, doc="[heat]")
    bodies: list[Body] = spec(doc="[[bodies]]", factory=list)
    emitters: list[Emitter] = spec(doc="[[emitters]]", factory=list)
    fields: list[FieldElement] = spec(doc="[[fields]]", factory=list)
    smoke: Smoke | None = spec(None, doc="[smoke]")
    render: Render = spec(doc="[render]", factory=Render)
    materials: dict | None = spec(None, doc="[materials.NAME]")


@dataclass(frozen=True, kw_only=True)
class Scene:
    """A validated scene: what to build and how to run and draw it."""

    name: str
    description: str
    path: Path
    world: World
    pair: PairForce | None
    heat: Heat | None
    bodies: list[Body]
    render: Render
    materials: dict[str, Material] = field(repr=False)
    emitters: list[Emitter] = field(default_factory=list)
    fields: list[FieldElement] = field(default_factory=list)
    smoke: Smoke | None = None

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


def parse_override(text: str) -> tuple[str, Any]:
    """Split `key=value` and read the value as TOML (number, bool, array, string); bare words become strings."""
    if "=" not in text:
        raise SceneError("--set", text, "expected key=value")
    key, raw = (s.strip() for s in text.split("=", 1))
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value


def apply_override(data: dict, key: str, value: Any) -> None:
    """Set a dotted key (`world.dt`, `bodies.0.temperature`, `heat.sources.0.temperature`) in the raw scene table."""
    parts = key.split(".")
    node: Any = data
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise SceneError("--set", key, f"'{part}' is not an index below {len(node)}")
            if last:
                node[int(part)] = value
            else:
                node = node[int(part)]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise SceneError("--set", key, f"'{'.'.join(parts[:i])}' is not a table or array")


def read_scene_table(path: Path, missing: str = "no such scene file") -> dict:
    """The raw table of a scene file (TOML); SceneError naming the file when it is missing (`missing` says what was
    expected), a folder, or not TOML."""
    file = str(path)
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError as exc:
        raise SceneError(file, "", missing) from exc
    except IsADirectoryError as exc:
        raise SceneError(file, "", "is a folder; expected a scene file (.toml)") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(file, "", f"not valid TOML: {exc}") from exc


def load_scene(path: str | Path, overrides: list[str] | None = None) -> Scene:
    """Read, override and validate a scene file. Raises SceneError naming the file, key and expectation."""
    path = Path(path)
    data = read_scene_table(path)
    for text in overrides or []:
        key, value = parse_override(text)
        apply_override(data, key, value)
    return scene_from_dict(data, path)


def scene_from_dict(data: dict, path: Path) -> Scene:
    """Validate a raw scene table (as read from TOML) into a Scene; `path` names it in errors and anchors files."""
    file = str(path)
    raw = parse_table(_SceneFile, data, file)
    materials = resolve_materials(raw.materials or {}, file)
    world: World = raw.world
    dim = world.dim
    _check_vec(file, "world.lo", world.lo, dim)
    _check_vec(file, "world.hi", world.hi, dim)
    if any(h <= l for l, h in zip(world.lo, world.hi)):
        raise SceneError(file, "world.hi", f"expected every component above world.lo {list(world.lo)}")
    if world.substeps == "auto" and world.frame_time / world.dt > MAX_SUBSTEPS:
        raise SceneError(
            file,
            "world.frame_time",
            f"{world.frame_time:g} is over {MAX_SUBSTEPS:,} steps of dt {world.dt:g}; expected a shorter frame or a "
            "longer step",
        )
    if world.gravity:
        _check_vec(file, "world.gravity", world.gravity, dim)
    else:
        world = _replace(world, gravity=(0.0,) * dim)
    if raw.pair is not None and raw.pair.b <= raw.pair.a:
        raise SceneError(file, "pair.b", f"expected the repulsion exponent b above a = {raw.pair.a}")
    for i, name in enumerate(raw.scene.palette):
        if name not in materials:
            raise SceneError(
                file,
                f"scene.palette[{i}]",
                f"unknown material {name!r}; expected one of: {', '.join(sorted(materials))}",
            )
    if not raw.bodies and not raw.emitters and not raw.scene.palette:
        raise SceneError(
            file, "bodies", "expected at least one [[bodies]] or [[emitters]] table, or a scene.palette to spawn from"
        )
    emitters = [_check_emitter(file, f"emitters[{i}]", e, i, dim, materials, path) for i, e in enumerate(raw.emitters)]
    for i, element in enumerate(raw.fields):
        _check_field(file, f"fields[{i}]", element, dim)
    if raw.smoke is not None:
        for i, src in enumerate(raw.smoke.sources):
            _check_box(file, f"smoke.sources[{i}]", src.lo, src.hi, dim)
            if src.velocity:
                _check_vec(file, f"smoke.sources[{i}].velocity", src.velocity, dim)
    bodies = [_check_body(file, f"bodies[{i}]", b, i, dim, materials, path) for i, b in enumerate(raw.bodies)]
    for i, body in enumerate(bodies):
        lo, hi = _body_bounds(body)
        if any(a < l - 1e-9 for a, l in zip(lo, world.lo)) or any(b > h + 1e-9 for b, h in zip(hi, world.hi)):
            raise SceneError(
                file,
                f"bodies[{i}]",
                f"the body ({list(lo)}..{list(hi)}) lies outside the domain "
                f"{list(world.lo)}..{list(world.hi)}; expected it inside world.lo..world.hi",
            )
    spacing = particle_spacing(bodies, emitters)
    heat = raw.heat
    if heat is not None:
        for i, src in enumerate(heat.sources):
            _check_source(file, f"heat.sources[{i}]", src, dim)
        reach = max(heat_support(heat, spacing), raw.pair.cutoff if raw.pair else 0.0)
        if heat.refreeze and heat.refreeze_radius * spacing > reach + 1e-12:
            raise SceneError(
                file,
                "heat.refreeze_radius",
                f"{heat.refreeze_radius:g} spacings is {heat.refreeze_radius * spacing:g} long; expected at most the "
                f"neighbour reach {reach:g} (the heat radius, pair.cutoff)",
            )
    if world.periodic:
        reach = max(raw.pair.cutoff if raw.pair else 0.0, heat_support(heat, spacing) if heat else 0.0)
        if any((h - l) < 3 * reach for l, h in zip(world.lo, world.hi)):
            raise SceneError(file, "world.periodic", f"expected every side of a periodic domain >= 3 x {reach}")
    render = raw.render
    _check_render(file, render, dim)
    check_size(file, world, bodies, emitters, bool(raw.pair or heat), raw.smoke)
    return Scene(
        name=raw.scene.name or path.stem,
        description=raw.scene.description,
        path=path,
        world=world,
        pair=raw.pair,
        heat=heat,
        bodies=bodies,
        render=render,
        materials={
            name: materials[name]
            for name in dict.fromkeys([b.material for b in bodies] + [e.material for e in emitters] + raw.scene.palette)
        },
        palette=list(raw.scene.palette),
        lesson=raw.scene.lesson,
        emitters=emitters,
        fields=list(raw.fields),
        smoke=raw.smoke,
        spacing=spacing,
        source=copy.deepcopy(data),
    )


def _replace(obj, **changes):
    import dataclasses

    return dataclasses.replace(obj, **changes)


def _body_bounds(body: Body) -> tuple[tuple[float, ...], tuple[float, ...]]:
    if body.shape in ("disk", "sphere"):
        return tuple(c - body.radius for c in body.center), tuple(c + body.radius for c in body.center)
    return body.lo, body.hi


def _check_vec(file: str, key: str, vec: tuple, dim: int) -> None:
    if len(vec) != dim:
        raise SceneError(file, key, f"expected {dim} numbers (world.dim = {dim}), got {len(vec)}")


def _check_box(file: str, key: str, lo: tuple, hi: tuple, dim: int) -> None:
    """A region's corners: dim numbers each, and hi above lo on every axis."""
    _check_vec(file, f"{key}.lo", lo, dim)
    _check_vec(file, f"{key}.hi", hi, dim)
    if any(h <= l for l, h in zip(lo, hi)):
        raise SceneError(file, f"{key}.hi", f"expected every component above {key}.lo {list(lo)}, got {list(hi)}")


def _check_source(file: str, key: str, src: HeatSource, dim: int) -> None:
    _check_box(file, key, src.lo, src.hi, dim)
    if src.mode != "power" and src.temperature is None:
        raise SceneError(file, f"{key}.temperature", f"missing; expected a number (degrees) for a {src.mode} source")
    times, values = src.schedule_times, src.schedule_values
    if len(times) != len(values):
        raise SceneError(
            file,
            f"{key}.schedule_values",
            f"expected as many values as schedule_times ({len(times)}), got {len(values)}",
        )
    if src.mode != "power":
        for k, value in enumerate(values):
            problem = celsius(value)
            if problem:
                raise SceneError(file, f"{key}.schedule_values[{k}]", problem)
    if times and (times[0] != 0 or any(b <= a for a, b in zip(times, times[1:]))):
        raise SceneError(file, f"{key}.schedule_times", f"expected increasing times starting at 0, got {list(times)}")
    if src.schedule_period and times and src.schedule_period <= times[-1]:
        raise SceneError(
            file, f"{key}.schedule_period", f"expected a period longer than the last schedule time {times[-1]:g}"
        )


def _check_field(file: str, key: str, element: FieldElement, dim: int) -> None:
    if element.kind in ("vortex", "source", "explosion"):
        if not element.center:
            raise SceneError(file, f"{key}.center", f"missing; expected {dim} numbers for a {element.kind}")
        _check_vec(file, f"{key}.center", element.center, dim)
    if element.kind == "wind":
        _check_vec(file, f"{key}.velocity", element.velocity, dim)
    if element.axis:
        _check_vec(file, f"{key}.axis", element.axis, 3)
        if not any(element.axis):
            raise SceneError(file, f"{key}.axis", "expected a non-zero direction")


def _check_emitter(file: str, key: str, e: Emitter, index: int, dim: int, materials: dict, path: Path) -> Emitter:
    if e.material not in materials:
        raise SceneError(
            file, f"{key}.material", f"unknown material {e.material!r}; expected one of: {', '.join(sorted(materials))}"
        )
    changes: dict[str, Any] = {"name": e.name or f"emitter{index}"}
    if e.color and (len(e.color) != 3 or not all(0 <= c <= 1 for c in e.color)):
        raise SceneError(file, f"{key}.color", f"expected [r, g, b] with each in [0, 1], got {list(e.color)}")
    if e.shape == "mask":
        if dim != 2:
            raise SceneError(file, f"{key}.shape", "a PNG mask shapes 2D emitters only")
        changes["mask"] = str(resolve_png(file, f"{key}.mask", e.mask, path))
    if e.shape in ("box", "mask"):
        _check_box(file, key, e.lo, e.hi, dim)
    else:
        _check_vec(file, f"{key}.center", e.center, dim)
    if e.shape in ("disk", "sphere"):
        want = 2 if e.shape == "disk" else 3
        if dim != want:
            raise SceneError(file, f"{key}.shape", f"{e.shape!r} needs world.dim = {want}")
        if e.size <= 0:
            raise SceneError(file, f"{key}.size", f"expected the {e.shape}'s radius > 0")
    if e.surface and e.shape == "point":
        raise SceneError(file, f"{key}.surface", "a point has no surface; expected a box, disk or sphere")
    if e.velocity:
        _check_vec(file, f"{key}.velocity", e.velocity, dim)
    else:
        changes["velocity"] = (0.0,) * dim
    if e.draw == "sphere" and dim == 2:
        raise SceneError(file, f"{key}.draw", "'sphere' is a 3D drawing; expected splat or dot in 2D")
    if e.blend != "opaque" and e.draw == "sphere":
        raise SceneError(file, f"{key}.blend", 'shaded spheres are opaque; use draw = "splat" for alpha or additive')
    if e.refill_density and (e.shape in ("point", "mask") or e.surface):
        raise SceneError(file, f"{key}.refill_density", "refilling needs a region: a box, disk or sphere, not surface")
    if e.bursts and e.burst_count == 0:
        raise SceneError(file, f"{key}.burst_count", "expected a count > 0 with bursts")
    if e.stop <= e.start:
        raise SceneError(file, f"{key}.stop", f"expected a time after start ({e.start:g})")
    return _replace(e, **changes)


def _check_body(file: str, key: str, body: Body, index: int, dim: int, materials: dict, scene_path: Path) -> Body:
    if body.material not in materials:
        raise SceneError(
            file,
            f"{key}.material",
            f"unknown material {body.material!r}; expected one of: {', '.join(sorted(materials))}",
        )
    changes: dict[str, Any] = {}
    if not body.name:
        changes["name"] = f"body{index}"
    lattice = body.lattice or ("square" if dim == 2 else "cubic")
    if body.draw == "sphere" and dim == 2:
        raise SceneError(file, f"{key}.draw", "'sphere' is a 3D drawing; expected splat or dot in 2D")
    if not body.draw:
        changes["draw"] = "splat" if dim == 2 else "sphere"
    if body.blend != "opaque" and body.draw == "sphere":
        raise SceneError(
            file, f"{key}.blend", 'shaded spheres are opaque; use draw = "splat" for alpha or additive bodies'
        )
    if (dim == 2) != (lattice in ("square", "hex")):
        raise SceneError(file, f"{key}.lattice", f"lattice {lattice!r} does not exist in {dim}D")
    changes["lattice"] = lattice
    if body.shape in ("box", "mask"):
        _check_box(file, key, body.lo, body.hi, dim)
    if body.shape in ("disk", "sphere"):
        want = 2 if body.shape == "disk" else 3
        if dim != want:
            raise SceneError(
                file,
                f"{key}.shape",
                f"{body.shape!r} needs world.dim = {want}; use {'sphere' if want == 2 else 'disk'}",
            )
        _check_vec(file, f"{key}.center", body.center, dim)
        if body.radius <= 0:
            raise SceneError(file, f"{key}.radius", "expected a radius > 0 for a disk or sphere")
    if body.shape == "mask":
        if dim != 2:
            raise SceneError(file, f"{key}.shape", "a PNG mask shapes 2D bodies only")
        changes["mask"] = str(resolve_png(file, f"{key}.mask", body.mask, scene_path))
    if body.velocity:
        _check_vec(file, f"{key}.velocity", body.velocity, dim)
    else:
        changes["velocity"] = (0.0,) * dim
    return _replace(body, **changes)


def resolve_data_file(file: str, key: str, name: str, scene_path: Path) -> Path:
    """Resolve a file named in a scene; it must exist inside the scene's folder or the project's assets/ folder."""
    if not name:
        raise SceneError(file, key, "expected a file name")
    scene_dir = scene_path.resolve().parent
    assets = ASSETS_DIR.resolve()
    if Path(name).is_absolute() or ".." in Path(name).parts:
        raise SceneError(
            file,
            key,
            f"{name!r} points outside the scene's folder and assets/; expected a relative "
            "name of a file inside one of them",
        )
    for root in (scene_dir, assets.parent, assets):
        cand = (root / name).resolve()  # resolve() follows links, so a link out of the folders is caught below
        if cand.is_file() and (cand.is_relative_to(scene_dir) or cand.is_relative_to(assets)):
            return cand
    raise SceneError(file, key, f"file {name!r} not found in the scene's folder or assets/")


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def resolve_png(file: str, key: str, name: str, scene_path: Path) -> Path:
    """resolve_data_file for a PNG image: the file must start with the PNG signature."""
    path = resolve_data_file(file, key, name, scene_path)
    with open(path, "rb") as image:
        if image.read(len(PNG_SIGNATURE)) != PNG_SIGNATURE:
            raise SceneError(file, key, f"{name!r} is not a PNG image; expected a .png file")
    return path


def _check_render(file: str, render: Render, dim: int) -> None:
    if len(render.temperature_range) != 2 or render.temperature_range[1] <= render.temperature_range[0]:
        raise SceneError(file, "render.temperature_range", "expected [cold, hot] with hot > cold")
    if len(render.background) != 3:
        raise SceneError(file, "render.background", "expected [r, g, b]")
    if dim == 3:
        if render.camera_position:
            _check_vec(file, "render.camera_position", render.camera_position, 3)
        if render.camera_target:
            _check_vec(file, "render.camera_target", render.camera_target, 3)
        _check_vec(file, "render.light_direction", render.light_direction, 3)
    if not math.isfinite(render.fps):
        raise SceneError(file, "render.fps", "expected a finite number")
