"""Every shipped scene runs headless; outputs (MP4, GIF, PNG, CSV) are valid files; Ctrl-C leaves valid files."""

import csv

import numpy as np
import pytest
from taichi.lang.field import ScalarField
from taichi.lang.matrix import MatrixField

from sandbox.app.cli import main
from sandbox.app.runner import run_headless
from sandbox.config.scene import load_scene
from sandbox.render.video import read_png
from sandbox.simulation import STAT_COLUMNS, Simulation

from .conftest import SCENES

SHIPPED = sorted(p.stem for p in SCENES.glob("*.toml"))
# the six slowest scenes' ten frames in the long tier (`python3 -m pytest -m long`), every other scene's here
HEAVY = {"candle", "boiling_pot", "states_of_matter", "crystal_3d", "smoke_vortex", "evaporation"}


def test_the_four_core_scenes_ship():
    assert {"melting_block", "melting_block_3d", "lj_box", "spring_lattice"} <= set(SHIPPED)


@pytest.mark.parametrize("name", [pytest.param(s, marks=pytest.mark.long) if s in HEAVY else s for s in SHIPPED])
def test_every_shipped_scene_runs_ten_frames_headless(name, tmp_path, monkeypatch):
    # field[i] from Python compiles a reader or writer kernel for that field (about 20 ms each, at every start):
    # building a scene copies its tables in batches instead
    element_access = []

    def spy(original):
        def access(field, *args):
            element_access.append(field)
            return original(field, *args)

        return access

    for cls in (ScalarField, MatrixField):
        for method in ("__getitem__", "__setitem__"):
            monkeypatch.setattr(cls, method, spy(getattr(cls, method)))
    sim = Simulation(load_scene(SCENES / f"{name}.toml"))
    assert element_access == []
    monkeypatch.undo()
    out = tmp_path / "frames"
    result = run_headless(sim, 10, 2, out, tmp_path / "stats.csv", width=160, height=90, progress=False)
    assert result.frames == 10 and not result.interrupted
    pngs = sorted(out.glob("*.png"))
    assert len(pngs) == 10
    img = read_png(pngs[-1])
    assert img.shape == (90, 160, 3)
    background = np.round(np.array(sim.scene.render.background) * 255)
    assert (np.abs(img.astype(int) - background).sum(axis=2) > 30).sum() > 20  # particles were drawn
    rows = list(csv.DictReader(open(tmp_path / "stats.csv")))
    assert len(rows) == 10 and all(np.isfinite(float(r["total_energy"])) for r in rows)


def test_cli_writes_mp4_and_stats_csv(tmp_path):
    import imageio_ffmpeg

    out, stats = tmp_path / "clip.mp4", tmp_path / "stats.csv"
    code = main(
        [
            "run",
            "melting_block",
            "--headless",
            "--frames",
            "4",
            "--out",
            str(out),
            "--stats",
            str(stats),
            "--width",
            "320",
            "--height",
            "180",
            "--quiet",
            "--arch",
            "cpu",
        ]
    )
    assert code == 0
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == 4
    rows = list(csv.DictReader(open(stats)))
    assert list(rows[0].keys()) == list(STAT_COLUMNS) and len(rows) == 4
    assert [int(r["frame"]) for r in rows] == [0, 1, 2, 3]
    times = [float(r["time"]) for r in rows]
    assert np.allclose(np.diff(times), 0.0025 * 8)
    for r in rows:
        assert float(r["total_energy"]) == pytest.approx(float(r["kinetic_energy"]) + float(r["potential_energy"]))


def test_gif_and_still_outputs(tmp_path):
    import imageio_ffmpeg

    def three_small_frames(out):
        args = ["run", "spring_lattice", "--headless", "--frames", "3", "--out", str(out), "--width", "96"]
        return main(args + ["--height", "54", "--quiet", "--arch", "cpu"])

    gif, still = tmp_path / "clip.gif", tmp_path / "still.png"
    assert three_small_frames(gif) == 0
    assert gif.read_bytes()[:6] == b"GIF89a"
    assert imageio_ffmpeg.count_frames_and_secs(str(gif))[0] == 2  # frames 0 and 2: a GIF plays at most 15 fps
    assert three_small_frames(still) == 0
    assert read_png(still).shape == (54, 96, 3)


