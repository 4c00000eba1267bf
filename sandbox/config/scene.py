"""Scene files: TOML → a typed, validated, immutable Scene. Opening a scene never runs code.

A scene is data: [scene], [world], optional [pair] and [heat] (a scene without them builds no pair or heat pass),
[[bodies]], [render] and optional [materials.NAME] tables. Every error names the file, the key and what was expected;
`sandbox keys` prints the full reference of keys with defaults and meanings.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

from ..errors import SceneError
from .arguments import MAX_SUBSTEPS
from .budget import check_size
from .materials import ASSETS_DIR, resolve_materials
from .resources import read_small_text
from .scene_tables import (
    WALL_SIDES,
    Body,
    Emitter,
    FieldElement,
    HeatSource,
    Render,
    Scene,
    SceneSections,
    World,
    _SceneFile,
    heat_support,
    particle_spacing,
)
from .schema import celsius, check_lengths, parse_table, unknown

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def parse_override(text: str) -> tuple[str, Any]:
    """Split `key=value` and read the value as TOML (number, bool, array, string); bare words become strings."""
    if "=" not in text:
        raise SceneError("--set", text, "expected key=value")
    key, raw = (s.strip() for s in text.split("=", 1))
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except RecursionError:
        value = None
    check_depth(value, "--set", key)
    return key, value


MAX_DEPTH = 16  # tables and arrays inside one another; a scene needs about five


def check_depth(data: Any, file: str, key: str = "", limit: int = MAX_DEPTH) -> None:
    """SceneError when `data` nests tables or arrays deeper than `limit` (checked without recursion, so a crafted
    file cannot exhaust the stack), or could not even be read for its depth (`data` None from a RecursionError)."""
    if data is None:
        raise SceneError(file, key, f"nested too deeply; expected tables and arrays at most {limit} deep")
    stack = [(data, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, dict | list):
            if depth >= limit:
                raise SceneError(file, key, f"nested more than {limit} deep; expected a flatter table")
            stack.extend((child, depth + 1) for child in (node.values() if isinstance(node, dict) else node))


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
        data = tomllib.loads(read_small_text(path))
    except RecursionError:
        data = None
    except FileNotFoundError as exc:
        raise SceneError(file, "", missing) from exc
    except IsADirectoryError as exc:
        raise SceneError(file, "", "is a folder; expected a scene file (.toml)") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(file, "", f"not valid TOML: {exc}") from exc
    except ValueError as exc:
        raise SceneError(file, "", str(exc)) from exc
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise SceneError(file, "", f"cannot be read ({reason}); expected a scene file") from exc
    check_depth(data, file)
    return data


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
    check_depth(data, file)
    raw = parse_table(_SceneFile, data, file)
    materials = resolve_materials(raw.materials or {}, file)
    world: World = raw.world
    dim = world.dim
    check_lengths(raw, dim, file)  # every vector declared with a length: world.lo, bodies[0].velocity, ...
    world = _check_world(file, world)
    if raw.pair is not None and raw.pair.law == "power" and raw.pair.b <= raw.pair.a:
        raise SceneError(file, "pair.b", f"expected the repulsion exponent b above a = {raw.pair.a}")
    if raw.pair is not None and raw.pair.force_shift and raw.heat is not None:
        raise SceneError(file, "pair.force_shift", "expected no [heat] table with it: the force shift is for atoms")
    for i, name in enumerate(raw.scene.palette):
        if name not in materials:
            raise SceneError(
                file,
                f"scene.palette[{i}]",
                unknown("material", name, materials),
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
    if raw.pair is not None and raw.pair.law == "morse" and raw.heat is not None:
        boiling = [name for name in used_names(bodies, emitters, raw.scene.palette) if materials[name].boils]
        if boiling:
            raise SceneError(
                file,
                "pair.law",
                f"{boiling[0]} boils, and its vapour loses the power law's attraction; expected law = "
                '"power" with a material that boils',
            )
    lesson_problem = raw.scene.lesson.problem()
    if lesson_problem:
        raise SceneError(file, f"scene.lesson.{lesson_problem[0]}", lesson_problem[1])
    heat = raw.heat
    _check_molecular(file, raw)
    _check_reach(file, world, heat, raw.pair, spacing)
    render = raw.render
    _check_render(file, render, dim)
    reach = raw.pair.cutoff if raw.pair else 1.0
    check_size(file, world, bodies, emitters, bool(raw.pair or heat), raw.smoke, reach)
    sections = {f.name: getattr(raw, f.name) for f in dataclasses.fields(SceneSections)}
    sections.update(world=world, bodies=bodies, emitters=emitters, fields=list(raw.fields))  # as checked above
    used = used_names(bodies, emitters, raw.scene.palette)
    return Scene(
        **sections,
        name=raw.scene.name or path.stem,
        description=raw.scene.description,
        path=path,
        materials={name: materials[name] for name in used},
        palette=list(raw.scene.palette),
        lesson=raw.scene.lesson,
        spacing=spacing,
        source=copy.deepcopy(data),
    )


def used_names(bodies, emitters, palette) -> list[str]:
    """The materials a scene uses, in first-use order: the bodies', the emitters', then the palette's."""
    return list(dict.fromkeys([b.material for b in bodies] + [e.material for e in emitters] + list(palette)))


