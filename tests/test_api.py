"""The Python API: loading, running into a table, particles by stable id, pictures, save/resume bit for bit,
checkpoints and extended-XYZ export."""

import json

import numpy as np
import pytest

import sandbox
from sandbox.app.cli import main
from sandbox.core import runtime
from sandbox.errors import OutputError, SandboxError
from sandbox.files import persist

SMALL_BLOCK = {"bodies.0.lo": [56.0, 0.0], "bodies.0.hi": [72.0, 12.0]}
FREEZING = {  # a small molten blob on a cold plate: it refreezes within a few frames
    "bodies.0.temperature": 57.0,
    "bodies.0.radius": 5.0,
    "bodies.0.center": [64.0, 5.6],
    "heat.sources.0.schedule_values": [0.0, 140.0],
}
SIDE = 33.54101966  # 30 x 30 sites of the LJ box
SMALL_LJ = {"world.reorder": 1, "world.hi": [SIDE, SIDE], "bodies.0.hi": [SIDE, SIDE]}  # storage sorted every build
CASES = {
    "melting_block": (SMALL_BLOCK, 4, 4),
    "lj_box": (SMALL_LJ, 2, 3),  # storage reordered before and after the save
    "candle": ({"bodies.0.hi": [70.0, 8.0]}, 6, 6),  # a flame emits and retires particles
    "freeze_thaw": (FREEZING, 6, 9),  # springs made by refreezing before and after the save
}


def _everything(sim) -> dict:
    """Every entry of the state, as the state file holds them (the fields in one batched copy, as save() reads them:
    a to_numpy() per field would compile a copy kernel for each)."""
    entries = sim.state.entries()
    out = {f"field:{k}": v for k, v in persist._download([e for e in entries if e.kind == "field"]).items()}
    out.update({f"{e.kind}:{e.name}": e.get() for e in entries if e.kind == "value"})
    out.update({f"{e.kind}:{e.name}": e.get().to_numpy() for e in entries if e.kind == "ndarray"})
    return out


# freeze_thaw (refrozen springs across the save) and candle (emitted and retired particles) in the long tier,
# `python3 -m pytest -m long` (README)
@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=pytest.mark.long) if n in ("freeze_thaw", "candle", "lj_box") else n for n in CASES]
)
def test_a_resumed_run_continues_bit_for_bit(name, tmp_path):
    overrides, before, after = CASES[name]
    sim = sandbox.load(name, set=overrides, arch="cpu")
    sim.run(before)
    path = sim.save(tmp_path / "state")
    assert path.name == "state.npz" and not list(tmp_path.glob(".*partial*"))
    made_before = int(sim.state.springs.created[None]) if name == "freeze_thaw" else 0
    expected_rows = sim.run(after)
    expected, expected_state = sim.particles(), _everything(sim)
    if name == "freeze_thaw":
        assert int(sim.state.springs.created[None]) > made_before > 0  # refreezing went on across the save
    runtime.reset()  # as a new process would: the resumed simulation is built afresh
    resumed = sandbox.resume(path)
    assert resumed.frames_done == before and resumed.scene.source == sim.scene.source
    rows = resumed.run(after)
    got = resumed.particles()
    for key in expected:
        assert np.array_equal(got[key], expected[key], equal_nan=True), key
    for column in rows.columns:
        if column != "step_seconds":
            assert np.array_equal(rows[column], expected_rows[column], equal_nan=True), column
    state = _everything(resumed)
    assert state.keys() == expected_state.keys()
    for key, value in expected_state.items():
        if isinstance(value, np.ndarray):
            assert np.array_equal(state[key], value, equal_nan=True), key
        else:
            assert state[key] == value, key


def test_particle_ids_stay_with_their_particles_while_storage_is_reordered():
    sim = sandbox.load("lj_box", set=SMALL_LJ, arch="cpu")
    first = sim.particles()
    n = len(first["id"])
    assert n == 900 and np.array_equal(first["id"], np.arange(n))
    sim.run(2)
    later = sim.particles()
    stored = sim.particles.ident.to_numpy()[:n]
    assert sim.hood.order.applied > 0 and not np.array_equal(stored, np.arange(n))  # the storage was reordered ...
    assert np.array_equal(later["id"], first["id"])  # ... the table is still by id, and each particle moved little
    step = later["position"] - first["position"]
    step -= SIDE * np.round(step / SIDE)  # (periodic)
    assert np.linalg.norm(step, axis=1).max() < 0.5