def test_interrupt_leaves_a_valid_video(tmp_path):
    import imageio_ffmpeg

    sim = Simulation(load_scene(SCENES / "spring_lattice.toml"))
    out = tmp_path / "cut.mp4"

    def interrupt(frame, stats):
        if frame == 2:
            raise KeyboardInterrupt

    result = run_headless(sim, 50, 2, out, width=96, height=54, progress=False, on_frame=interrupt)
    assert result.interrupted and result.frames == 3
    assert imageio_ffmpeg.count_frames_and_secs(str(out))[0] == 3


def test_check_prints_the_pipeline(capsys):
    assert main(["check", "spring_lattice", "--arch", "cpu"]) == 0
    out = capsys.readouterr().out.split("pipeline per step:")[1]
    assert "spring update" in out and "spring-damper forces" in out
    assert "pair force" not in out and "heat" not in out and "neighbour" not in out
    assert main(["check", "melting_block", "--arch", "cpu"]) == 0
    out = capsys.readouterr().out
    for part in ("neighbour lists", "thermoelastic", "pair force (a=8, b=14", "heat diffusion", "particles 1200"):
        assert part in out
    assert "many steps, in one kernel launch" in out  # 1,200 particles: every loop on one thread
    assert main(["check", "fireworks", "--arch", "cpu"]) == 0
    assert "in one kernel launch" not in capsys.readouterr().out  # emitters act between steps


def test_list_and_keys_describe_everything(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in SHIPPED + ["wax", "jelly", "lj", "steel"]:
        assert f"  {name} " in out
    assert main(["keys"]) == 0
    out = capsys.readouterr().out
    for key in ("dt", "substeps", "integrator", "cutoff", "stepper", "material", "blend", "motion_blur", "stiffness"):
        assert f"  {key} " in out


def test_every_shipped_scene_has_a_lesson_that_list_and_the_window_show(capsys):
    """What happens, what to try and the physics, in each shipped scene's file: `sandbox list` prints all three, and
    the window's panel shows them wrapped to its width, every word kept."""
    from sandbox.app.window_state import LESSON_WIDTH, lesson_text

    for name in SHIPPED:
        lesson = load_scene(SCENES / f"{name}.toml").lesson
        parts = dict(lesson.parts())
        assert list(parts) == ["What happens", "Try", "The physics"], name
        assert all(len(text) > 60 for text in parts.values()), name
        lines = lesson_text(lesson)
        assert all(len(line) <= LESSON_WIDTH for line in lines)
        assert " ".join(lines).split() == " ".join(f"{k}: {v}" for k, v in parts.items()).split()
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for label in ("What happens: ", "Try: ", "The physics: "):
        assert out.count(label) == len(SHIPPED)


def test_a_lesson_of_the_wrong_type_is_one_clear_error(scene_file):
    from sandbox.errors import SceneError

    path = scene_file((SCENES / "spring_lattice.toml").read_text().replace('happens = "', 'happens = 3\nx = "', 1))
    with pytest.raises(SceneError, match="scene.lesson"):
        load_scene(path)


def test_a_default_gif_is_small_enough_to_share(tmp_path):
    """Issue 43: without --width/--height a GIF is 400 pixels wide, at most 15 frames a second, with fewer frames
    where its estimate would pass 8 MB; every shipped scene's default GIF is estimated under 10 MB
    (benchmarks/gif_sizes.py writes them all). A GIF estimated over 50 MB is warned about before the run."""
    from sandbox.config.arguments import GIF_BUDGET, GIF_WARN, gif_plan, gif_warning
    from sandbox.config.resources import shipped_scenes
    from sandbox.config.scene import load_scene
    from sandbox.render.encoder import frame_digests

    for path in shipped_scenes():
        r = load_scene(path).render
        width, height, every, size = gif_plan(r.width, r.height, r.fps, r.frames, sized=False)
        assert width == 400 and r.fps / every <= 15 and size < GIF_BUDGET * 1.25, (path.stem, every, size)
    assert gif_plan(1280, 720, 30.0, 300, sized=True)[:3] == (1280, 720, 2)  # a size asked for is kept
    gif = tmp_path / "small.gif"
    argv = ["run", "lj_box", "--headless", "--quiet", "--frames", "12", "--out", str(gif)]
    assert main(argv) == 0
    assert len(frame_digests(gif)) == 6  # 30 frames a second: every other frame
    width, height, every, size = gif_plan(1920, 1080, 30.0, 2000, sized=True)
    assert size > GIF_WARN and "big.gif will be about 746 MB (1920 x 1080, 15 frames a second)" in gif_warning(
        "big.gif", width, height, 30.0 / every, size
    )