def _check_molecular(file: str, raw) -> None:
    """The molecular model needs a pair force and no heat field (its temperature is the atoms' motion); each thermal
    wall is a wall of this box, named once, and the box has walls."""
    molecular = raw.molecular
    if molecular is None:
        return
    if raw.pair is None:
        raise SceneError(file, "molecular", "the molecular model needs a [pair] table: the atoms' force")
    if raw.heat is not None:
        raise SceneError(  # named as [molecular]: a --set of a molecular key on a heat scene is what adds it
            file,
            "molecular",
            "expected [molecular] or [heat], not both: a molecular scene's temperature is measured from the motion",
        )
    if molecular.phase_radius > raw.pair.cutoff:
        raise SceneError(
            file,
            "molecular.phase_radius",
            f"expected at most the pair cutoff {raw.pair.cutoff:g} (its neighbour reach)",
        )
    lid = molecular.lid
    if lid is not None:
        lo, hi = raw.world.lo[1], raw.world.hi[1]
        if raw.world.periodic:
            raise SceneError(
                file, "molecular.lid", "a periodic box has no top for a lid; expected world.periodic = false"
            )
        if not lo < lid.height <= hi:
            raise SceneError(file, "molecular.lid.height", f"expected a height in ({lo:g}, {hi:g}], got {lid.height:g}")
        for i, body in enumerate(raw.bodies):
            if body.shape == "box" and body.hi[1] > lid.height:
                raise SceneError(
                    file, f"bodies[{i}]", f"the body reaches above the lid (at {lid.height:g}); expected it below"
                )
        if any(w.side == "top" for w in molecular.walls):
            raise SceneError(file, "molecular.lid", "the top wall is a thermal wall; expected the lid or the wall")
    seen = set()
    if molecular.heater is not None:
        check_schedule(file, "molecular.heater", molecular.heater)
    if molecular.lid:
        check_schedule(file, "molecular.lid", molecular.lid)
        for k, value in enumerate(molecular.lid.schedule_values):
            if not value >= 0:
                raise SceneError(file, f"molecular.lid.schedule_values[{k}]", f"expected a pressure >= 0, got {value}")
    for i, wall in enumerate(molecular.walls):
        axis, _ = WALL_SIDES[wall.side]
        if axis >= raw.world.dim:
            raise SceneError(file, f"molecular.walls[{i}].side", f"{wall.side!r} is a wall of a 3D box only")
        if wall.side in seen:
            raise SceneError(file, f"molecular.walls[{i}].side", f"the {wall.side} wall is named twice")
        seen.add(wall.side)
        if raw.world.periodic:
            raise SceneError(
                file, f"molecular.walls[{i}]", "a periodic box has no walls; expected world.periodic = false"
            )


def _check_world(file: str, world: World) -> World:
    """The box (hi above lo), the frame's step count under "auto", and gravity zero where none is given."""
    _check_box(file, "world", world.lo, world.hi, world.dim)
    if world.substeps == "auto" and world.frame_time / world.dt > MAX_SUBSTEPS:
        raise SceneError(
            file,
            "world.frame_time",
            f"{world.frame_time:g} is over {MAX_SUBSTEPS:,} steps of dt {world.dt:g}; expected a shorter frame or a "
            "longer step",
        )
    return world if world.gravity else _replace(world, gravity=(0.0,) * world.dim)


