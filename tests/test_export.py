"""Particle caches for Blender, Houdini and ParaView (issue 59), each read back by an independent reader (usd-core's
own API, VTK's XML reader, plyfile) and checked against `sim.particles()` at the frames cached: counts, time
samples, attributes, units; the surface of a sphere of particles against the sphere's area and volume; resume and
bad input as for every output; a Blender render where Blender is installed."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import sandbox
from sandbox.app.cli import EXIT_BAD_INPUT, main
from sandbox.render.surface import area_and_volume, reconstruct

pytestmark = pytest.mark.xdist_group("export")

SMALL = {"bodies.0.hi": [70.0, 8.0]}  # candle: 96 wax particles and springs, a flame of emitted ones, heat
FRAMES, EVERY = 4, 2


def padded(a: np.ndarray) -> np.ndarray:
    out = np.zeros((len(a), 3))
    out[:, : a.shape[1]] = a
    return out


@pytest.fixture(scope="module", params=["usd", "vtp", "ply"])
def cached(request, tmp_path_factory):
    """A candle cached through the Python API at frames 0, 2, 4 (with surfaces), and the particle tables then."""
    folder = tmp_path_factory.mktemp(f"cache_{request.param}")
    path = folder / f"wax.{request.param}"
    sim = sandbox.load("candle", set=SMALL, arch="cpu")
    tables = []
    with sandbox.Cache(path) as cache:
        for k in range(FRAMES + 1):
            if k % EVERY == 0:
                cache.write(sim, surface=True)
                tables.append((sim.frames_done, sim.time, sim.particles(), sim.scene.spacing))
            sim.run(1)
    return request.param, path, tables


def test_the_cache_holds_every_cached_frame_as_the_simulation_had_it(cached):
    kind, path, tables = cached
    read = {"usd": _read_usd, "vtp": _read_vtk, "ply": _read_ply}[kind]
    frames = read(path, [frame for frame, *_ in tables])
    assert [f["frame"] for f in frames] == [frame for frame, *_ in tables]
    for got, (_, time, p, _) in zip(frames, tables):
        assert got["time"] == pytest.approx(time, abs=1e-6)
        assert len(got["points"]) == len(p["id"])
        np.testing.assert_allclose(got["points"], padded(p["position"]), atol=1e-5)
        np.testing.assert_allclose(got["temperature"], p["temperature"], rtol=1e-6)
        np.testing.assert_array_equal(got["id"], p["id"])
        np.testing.assert_array_equal(got["material"], p["material"])
        assert set(np.unique(got["phase"])) <= {0, 1, 2}
        melted = p["melt_fraction"] >= 0.5
        assert np.array_equal(got["phase"] >= 1, melted | (got["phase"] == 2))
        assert got["surface_points"] > 100 and got["surface_triangles"] > 100
        t_lo, t_hi = p["temperature"].min(), p["temperature"].max()
        assert t_lo - 1e-3 <= got["surface_temperature_min"] <= got["surface_temperature_max"] <= t_hi + 1e-3


def _read_usd(path: Path, frames: list[int]) -> list[dict]:
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.001)
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (frames[0], frames[-1])
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/surface"))
    assert points and mesh
    out = []
    for frame in frames:
        prim = points.GetPrim()
        surface = np.asarray(mesh.GetPrim().GetAttribute("primvars:temp_c").Get(frame))
        out.append(
            {
                "frame": frame,
                "time": prim.GetAttribute("sandbox:time").Get(frame),
                "points": np.asarray(points.GetPointsAttr().Get(frame)),
                "temperature": np.asarray(prim.GetAttribute("primvars:temp_c").Get(frame)),
                "id": np.asarray(points.GetIdsAttr().Get(frame)),
                "material": np.asarray(prim.GetAttribute("primvars:material").Get(frame)),
                "phase": np.asarray(prim.GetAttribute("primvars:phase").Get(frame)),
                "surface_points": len(mesh.GetPointsAttr().Get(frame)),
                "surface_triangles": len(mesh.GetFaceVertexCountsAttr().Get(frame)),
                "surface_temperature_min": surface.min(),
                "surface_temperature_max": surface.max(),
            }
        )
        assert np.all(np.asarray(points.GetWidthsAttr().Get(frame)) > 0)
    return out


def _read_vtk(path: Path, frames: list[int]) -> list[dict]:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    collection = ET.parse(path.with_suffix(".pvd")).getroot().find("Collection")
    sets = [(float(d.get("timestep")), int(d.get("part")), d.get("file")) for d in collection]
    assert [part for _, part, _ in sets] == [0, 1, 2] * len(frames)  # particles, surface, the scene's parts
    out = []
    for k in range(len(frames)):
        (time, _, particles), (_, _, surface) = sets[3 * k], sets[3 * k + 1]
        data = {}
        for name in (particles, surface):
            reader = vtkXMLPolyDataReader()
            reader.SetFileName(str(path.parent / name))
            reader.Update()
            data[name] = reader.GetOutput()
        poly, mesh = data[particles], data[surface]
        arrays = {poly.GetPointData().GetArrayName(i): vtk_to_numpy(poly.GetPointData().GetArray(i)) for i in range(8)}
        temperature = vtk_to_numpy(mesh.GetPointData().GetArray("temperature"))
        assert poly.GetNumberOfVerts() == poly.GetNumberOfPoints() and poly.GetNumberOfLines() > 0
        out.append(
            {
                "frame": int(particles.split(".")[-2]),
                "time": time,
                "points": vtk_to_numpy(poly.GetPoints().GetData()),
                "temperature": arrays["temperature"],
                "id": arrays["id"],
                "material": arrays["material"],
                "phase": arrays["phase"],
                "surface_points": mesh.GetNumberOfPoints(),
                "surface_triangles": mesh.GetNumberOfPolys(),
                "surface_temperature_min": temperature.min(),
                "surface_temperature_max": temperature.max(),
            }
        )
    return out


def _read_ply(path: Path, frames: list[int]) -> list[dict]:
    from plyfile import PlyData

    out = []
    for frame in frames:
        ply = PlyData.read(str(path.with_name(f"wax.ply.{frame:05d}.ply")))
        surface = PlyData.read(str(path.with_name(f"wax.ply.surface.{frame:05d}.ply")))
        v = ply["vertex"]
        comment = ply.comments[0].split()
        assert ply.comments[1] == "unit 0.001 m up Y" and len(ply["edge"].data) > 0
        assert surface["face"].data["vertex_indices"][0].size == 3
        out.append(
            {
                "frame": int(comment[2]),
                "time": float(comment[4]),
                "points": np.stack([v["x"], v["y"], v["z"]], axis=1),
                "temperature": v["temp_c"],
                "id": v["id"],
                "material": v["material"],
                "phase": v["phase"],
                "surface_points": len(surface["vertex"].data),
                "surface_triangles": len(surface["face"].data),
                "surface_temperature_min": surface["vertex"]["temp_c"].min(),
                "surface_temperature_max": surface["vertex"]["temp_c"].max(),
            }
        )
    return out


def test_the_temperature_has_a_name_no_renderer_reserves(cached):
    """Cycles takes an attribute named `temperature` for smoke's and shades it flat: the formats Blender and Houdini
    read (USD, PLY) carry it as `temp_c`, on the particles and the surface; VTK, for ParaView, keeps `temperature`."""
    kind, path, tables = cached
    frame = tables[0][0]
    if kind == "usd":
        from pxr import Usd

        stage = Usd.Stage.Open(str(path))
        names = [set(stage.GetPrimAtPath(p).GetPropertyNames()) for p in ("/World/particles", "/World/surface")]
        assert all("primvars:temp_c" in n and "primvars:temperature" not in n for n in names)
    elif kind == "ply":
        from plyfile import PlyData

        for name in (f"wax.ply.{frame:05d}.ply", f"wax.ply.surface.{frame:05d}.ply"):
            properties = [p.name for p in PlyData.read(str(path.with_name(name)))["vertex"].properties]
            assert "temp_c" in properties and "temperature" not in properties
    else:
        text = path.with_name(f"wax.pvd.{frame:05d}.vtp").read_bytes()
        assert b'Name="temperature"' in text and b"temp_c" not in text


def test_the_surface_of_a_sphere_of_particles_has_its_area_and_volume():
    """A ball of radius 8 spacings on a cubic lattice (2,109 particles, each a unit cube of volume): the
    reconstructed surface encloses the particles' volume within 2% and has the area of that sphere within 6%
    (marching cubes' facets add a little area), and the values interpolated onto it are the particles' there."""
    g = np.arange(-12, 13, dtype=np.float64)
    lattice = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    ball = lattice[np.linalg.norm(lattice, axis=1) <= 8.0]
    surface = reconstruct(ball, {"r": np.linalg.norm(ball, axis=1)}, radius=0.5)
    area, volume = area_and_volume(surface)
    sphere_r = (3 * len(ball) / (4 * np.pi)) ** (1 / 3)
    assert volume == pytest.approx(len(ball), rel=0.02)
    assert area == pytest.approx(4 * np.pi * sphere_r**2, rel=0.06)
    assert np.median(surface.vertex_data["r"]) == pytest.approx(7.6, abs=0.6)  # the outer shell's radii


def test_a_2d_scene_gives_a_closed_slab(tmp_path):
    """A 2D block of 20 x 10 particles is extruded three spacings thick: its volume is about 20 x 10 x 3."""
    x, y = np.meshgrid(np.arange(20.0), np.arange(10.0))
    points = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    _, volume = area_and_volume(reconstruct(points, {}, radius=0.5, dim=2))
    assert volume == pytest.approx(20 * 10 * 3, rel=0.05)


def run(folder: Path, *extra: str, frames: int = 8) -> int:
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        argv = ["run", "candle", "--set", "bodies.0.hi=[70.0,8.0]", "--headless", "--quiet", "--frames", str(frames)]
        return main([*argv, *extra])
    finally:
        os.chdir(cwd)


@pytest.mark.long  # `python3 -m pytest -m long`
def test_a_cache_resumes_like_every_output(tmp_path):
    """8 frames with checkpoints, then resumed to 12: the PLY files are byte for byte those of one run of 12."""
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    whole.mkdir(), resumed.mkdir()
    outputs = ["--checkpoint-every", "4", "--checkpoint", "c.npz", "--cache", "c.ply"]
    assert run(whole, *outputs, frames=12) == 0
    assert run(resumed, *outputs, frames=8) == 0
    resume = ["run", "candle", "--resume", "c.npz", "--headless", "--quiet", "--frames", "12", *outputs[:4]]
    cwd = os.getcwd()
    os.chdir(resumed)
    try:
        assert main([*resume, "--cache", "c.ply"]) == 0
    finally:
        os.chdir(cwd)
    names = sorted(p.name for p in whole.glob("c.ply.*.ply"))
    assert names == sorted(f"c.ply.{kind}{k:05d}.ply" for kind in ("", "parts.") for k in range(13))
    assert sorted(p.name for p in resumed.glob("c.ply.*.ply")) == names
    for name in names:
        assert (resumed / name).read_bytes() == (whole / name).read_bytes(), name


@pytest.mark.parametrize(
    "args, says",
    [
        (["--cache", "wax.obj"], "unknown cache kind '.obj'"),
        (["--cache", "/proc/nowhere/wax.usd"], "--cache /proc/nowhere/wax.usd"),
        (["--cache", "s.vtp", "--stats", "s.pvd"], "--cache s.pvd: the same file as --stats"),
        (["--cache-every", "2"], "expected together with --cache"),
    ],
)
def test_bad_cache_options_are_one_line_and_write_nothing(tmp_path, capsys, args, says):
    assert run(tmp_path, *args, frames=2) == EXIT_BAD_INPUT
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error")]
    assert len(err) == 1 and says in err[0], err
    assert not list(tmp_path.iterdir())


def test_a_surface_is_written_in_one_order_whatever_order_it_was_built_in():
    """Identical runs wrote surfaces that differed in bytes (issue 72): splashsurf may emit the same mesh in another
    order. The canonical form of a mesh shuffled (vertices renumbered, triangles reordered and turned) is the
    original's, and it is the same closed surface (area and volume kept)."""
    from sandbox.files.cache_formats import Surface
    from sandbox.render.surface import canonical

    rng = np.random.default_rng(5)
    points = rng.normal(size=(2000, 3))
    points = 6.0 * points / np.linalg.norm(points, axis=1, keepdims=True)
    built = reconstruct(points, {"t": points[:, 0].copy()}, 0.5)
    perm = rng.permutation(len(built.vertices))
    renumber = np.empty_like(perm)
    renumber[perm] = np.arange(len(perm))
    tri = renumber[built.triangles][rng.permutation(len(built.triangles))]
    tri = np.roll(tri, 1, axis=1)  # each triangle turned: the same orientation
    shuffled = Surface(built.vertices[perm], tri, {"t": built.vertex_data["t"][perm]})
    again = canonical(shuffled)
    assert again.vertices.tobytes() == built.vertices.tobytes()
    assert again.triangles.tobytes() == built.triangles.tobytes()
    assert again.vertex_data["t"].tobytes() == built.vertex_data["t"].tobytes()
    assert area_and_volume(again) == pytest.approx(area_and_volume(shuffled))


def moving_body(corner: float):
    """A 2D box of particles from (5, 5) to (corner, corner), no springs, moving at (3, 1) with no force on it
    (dt 0.002, 10 steps a frame)."""
    from tests.conftest import make_scene, scene_dict

    world = {"dim": 2, "lo": [0.0, 0.0], "hi": [40.0, 40.0], "dt": 0.002, "substeps": 10}
    body = {"material": "jelly", "shape": "box", "lo": [5.0, 5.0], "hi": [corner, corner], "springs": False}
    return sandbox.Simulation(make_scene(scene_dict(world=world, bodies=[{**body, "velocity": [3.0, 1.0]}])))


@pytest.mark.parametrize("kind", ["usd", "ply", "vtp"])
def test_a_ballistic_particles_velocity_carries_it_to_its_next_cached_position(tmp_path, kind):
    """Time right (issue 76): USD velocities were per simulated second while the stage plays 24 time codes a second
    and a frame is 0.02 simulated seconds, so motion blur came out 1 / (0.02 x 24) = 2.08 times the motion (here).
    Now position + velocity x (time codes apart / time codes a second) is the next cached position in USD and PLY (a
    frame of the run is a time code, or a Houdini frame, played at the cache's fps), and position + velocity x
    (timesteps apart) in VTK, whose collection's timesteps are simulated seconds: each to 1e-5 relative, for a body
    moving at (3, 1) with no force on it."""
    sim = moving_body(8.0)
    path = tmp_path / f"b.{kind}"
    with sandbox.Cache(path, fps=24.0) as cache:
        for _ in range(3):
            cache.write(sim)
            sim.run(2)
    frames, fps = [0, 2, 4], 24.0
    if kind == "usd":
        from pxr import Usd, UsdGeom

        stage = Usd.Stage.Open(str(path))
        assert stage.GetTimeCodesPerSecond() == fps
        points = UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
        p = [np.asarray(points.GetPointsAttr().Get(f)) for f in frames]
        v = [np.asarray(points.GetVelocitiesAttr().Get(f)) for f in frames]
        seconds = [2 / fps, 2 / fps]
    elif kind == "ply":
        from plyfile import PlyData

        plys = [PlyData.read(str(tmp_path / f"b.ply.{f:05d}.ply")) for f in frames]
        p = [np.stack([ply["vertex"][a] for a in "xyz"], axis=1) for ply in plys]
        v = [np.stack([ply["vertex"][a] for a in ("vx", "vy", "vz")], axis=1) for ply in plys]
        assert "velocity in length per second at 24 frames a second" in " ".join(plys[0].comments)
        seconds = [2 / fps, 2 / fps]
    else:
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

        collection = ET.parse(tmp_path / "b.pvd").getroot().find("Collection")
        sets = [(float(d.get("timestep")), d.get("file")) for d in collection if d.get("part") == "0"]
        p, v = [], []
        for _, name in sets:
            reader = vtkXMLPolyDataReader()
            reader.SetFileName(str(tmp_path / name))
            reader.Update()
            poly = reader.GetOutput()
            p.append(vtk_to_numpy(poly.GetPoints().GetData()))
            v.append(vtk_to_numpy(poly.GetPointData().GetArray("velocity")))
        seconds = [sets[1][0] - sets[0][0], sets[2][0] - sets[1][0]]
    for k in range(2):
        moved = p[k + 1] - p[k]
        assert np.abs(moved[:, 0]).min() > 0.1  # it moved: 0.12 along x in two frames
        np.testing.assert_allclose(p[k] + v[k] * seconds[k], p[k + 1], rtol=1e-5, atol=1e-5 * np.abs(p[k]).max())


def test_caches_carry_the_sandboxs_colours_extents_and_a_plain_triangle_surface(cached):
    """Looks tools read (issue 76, item 2): the sandbox's own colour of each particle (the temperature map over the
    scene's range, as the picture has it) as USD's displayColor, decoded to linear as USD expects, and as PLY's
    red/green/blue bytes in sRGB; USD extents that hold every point; the surface a plain triangle mesh
    (subdivisionScheme none, which renderers otherwise take for Catmull-Clark) with a unit normal at each vertex."""
    from sandbox.files.cache_usd import srgb_to_linear
    from sandbox.render.colormaps import TEMPERATURE_STOPS, ramp_np_many

    kind, path, tables = cached
    frame, _, p, _ = tables[-1]
    lo, hi = sandbox.load("candle", set=SMALL, arch="cpu").scene.render.temperature_range
    expected = np.round(255.0 * ramp_np_many(TEMPERATURE_STOPS, (p["temperature"] - lo) / (hi - lo))).astype(np.uint8)
    assert len(np.unique(expected, axis=0)) > 3  # a candle's wax and flame: several colours
    if kind == "usd":
        from pxr import Usd, UsdGeom

        stage = Usd.Stage.Open(str(path))
        points = UsdGeom.Points(stage.GetPrimAtPath("/World/particles"))
        colors = np.asarray(points.GetDisplayColorPrimvar().Get(frame))
        np.testing.assert_allclose(colors, srgb_to_linear(expected), atol=1e-6)
        xyz = np.asarray(points.GetPointsAttr().Get(frame))
        box = np.asarray(points.GetExtentAttr().Get(frame))
        assert np.all(box[0] <= xyz.min(axis=0)) and np.all(xyz.max(axis=0) <= box[1])
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/surface"))
        assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
        normals = np.asarray(mesh.GetNormalsAttr().Get(frame))
        assert len(normals) == len(mesh.GetPointsAttr().Get(frame))
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
        surface_t = np.asarray(mesh.GetPrim().GetAttribute("primvars:temp_c").Get(frame))
        surface_rgb = np.round(255.0 * ramp_np_many(TEMPERATURE_STOPS, (surface_t - lo) / (hi - lo)))
        colors = np.asarray(mesh.GetDisplayColorPrimvar().Get(frame))
        np.testing.assert_allclose(colors, srgb_to_linear(surface_rgb), atol=2e-3)  # its temperature's colour
    elif kind == "ply":
        from plyfile import PlyData

        v = PlyData.read(str(path.with_name(f"wax.ply.{frame:05d}.ply")))["vertex"]
        got = np.stack([v["red"], v["green"], v["blue"]], axis=1)
        assert got.dtype == np.uint8 and np.array_equal(got, expected)
        s = PlyData.read(str(path.with_name(f"wax.ply.surface.{frame:05d}.ply")))["vertex"]
        surface_rgb = np.round(255.0 * ramp_np_many(TEMPERATURE_STOPS, (s["temp_c"] - lo) / (hi - lo)))
        assert np.abs(np.stack([s["red"], s["green"], s["blue"]], axis=1) - surface_rgb).max() <= 1
    else:
        pytest.skip("VTK caches carry the temperature itself: ParaView colours by it with its own maps")


def test_the_cache_bench_measures_each_format_in_a_process_of_its_own(tmp_path):
    """`sandbox bench --cache`: each format is written in a fresh process (docs/export.md measured USD's memory in the
    process PLY and VTK had grown), and its bytes a frame are the writer's own (a PLY frame: its bytes exactly)."""
    from sandbox.files.cache_formats import ply_bytes
    from sandbox.research.cache_bench import bench_caches, synthetic_frame

    results = bench_caches(2000, 3, tmp_path)
    processes = {kind: r["process"] for kind, r in results["formats"].items()}
    assert len(set(processes.values())) == 3 and os.getpid() not in processes.values()
    rng = np.random.default_rng(1)
    frames = [synthetic_frame(2000, k, rng) for k in range(2)]  # as the bench makes them, written alternately
    written = 0
    for k in range(3):
        frames[k % 2].frame = k
        written += len(ply_bytes(frames[k % 2]))
    assert results["formats"]["ply"]["bytes_per_frame"] == pytest.approx(written / 3, rel=1e-12)
    assert not list((tmp_path).iterdir())  # every format's files removed


@pytest.mark.parametrize("kind", ["usd", "ply", "vtp"])
def test_the_surface_moves_with_the_velocity_it_carries(tmp_path, kind):
    """The surface carries the particles' velocity at its vertices in its format's time (issue 76: velocities on the
    surface): for a body moving at (3, 1) with no force on it, every vertex's velocity is the body's, and the surface's
    mean vertex moves by velocity x the time between cached frames (within 2% of the move: the next frame's surface is
    built anew)."""
    sim = moving_body(11.0)
    path = tmp_path / f"b.{kind}"
    with sandbox.Cache(path, fps=24.0) as cache:
        for _ in range(2):
            cache.write(sim, surface=True)
            sim.run(5)
    seconds = 5 / 24.0 if kind != "vtp" else 5 * 10 * 0.002  # playback seconds (USD, PLY) or simulated (VTK)
    points, velocity = [], []
    for frame in (0, 5):
        if kind == "usd":
            from pxr import Usd, UsdGeom

            stage = Usd.Stage.Open(str(path))
            mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/surface"))
            points.append(np.asarray(mesh.GetPointsAttr().Get(frame)))
            velocity.append(np.asarray(mesh.GetVelocitiesAttr().Get(frame)))
        elif kind == "ply":
            from plyfile import PlyData

            v = PlyData.read(str(tmp_path / f"b.ply.surface.{frame:05d}.ply"))["vertex"]
            points.append(np.stack([v[a] for a in "xyz"], axis=1))
            velocity.append(np.stack([v[a] for a in ("vx", "vy", "vz")], axis=1))
        else:
            from vtkmodules.util.numpy_support import vtk_to_numpy
            from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

            reader = vtkXMLPolyDataReader()
            reader.SetFileName(str(tmp_path / f"b.pvd.surface.{frame:05d}.vtp"))
            reader.Update()
            points.append(vtk_to_numpy(reader.GetOutput().GetPoints().GetData()))
            velocity.append(vtk_to_numpy(reader.GetOutput().GetPointData().GetArray("velocity")))
    moved = points[1].mean(axis=0) - points[0].mean(axis=0)
    for v in velocity:
        np.testing.assert_allclose(v, np.broadcast_to(v[0], v.shape), rtol=1e-5, atol=1e-6)  # one velocity
    np.testing.assert_allclose(velocity[0][0] * seconds, moved, rtol=0.02, atol=0.02 * np.abs(moved).max())
    assert moved[0] > 0.25  # it moved: 0.3 along x in five frames
