"""[render]: how a scene is drawn (picture size, colour map, legend, clock, title, framing, charts, 3D camera,
motion blur), as a typed, frozen table (schema.py's spec); scene_tables.py composes it into a scene."""

from __future__ import annotations

from dataclasses import dataclass

from .arguments import MAX_FRAMES, MAX_SIDE
from .quantities import CHART_SERIES
from .schema import between, non_negative, one_of, positive, spec, unit_interval, unknown

COLOR_BY = ("temperature", "material", "speed", "phase")


def _view(box: tuple[float, ...]) -> str | None:
    """render.view: empty, or [x0, y0, x1, y1] with x0 < x1 and y0 < y1."""
    if not box:
        return None
    if len(box) != 4 or not (box[0] < box[2] and box[1] < box[3]):
        return f"expected [x0, y0, x1, y1] with x0 < x1 and y0 < y1, got {list(box)}"
    return None


@dataclass(frozen=True, kw_only=True)
class Render:
    width: int = spec(1280, doc="image width (pixels)", check=between(16, MAX_SIDE))
    height: int = spec(720, doc="image height (pixels)", check=between(16, MAX_SIDE))
    fps: float = spec(30.0, doc="frames per second of the video", check=positive)
    frames: int = spec(300, doc="frames in a headless run", check=between(1, MAX_FRAMES))
    color_by: str = spec("temperature", doc="temperature, material, speed or phase", check=one_of(*COLOR_BY))
    temperature_range: tuple[float, ...] = spec(
        (20.0, 200.0), doc="[cold, hot] ends of the temperature colour bar (°C)"
    )
    speed_range: float = spec(10.0, doc="speed drawn brightest when colouring by speed", check=positive)
    background: tuple[float, ...] = spec((0.06, 0.07, 0.09), doc="background colour [r, g, b]", length=3)
    particle_scale: float = spec(1.0, doc="drawn radius as a multiple of the particle radius", check=positive)
    camera_position: tuple[float, ...] = spec((), doc="3D: camera position (default: in front of the domain)", length=3)
    camera_target: tuple[float, ...] = spec((), doc="3D: the point looked at (default: domain centre)", length=3)
    fov: float = spec(40.0, doc="3D: vertical field of view in degrees", check=positive)
    light_direction: tuple[float, ...] = spec((0.4, 0.8, 0.5), doc="3D: direction towards the light", length=3)
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
    legend: bool = spec(
        True,
        doc="the legend at the top right: a colour bar with its range and unit (temperature, speed), or a swatch per "
        "material (material) or per solid and melt (phase)",
    )
    clock: bool = spec(True, doc="videos and pictures: the simulated time (t = 2.40 s) under the title")
    title: bool = spec(True, doc="videos and pictures: the scene's name at the top left")
    text_scale: float = spec(
        1.0,
        doc="text and legend size as a multiple of the default (1/40 of the picture's height): 1.5 for a projector",
        check=between(0.5, 4.0),
    )
    frame: str = spec(
        "content",
        doc="2D: what the picture shows: content (the bodies, heat sources and emitters, with a margin) or domain "
        "(the whole box)",
        check=one_of("content", "domain"),
    )
    view: tuple[float, ...] = spec((), doc="2D: the world box [x0, y0, x1, y1] to show (overrides frame)", check=_view)
    ground: bool = spec(True, doc="3D: a faint grid on the floor of the domain so depth reads")
    chart: list[str] = spec(
        doc="measurements to plot against time in a corner (window and video), e.g. "
        '["mean_temperature", "molten_fraction"]; one of: ' + ", ".join(CHART_SERIES),
        factory=list,
        check=lambda names: next((unknown("series", n, CHART_SERIES) for n in names if n not in CHART_SERIES), None),
    )
    surface_smoothing: float = spec(
        2.0,
        doc="caches with surfaces (--cache-surface): the SPH smoothing length in particle radii",
        check=between(0.5, 8.0),
    )
    surface_iso: float = spec(
        0.6, doc="caches with surfaces: the iso-level of the particles' normalised density", check=between(0.05, 0.95)
    )
    surface_cell: float = spec(
        0.5,
        doc="caches with surfaces: the marching-cubes cell in particle radii (smaller: finer, slower)",
        check=between(0.1, 4.0),
    )