def test_emitted_particles_get_new_ids_that_are_never_reused():
    sim = sandbox.load("candle", set={"bodies.0.hi": [70.0, 8.0]}, arch="cpu")
    wax = sim.model.built.count
    seen: set[int] = set()
    retired = False
    for _ in range(8):
        sim.run(3)
        ids = sim.particles()["id"]
        assert len(np.unique(ids)) == len(ids) and ids.max() < sim.particles.next_ident
        assert set(range(wax)) <= set(ids.tolist())  # the candle's own particles keep 0..wax-1
        flame = set(ids[ids >= wax].tolist())
        retired |= bool(seen - flame)
        seen |= flame
    assert retired and sim.particles.next_ident == wax + sum(sim.terms.emitters.emitted)


def test_load_run_and_picture_from_python():
    assert "melting_block" in sandbox.scene_names() and "wax" in sandbox.material_names()
    sim = sandbox.load("melting_block", set=[f"{k}={v}" for k, v in SMALL_BLOCK.items()], arch="cpu")
    assert sim.particles.n[None] == 192
    table = sim.run(3)
    assert len(table) == 3 and list(table["frame"]) == [1, 2, 3]
    assert np.allclose(table["time"], [0.02, 0.04, 0.06]) and table["particles"].dtype == np.int64
    more = sim.run(1)
    assert list(more["frame"]) == [4]  # numbered on from the frames already run
    a = sim.picture(160, 90)
    b = sim.picture(160, 90)
    assert a.shape == (90, 160, 3) and a.dtype == np.uint8 and np.array_equal(a, b)
    assert not np.shares_memory(a, b)  # a new array each call: a list of pictures is an animation
    sim.run(10)
    assert not np.array_equal(sim.picture(160, 90), a)  # it heated: the colours by temperature changed
    by_material = sim.picture(160, 90, color_by="material")  # the scene colours by temperature
    assert not np.array_equal(by_material, sim.picture(160, 90))
    with pytest.raises(SandboxError, match="render.colour': unknown key; did you mean 'color_by'"):
        sim.picture(colour="red")
    bad = [((0, 90), "width 0"), ((100000, 90), "width 100000"), ((-5, 10), "width -5"), ((160.5, 90), "width 160.5")]
    for size, says in bad:  # no silent scene size for 0, no huge allocation, no raw error
        with pytest.raises(SandboxError, match=f"picture\\(\\): {says}.*expected a whole number of pixels"):
            sim.picture(*size)
    with pytest.raises(SandboxError, match="render.color_by': expected one of"):
        sim.picture(160, 90, color_by="rainbow")
    scene = {
        "world": {"dim": 2, "lo": [0.0, 0.0], "hi": [20.0, 20.0], "dt": 0.001},
        "bodies": [{"material": "jelly", "shape": "box", "lo": [5.0, 5.0], "hi": [8.0, 8.0]}],
    }
    jelly = sandbox.load(scene, set={"world.gravity": [0.0, 0.0]}, arch="cpu")
    assert jelly.particles()["position"].shape == (9, 2)  # a 3 x 3 box at the default spacing
    jelly.run(2)
    assert np.allclose(jelly.particles()["velocity"], 0.0)  # no gravity, at rest: nothing moves


def test_a_second_precision_is_refused_while_the_first_is_in_use():
    sim = sandbox.load("melting_block", set=SMALL_BLOCK, arch="cpu")
    with pytest.raises(SandboxError, match="already runs cpu at f32"):
        sandbox.load("melting_block", set={**SMALL_BLOCK, "world.precision": "f64"}, arch="cpu")
    sim.run(1)  # still alive
    runtime.reset()
    with pytest.raises(SandboxError, match="built before Taichi was restarted"):
        sim.run(1)


def test_bad_state_files_give_one_clear_error(tmp_path):
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip")
    with pytest.raises(SandboxError, match="not a readable sandbox state file"):
        sandbox.resume(garbage)
    with pytest.raises(SandboxError, match="no such state file"):
        sandbox.resume(tmp_path / "missing.npz")
    other = tmp_path / "other.npz"
    np.savez(other, meta=np.array(json.dumps({"format": "something else"})))
    with pytest.raises(SandboxError, match="not a sandbox state file"):
        sandbox.resume(other)
    sim = sandbox.load("melting_block", set=SMALL_BLOCK, arch="cpu")
    path = sim.save(tmp_path / "good.npz")
    data = dict(np.load(path))
    meta = json.loads(str(data["meta"]))
    old = tmp_path / "old.npz"
    np.savez(old, **{**data, "meta": np.array(json.dumps({**meta, "sandbox": "0.0.1"}))})
    with pytest.raises(SandboxError, match="state file of sandbox '0.0.1'"):
        sandbox.resume(old)
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(SandboxError, match="not a readable sandbox state file"):
        sandbox.resume(truncated)