def _check_reach(file: str, world: World, heat, pair, spacing: float) -> None:
    """The heat sources, refreezing within the neighbour reach, and a periodic box at least three reaches wide."""
    if heat is not None:
        for i, src in enumerate(heat.sources):
            _check_source(file, f"heat.sources[{i}]", src, world.dim)
        reach = max(heat_support(heat, spacing), pair.cutoff if pair else 0.0)
        if heat.refreeze and heat.refreeze_radius * spacing > reach + 1e-12:
            raise SceneError(
                file,
                "heat.refreeze_radius",
                f"{heat.refreeze_radius:g} spacings is {heat.refreeze_radius * spacing:g} long; expected at most the "
                f"neighbour reach {reach:g} (the heat radius, pair.cutoff)",
            )
    if world.periodic:
        reach = max(pair.cutoff if pair else 0.0, heat_support(heat, spacing) if heat else 0.0)
        if any((h - l) < 3 * reach for l, h in zip(world.lo, world.hi)):
            raise SceneError(file, "world.periodic", f"expected every side of a periodic domain >= 3 x {reach}")


def _replace(obj, **changes):
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
    check_schedule(file, key, src)
    if src.mode != "power":
        for k, value in enumerate(src.schedule_values):
            problem = celsius(value)
            if problem:
                raise SceneError(file, f"{key}.schedule_values[{k}]", problem)


def check_schedule(file: str, key: str, table) -> None:
    """A schedule's keys (`schedule_times`, `schedule_values`, `schedule_period` of a heat source or the molecular
    heater): as many values as times, the times increasing from 0, the period longer than the last time."""
    times, values = table.schedule_times, table.schedule_values
    if len(times) != len(values):
        raise SceneError(
            file,
            f"{key}.schedule_values",
            f"expected as many values as schedule_times ({len(times)}), got {len(values)}",
        )
    if times and (times[0] != 0 or any(b <= a for a, b in zip(times, times[1:]))):
        raise SceneError(file, f"{key}.schedule_times", f"expected increasing times starting at 0, got {list(times)}")
    if table.schedule_period and times and table.schedule_period <= times[-1]:
        raise SceneError(
            file, f"{key}.schedule_period", f"expected a period longer than the last schedule time {times[-1]:g}"
        )


def _check_field(file: str, key: str, element: FieldElement, dim: int) -> None:
    if element.kind in ("vortex", "source", "explosion"):
        if not element.center:
            raise SceneError(file, f"{key}.center", f"missing; expected {dim} numbers for a {element.kind}")
        _check_vec(file, f"{key}.center", element.center, dim)
    if element.kind == "wind":
        _check_vec(file, f"{key}.velocity", element.velocity, dim)  # required for wind
    if element.axis:
        if not any(element.axis):
            raise SceneError(file, f"{key}.axis", "expected a non-zero direction")


def _check_emitter(file: str, key: str, e: Emitter, index: int, dim: int, materials: dict, path: Path) -> Emitter:
    if e.material not in materials:
        raise SceneError(file, f"{key}.material", unknown("material", e.material, materials))
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
    if not e.velocity:
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
            unknown("material", body.material, materials),
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
    if not body.velocity:
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
MAX_MASK_PIXELS = 4096 * 4096  # a mask is sampled at particle spacing: a few hundred pixels a side is plenty


def resolve_png(file: str, key: str, name: str, scene_path: Path) -> Path:
    """resolve_data_file for a PNG image: the file must start with the PNG signature, and its header (read before
    any pixel is decoded) give at most MAX_MASK_PIXELS pixels."""
    path = resolve_data_file(file, key, name, scene_path)
    with open(path, "rb") as image:
        head = image.read(24)  # the signature, then the IHDR chunk: length, type, width, height
    if head[: len(PNG_SIGNATURE)] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise SceneError(file, key, f"{name!r} is not a PNG image; expected a .png file")
    width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    if width * height > MAX_MASK_PIXELS:
        limit = f"at most {MAX_MASK_PIXELS:,} pixels (4096 x 4096)"
        raise SceneError(file, key, f"{name!r} is {width} x {height} pixels; expected {limit}")
    return path


def _check_render(file: str, render: Render, dim: int) -> None:
    if len(render.temperature_range) != 2 or render.temperature_range[1] <= render.temperature_range[0]:
        raise SceneError(file, "render.temperature_range", "expected [cold, hot] with hot > cold")
    if not render.background:
        raise SceneError(file, "render.background", "expected [r, g, b]")
    if not math.isfinite(render.fps):
        raise SceneError(file, "render.fps", "expected a finite number")
