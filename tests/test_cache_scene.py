"""Whole scenes in caches (issue 76, item 3): the walls, the heat plates and the lid beside the particles, and the
pictures' camera, each read back with an independent reader (usd-core, plyfile, VTK's XML reader); frame 0 and
--cache-from from the command line."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

import sandbox
from sandbox.app.cli import EXIT_BAD_INPUT
from sandbox.files.cache_usd import srgb_to_linear
from sandbox.render.colormaps import TEMPERATURE_STOPS, ramp_np_many
from tests.test_export import run as run_candle

pytestmark = pytest.mark.xdist_group("export")

BARE = {"title": False, "clock": False, "legend": False, "chart": []}  # a picture whose scene fills it


@pytest.fixture(scope="module")
def pot(tmp_path_factory):
    """boiling_pot (2D: a hot plate under the pot) cached at frame 0 in each format; its scene, and the view of a
    picture its scene fills (Flat2D's pixels per length and offset)."""
    folder = tmp_path_factory.mktemp("pot")
    sim = sandbox.load("boiling_pot", arch="cpu")
    for kind in ("usd", "ply", "vtp"):
        with sandbox.Cache(folder / f"pot.{kind}") as cache:
            cache.write(sim)
    sim.picture(**BARE)
    painter = sim._picture_renderer[1].painter
    return folder, sim.scene, (painter.px_per_unit, np.asarray(painter.offset.to_list()))


@pytest.fixture(scope="module")
def cooker(tmp_path_factory):
    """pressure_cooker (3D: a lid over a pool of atoms) cached at frames 0 and 6, with the lid's height then; its
    scene, and the camera of a picture its scene fills (eye, forward, target)."""
    folder = tmp_path_factory.mktemp("cooker")
    sim = sandbox.load("pressure_cooker", arch="cpu")
    heights = {}
    with sandbox.Cache(folder / "cooker.usd") as cache:
        for _ in range(2):
            heights[sim.frames_done] = float(sim.terms.lid.height[None])
            cache.write(sim)
            sim.run(6)
    sim.picture(**BARE)
    painter = sim._picture_renderer[1].painter
    return folder, sim.scene, heights, (painter.eye_np, painter.fwd_np, painter.target_np)


def usd_part(stage, name: str, time: float = 0.0) -> tuple[np.ndarray, np.ndarray, object]:
    """(points (V, 3), triangles (T, 3), the prim) of the part /World/parts/NAME at `time`."""
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/parts/{name}"))
    assert mesh, name
    points = np.asarray(mesh.GetPointsAttr().Get(time), float)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(time))
    assert set(counts) == {3}
    return points, np.asarray(mesh.GetFaceVertexIndicesAttr().Get(time)).reshape(-1, 3), mesh