def test_a_crash_while_saving_leaves_the_last_checkpoint_whole(tmp_path, monkeypatch):
    sim = sandbox.load("melting_block", set=SMALL_BLOCK, arch="cpu")
    path = sim.save(tmp_path / "ckpt.npz")
    saved = path.read_bytes()
    sim.run(1)

    def crash(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", crash)
    with pytest.raises(OutputError, match="No space left on device"):
        sim.save(path)
    assert path.read_bytes() == saved and sorted(p.name for p in tmp_path.iterdir()) == ["ckpt.npz"]


@pytest.mark.long  # three sandbox processes, each compiling its kernels: `python3 -m pytest -m long`
def test_cli_checkpoints_resume_and_dump(tmp_path):
    sets = [f"--set={k}={v}" for k, v in SMALL_BLOCK.items()]
    base = ["run", "melting_block", "--headless", "--quiet", "--arch", "cpu", "--width", "64", "--height", "36"]
    whole, first, rest = tmp_path / "whole.csv", tmp_path / "first.csv", tmp_path / "rest.csv"
    ckpt, dump = tmp_path / "ckpt.npz", tmp_path / "run.extxyz"
    code = main([*base, *sets, "--frames", "6", "--out", str(tmp_path / "a"), "--stats", str(whole)])
    assert code == 0
    code = main(
        [*base, *sets, "--frames", "3", "--out", str(tmp_path / "b"), "--stats", str(first)]
        + ["--checkpoint-every", "3", "--checkpoint", str(ckpt), "--dump", str(dump), "--dump-every", "2"]
    )
    assert code == 0 and persist.read_meta(ckpt)["frame"] == 3
    assert dump.read_text().count("Lattice=") == 1  # frame 2 (frame 4 is past the run)
    resume = [*base, "--frames", "6", "--resume", str(ckpt), "--out", str(tmp_path / "c"), "--stats", str(rest)]
    assert main(resume) == 2  # other files than the checkpoint's: nothing to continue (tests/test_run_files.py)
    assert main([*resume, "--restart-outputs"]) == 0  # new files, from the checkpoint's frame on
    whole_rows, rest_rows = whole.read_text().splitlines(), rest.read_text().splitlines()

    def measured(row):  # every column but the wall time of the steps
        return row.split(",")[:-1]

    assert [measured(r) for r in rest_rows[1:]] == [measured(r) for r in whole_rows[4:]]
    assert rest_rows[1].startswith("3,")
    assert main([*base, "--frames", "6", "--resume", str(ckpt), "--set", "world.dt=0.1"]) == 2
    assert main(["run", "lj_box", "--frames", "6", "--resume", str(ckpt)]) == 2
    assert main([*base, "--frames", "3", "--resume", str(ckpt)]) == 2  # saved at frame 3 already
    assert main([*base, *sets, "--dump-every", "2"]) == 2  # without --dump


def test_extxyz_frames_read_back_with_ase(tmp_path):
    ase_io = pytest.importorskip("ase.io")
    sim = sandbox.load("melting_block", set=SMALL_BLOCK, arch="cpu")
    path = tmp_path / "melt.extxyz"
    sim.run(2)
    sim.write_extxyz(path, append=False)
    sim.run(2)
    sim.write_extxyz(path, bonds=True)
    frames = ase_io.read(path, index=":")
    assert len(frames) == 2
    atoms, now = frames[1], sim.particles()
    n = len(now["id"])
    assert len(atoms) == n and np.array_equal(atoms.arrays["id"], now["id"])
    assert np.allclose(atoms.positions[:, :2], now["position"], rtol=1e-8, atol=0) and not atoms.positions[:, 2].any()
    assert np.allclose(atoms.arrays["velo"][:, :2], now["velocity"], rtol=1e-8, atol=1e-12)
    assert np.allclose(atoms.arrays["temperature"], now["temperature"], rtol=1e-8)
    assert np.allclose(atoms.arrays["melt_fraction"], now["melt_fraction"], rtol=1e-8, atol=1e-12)
    assert list(atoms.arrays["material"]) == [sim.material_names[m] for m in now["material"]]
    assert np.allclose(atoms.cell.lengths(), [128.0, 72.0, 1.0]) and not atoms.pbc.any()
    assert atoms.info["Time"] == pytest.approx(sim.time) and atoms.info["Step"] == sim.step_count
    bonds = [tuple(map(int, pair.split("-"))) for pair in atoms.info["Bonds"].split()]
    assert len(bonds) == int(sim.state.springs.alive.to_numpy()[: sim.state.springs.span[None]].sum())
    assert "Bonds" not in frames[0].info


def test_a_folder_named_like_a_shipped_scene_does_not_hide_it(tmp_path, monkeypatch):
    import sandbox

    (tmp_path / "lj_box").mkdir()
    monkeypatch.chdir(tmp_path)
    assert sandbox.load("lj_box").scene.name == "lj_box"