def outward(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Each triangle's normal dotted with the way from the box's centre to the triangle (> 0: it faces out)."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), (a + b + c) / 3 - centre)


def test_the_walls_are_the_domain_open_at_the_top_and_front(pot):
    """The walls: the domain's box (a 2D scene one spacing deep about z = 0) with its floor, back and sides (4 of
    6 faces: 8 triangles), every face wound to point out of the box, two-sided, in the pictures' wall colour."""
    from pxr import Usd

    folder, scene, _ = pot
    stage = Usd.Stage.Open(str(folder / "pot.usd"))  # kept: a prim is valid while its stage is
    points, triangles, mesh = usd_part(stage, "walls")
    half = 0.5 * scene.spacing
    np.testing.assert_allclose(points.min(axis=0), [*scene.world.lo, -half], atol=1e-6)
    np.testing.assert_allclose(points.max(axis=0), [*scene.world.hi, half], atol=1e-6)
    assert len(triangles) == 8 and np.all(outward(points, triangles) > 0)
    top = points[triangles].reshape(-1, 3)
    assert not np.any(np.all(np.isclose(points[triangles][:, :, 1], scene.world.hi[1]), axis=1))  # no top
    assert top[:, 2].min() == pytest.approx(-half)
    assert mesh.GetDoubleSidedAttr().Get() and mesh.GetSubdivisionSchemeAttr().Get() == "none"


def test_a_hot_plate_is_its_heat_sources_box_in_its_colour_and_temperature(pot):
    """The pot's hot plate (a 600 C source under the floor): its box, closed (6 faces, 12 triangles, facing out),
    its temperature as `temp_c`, and the pictures' colour for 600 C as its displayColor (linear) and its PLY colour
    (sRGB), the same box in the USD, PLY and VTK caches."""
    from plyfile import PlyData
    from pxr import Usd
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    folder, scene, _ = pot
    source = scene.heat.sources[0]
    stage = Usd.Stage.Open(str(folder / "pot.usd"))
    points, triangles, mesh = usd_part(stage, "plate_0")
    half = 0.5 * scene.spacing
    np.testing.assert_allclose(points.min(axis=0), [*source.lo, -half], atol=1e-6)
    np.testing.assert_allclose(points.max(axis=0), [*source.hi, half], atol=1e-6)
    assert len(triangles) == 12 and np.all(outward(points, triangles) > 0)
    assert list(mesh.GetPrim().GetAttribute("primvars:temp_c").Get(0)) == [pytest.approx(source.temperature)]
    lo, hi = scene.render.temperature_range
    srgb = np.round(255 * ramp_np_many(TEMPERATURE_STOPS, np.array([(source.temperature - lo) / (hi - lo)])))
    np.testing.assert_allclose(mesh.GetDisplayColorPrimvar().Get(0)[0], srgb_to_linear(srgb)[0], atol=1e-6)

    ply = PlyData.read(str(folder / "pot.ply.parts.00000.ply"))
    assert "parts 0 walls 1 plate_0" in ply.comments
    v = ply["vertex"].data
    plate = v[v["part"] == 1]
    np.testing.assert_allclose(np.stack([plate["x"], plate["y"], plate["z"]], 1).min(axis=0), points.min(axis=0))
    assert {tuple(c) for c in np.stack([plate["red"], plate["green"], plate["blue"]], 1)} == {tuple(srgb[0])}
    assert np.all(np.isnan(v["temp_c"][v["part"] == 0])) and np.all(plate["temp_c"] == source.temperature)

    collection = ET.parse(folder / "pot.pvd").getroot().find("Collection")
    files = {int(d.get("part")): d.get("file") for d in collection}
    assert files[2] == "pot.pvd.parts.00000.vtp"
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(folder / files[2]))
    reader.Update()
    poly = reader.GetOutput()
    part = vtk_to_numpy(poly.GetPointData().GetArray("part"))
    xyz = vtk_to_numpy(poly.GetPoints().GetData())
    np.testing.assert_allclose(xyz[part == 1].max(axis=0), points.max(axis=0))
    assert poly.GetNumberOfPolys() == 8 + 12


def test_the_lid_moves_with_the_atoms_under_it(cooker):
    """pressure_cooker's lid is a box from its height to the top of the domain at every cached frame: its underside
    at the height the simulation had then (the lid moved between them)."""
    from pxr import Usd

    folder, scene, heights, _ = cooker
    stage = Usd.Stage.Open(str(folder / "cooker.usd"))
    assert len(set(heights.values())) == 2
    for frame, height in heights.items():
        points, triangles, _ = usd_part(stage, "lid", frame)
        assert points[:, 1].min() == pytest.approx(height, abs=1e-5)
        assert points[:, 1].max() == pytest.approx(scene.world.hi[1], abs=1e-5)
        np.testing.assert_allclose(points[:, [0, 2]].min(axis=0), np.asarray(scene.world.lo)[[0, 2]], atol=1e-5)
        assert len(triangles) == 12


def test_a_3d_cache_holds_the_camera_its_pictures_are_taken_with(cooker):
    """/World/camera is the pictures' camera: placed at the renderer's eye, looking along its view, with its
    vertical field of view and the picture's aspect, as USD's own camera maths reads it; the target projects to
    the middle of the frame."""
    from pxr import Gf, Usd, UsdGeom

    folder, scene, _, (eye, forward, target) = cooker
    cfg = scene.render
    stage = Usd.Stage.Open(str(folder / "cooker.usd"))
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/camera")).GetCamera(0)
    frustum = camera.frustum
    np.testing.assert_allclose(np.asarray(frustum.GetPosition()), eye, atol=1e-4)
    np.testing.assert_allclose(np.asarray(frustum.ComputeViewDirection()), forward, atol=1e-6)
    assert camera.GetFieldOfView(Gf.Camera.FOVVertical) == pytest.approx(cfg.fov, abs=1e-4)
    assert camera.aspectRatio == pytest.approx(cfg.width / cfg.height, rel=1e-6)
    assert camera.projection == Gf.Camera.Perspective
    ndc = frustum.ComputeProjectionMatrix().Transform(frustum.ComputeViewMatrix().Transform(Gf.Vec3d(*target)))
    assert abs(ndc[0]) < 1e-6 and abs(ndc[1]) < 1e-6


def test_a_2d_cache_holds_an_orthographic_camera_over_the_pictures_view(pot):
    """A 2D scene's camera looks along -z, orthographic, over the box its pictures show: the frame's height is
    the picture's height in scene lengths and its middle the picture's middle (Flat2D's own view)."""
    from pxr import Gf, Usd, UsdGeom

    folder, scene, (scale, offset) = pot
    cfg = scene.render
    stage = Usd.Stage.Open(str(folder / "pot.usd"))
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/camera")).GetCamera(0)
    assert camera.projection == Gf.Camera.Orthographic
    assert camera.verticalAperture / 10 == pytest.approx(cfg.height / scale, rel=1e-5)
    assert camera.aspectRatio == pytest.approx(cfg.width / cfg.height, rel=1e-6)
    middle = (np.array([cfg.width, cfg.height]) / 2 - offset) / scale
    np.testing.assert_allclose(np.asarray(camera.frustum.GetPosition())[:2], middle, atol=1e-3)
    np.testing.assert_allclose(np.asarray(camera.frustum.ComputeViewDirection()), [0, 0, -1], atol=1e-9)
    ply_camera = next(c for c in _ply_comments(folder / "pot.ply.00000.ply") if c.startswith("camera "))
    words = ply_camera.split()
    assert words[-4] == "ortho_height" and float(words[-3]) == pytest.approx(cfg.height / scale)


def _ply_comments(path) -> list[str]:
    from plyfile import PlyData

    return PlyData.read(str(path)).comments


def run(folder, *extra: str, frames: int) -> int:
    return run_candle(folder, "--no-video", *extra, frames=frames)


@pytest.mark.long  # two command-line runs, each compiling its kernels: `python3 -m pytest -m long`
def test_the_command_line_caches_frame_0_and_from_a_chosen_frame(tmp_path):
    """`--cache-every 3` caches frames 0, 3, 6 (frame 0 the scene as loaded); `--cache-from 4 --cache-every 3`
    frames 4 and 7 of 8; each file holds that frame's time."""
    from plyfile import PlyData

    first = tmp_path / "first"
    first.mkdir()
    assert run(first, "--cache", "w.ply", "--cache-every", "3", frames=7) == 0
    assert sorted(p.name for p in first.glob("w.ply.0*.ply")) == [f"w.ply.{k:05d}.ply" for k in (0, 3, 6)]
    loaded = sandbox.load("candle", set={"bodies.0.hi": [70.0, 8.0]}, arch="cpu")
    v = PlyData.read(str(first / "w.ply.00000.ply"))["vertex"].data
    np.testing.assert_allclose(np.stack([v["x"], v["y"]], 1), loaded.particles()["position"], atol=1e-6)
    later = tmp_path / "later"
    later.mkdir()
    assert run(later, "--cache", "w.usd", "--cache-every", "3", "--cache-from", "4", frames=8) == 0
    assert sorted(p.name for p in later.glob("w.usd.*.usdc")) == ["w.usd.00004.usdc", "w.usd.00007.usdc"]
    from pxr import Usd

    stage = Usd.Stage.Open(str(later / "w.usd"))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (4, 7)
    times = [stage.GetPrimAtPath("/World/particles").GetAttribute("sandbox:time").Get(t) for t in (4, 7)]
    assert times == pytest.approx([4 * 0.02, 7 * 0.02])


@pytest.mark.parametrize(
    "args, says",
    [
        (["--cache", "w.ply", "--cache-from", "9"], "--cache-from 9: the run ends at frame 4"),
        (["--cache-from", "2"], "expected together with --cache"),
        (["--cache", "w.ply", "--cache-from", "-1"], "--cache-from"),
    ],
)
def test_a_cache_from_outside_the_run_is_one_line(tmp_path, capsys, args, says):
    assert run(tmp_path, *args, frames=4) == EXIT_BAD_INPUT
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error")]
    assert len(err) == 1 and says in err[0], err
    assert not list(tmp_path.iterdir())
