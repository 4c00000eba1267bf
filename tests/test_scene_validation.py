"""Scene files are validated data: each mistake gives one error naming the file, the key and the expectation."""

import subprocess
import sys

import pytest

from sandbox.app.cli import main
from sandbox.config.scene import apply_override, load_scene, parse_override
from sandbox.errors import SandboxError, SceneError

GOOD = """
[world]
dim = 2
lo = [0.0, 0.0]
hi = [20.0, 20.0]

[[bodies]]
material = "jelly"
lo = [5.0, 5.0]
hi = [8.0, 8.0]
"""


def test_good_scene_loads_with_defaults(scene_file):
    scene = load_scene(scene_file(GOOD))
    assert scene.dim == 2 and scene.world.dt == 0.002 and scene.world.gravity == (0.0, 0.0)
    assert scene.pair is None and scene.heat is None
    assert scene.bodies[0].lattice == "square" and scene.bodies[0].name == "body0"


@pytest.mark.parametrize(
    "text, key, expectation",
    [
        (GOOD.replace("dim = 2", "dim = 2\ncolour = 3"), "world.colour", "unknown key"),
        (GOOD.replace("dim = 2", 'dim = "two"'), "world.dim", "expected an integer"),
        (GOOD.replace("dim = 2", "dim = 2\ndt = -0.1"), "world.dt", "expected a number > 0"),
        (GOOD.replace("dim = 2", "dim = 2\ndt = 0.0"), "world.dt", "expected a number > 0"),
        (GOOD.replace('material = "jelly"', 'material = "jely"'), "bodies[0].material", "unknown material 'jely'"),
        (
            GOOD.replace('material = "jelly"', 'material = "jelly"\nseed = -1'),
            "bodies[0].seed",
            "expected a number >= 0",
        ),
        (GOOD.replace("hi = [20.0, 20.0]", "hi = [20.0, 20.0, 20.0]"), "world.hi", "expected 2 numbers"),
        (
            GOOD + '\n[materials.heavy]\nbased_on = "jelly"\nparticle_mass = -1.0\n',
            "materials.heavy.particle_mass",
            "expected a number > 0",
        ),
        (
            GOOD + '\n[materials.soft]\nbased_on = "jelly"\nstiffness = -5.0\n',
            "materials.soft.stiffness",
            "expected a number > 0",
        ),
        (GOOD + '\n[materials.soft]\nbased_on = "jelly"\nstiffness = 0.0\n', "materials.soft.stiffness", "> 0"),
        (
            GOOD + '\n[materials.light]\nbased_on = "jelly"\nparticle_mass = 0.0\n',
            "materials.light.particle_mass",
            "> 0",
        ),
        (GOOD + '\n[materials.void]\nbased_on = "jelly"\ndensity = 0.0\n', "materials.void.density", "> 0"),
        (GOOD.replace("dim = 2", 'dim = 2\nsubsteps = "lots"'), "world.substeps", 'from 1 to 100,000 or "auto"'),
        (GOOD.replace("dim = 2", "dim = 2\nsubsteps = 0"), "world.substeps", 'from 1 to 100,000 or "auto"'),
        (GOOD.replace("dim = 2", "dim = 2\nsubsteps = 1000000"), "world.substeps", 'from 1 to 100,000 or "auto"'),
        (GOOD.replace("dim = 2", "dim = 2\ndt = inf"), "world.dt", "expected a finite number, got inf"),
        (GOOD + "\n[heat]\nambient = -300.0\n", "heat.ambient", "expected a temperature >= -273.15"),
        (
            GOOD + "\n[heat]\n[[heat.sources]]\nlo = [0.0, 5.0]\nhi = [10.0, 4.0]\ntemperature = 90.0\n",
            "heat.sources[0].hi",
            "expected every component above heat.sources[0].lo",
        ),
        (GOOD.replace("dim = 2", "dim = 2\ncapacity = 6000000"), "world.capacity", "expected at most 5,000,000"),
        (GOOD + "\n[pair]\na = 1e12\nb = 2e12\n", "pair.a", "expected a number above 0 and at most 64"),
        (GOOD + "\n[heat]\nrefreeze_max_bonds = 1000000000000\n", "heat.refreeze_max_bonds", "from 0 to 64"),
        (GOOD.replace("dim = 2", "dim = 2\nimplicit_max_iterations = 0"), "world.implicit_max_iterations", "from 1"),
        (
            GOOD.replace("hi = [8.0, 8.0]", "hi = [8.0, 8.0]\nspacing = 0.0005"),
            "bodies[0]",
            "about 36,000,001 particles at spacing 0.0005; expected at most world.max_particles",
        ),
        (
            GOOD.replace('material = "jelly"', 'material = "jelly"\nshape = "mask"\nmask = "nope.png"'),
            "bodies[0].mask",
            "not found",
        ),
        (
            GOOD.replace('material = "jelly"', 'material = "jelly"\nshape = "mask"\nmask = "../../etc/passwd"'),
            "bodies[0].mask",
            "outside the scene's folder",
        ),
        (
            GOOD.replace('material = "jelly"', 'material = "jelly"\nshape = "mask"\nmask = "/etc/hostname"'),
            "bodies[0].mask",
            "outside the scene's folder",
        ),
        (
            GOOD.replace("lo = [5.0, 5.0]", "lo = [15.0, 15.0]").replace("hi = [8.0, 8.0]", "hi = [25.0, 25.0]"),
            "bodies[0]",
            "outside the domain",
        ),
        (GOOD + "\n[pair]\na = 4.0\nb = 2.0\n", "pair.b", "expected the repulsion exponent b above"),
        (GOOD.replace("dim = 2", 'dim = 2\nintegrator = "leapfrog"'), "world.integrator", "expected one of"),
        # phase change
        (
            GOOD + '\n[materials.odd]\nbased_on = "wax"\nliquidus_temperature = 10.0\n',
            "materials.odd.liquidus_temperature",
            "expected a temperature >= melt_temperature",
        ),
        (
            GOOD + "\n[heat]\n[[heat.sources]]\nlo = [0.0, 0.0]\nhi = [1.0, 1.0]\n",
            "heat.sources[0].temperature",
            "missing",
        ),
        (
            GOOD + "\n[heat]\n[[heat.sources]]\nlo = [0.0, 0.0]\nhi = [1.0, 1.0]\ntemperature = 9.0\n"
            "schedule_times = [0.0, 1.0]\nschedule_values = [1.0]\n",
            "heat.sources[0].schedule_values",
            "expected as many values as schedule_times",
        ),
        (GOOD + "\n[heat]\nrefreeze_radius = 4.0\n", "heat.refreeze_radius", "at most the neighbour reach"),
        # effects
        (GOOD + '\n[[emitters]]\nmaterial = "jelly"\nshape = "disk"\ncenter = [1.0, 1.0]\n', "emitters[0].size", "> 0"),
        (
            GOOD + '\n[[emitters]]\nmaterial = "jelly"\ncenter = [1.0, 1.0]\nbursts = [1.0]\n',
            "emitters[0].burst_count",
            "expected a count > 0",
        ),
        (
            GOOD + '\n[[emitters]]\nmaterial = "jelly"\nshape = "mask"\nmask = "../x.png"\nlo = [0.0, 0.0]\n'
            "hi = [1.0, 1.0]\n",
            "emitters[0].mask",
            "outside the scene's folder",
        ),
        (GOOD + '\n[[fields]]\nkind = "vortex"\n', "fields[0].center", "missing"),
        (GOOD + '\n[[fields]]\nkind = "tornado"\n', "fields[0].kind", "expected one of"),
        (GOOD + '\n[render]\nchart = ["gas_fractio"]\n', "render.chart", "did you mean 'gas_fraction'?"),
    ],
)
def test_bad_scene_names_file_key_and_expectation(scene_file, text, key, expectation):
    path = scene_file(text)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    message = str(err.value)
    assert message.startswith(str(path)), message
    assert f"'{key}'" in message, message
    assert expectation in message, message


def test_invalid_toml_is_one_error(scene_file):
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(scene_file("[world\n"))


def test_mask_in_scene_folder_is_accepted(scene_file, tmp_path):
    import numpy as np

    from sandbox.render.video import write_png

    img = np.zeros((8, 8, 3), np.uint8)
    img[2:6, 2:6] = 255
    write_png(tmp_path / "square.png", img)
    text = GOOD.replace('material = "jelly"', 'material = "jelly"\nshape = "mask"\nmask = "square.png"')
    scene = load_scene(scene_file(text))
    assert scene.bodies[0].mask.endswith("square.png")


def test_a_huge_mask_is_refused_from_its_header_before_decoding(scene_file, tmp_path):
    """A 20000 x 20000 PNG (a few hundred bytes: its pixels need never be decoded) is refused by its header."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", 20000, 20000, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b"")
    (tmp_path / "big.png").write_bytes(png)
    text = GOOD.replace('material = "jelly"', 'material = "jelly"\nshape = "mask"\nmask = "big.png"')
    with pytest.raises(SceneError, match=r"'big.png' is 20000 x 20000 pixels; expected at most 16,777,216 pixels"):
        load_scene(scene_file(text))


def test_deep_nesting_is_one_error_not_a_recursion(scene_file):
    """Tables or arrays nested thousands deep (in a file or a --set) end in a SceneError, not a RecursionError."""
    with pytest.raises(SceneError, match="nested too deeply"):
        load_scene(scene_file(GOOD + "\n[extra]\nx = " + "[" * 3000 + "]" * 3000 + "\n"))
    with pytest.raises(SceneError, match="nested more than 16 deep"):
        load_scene(scene_file(GOOD + "\n[extra]\nx = " + "[" * 20 + "]" * 20 + "\n"))
    for depth in (20, 3000):
        with pytest.raises(SceneError, match="--set: key 'world.lo': nested"):
            load_scene(scene_file(GOOD), ["world.lo=" + "[" * depth + "]" * depth])


def test_overrides_set_nested_values(scene_file):
    scene = load_scene(scene_file(GOOD), ["world.dt=0.0005", "bodies.0.temperature=35", "render.color_by=speed"])
    assert scene.world.dt == 0.0005 and scene.bodies[0].temperature == 35.0 and scene.render.color_by == "speed"
    assert parse_override("a.b=[1, 2]") == ("a.b", [1, 2])
    with pytest.raises(SceneError, match="not an index"):
        apply_override({"bodies": []}, "bodies.3.x", 1)


def test_cli_bad_scene_prints_one_line_and_exits_nonzero(scene_file, capsys):
    path = scene_file(GOOD.replace("dim = 2", "dim = 2\nwibble = 1"))
    code = main(["check", str(path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("error: ") and "world.wibble" in err[0]


def test_cli_subprocess_exit_code(scene_file):
    path = scene_file(GOOD.replace('material = "jelly"', 'material = "unobtainium"'))
    proc = subprocess.run(
        [sys.executable, "-m", "sandbox", "run", str(path), "--headless", "--frames", "1"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "unknown material 'unobtainium'" in lines[0]
    assert "Traceback" not in proc.stderr


def test_typos_get_the_nearest_valid_name(capsys):
    """A misspelt scene name, --set key or material: one line with the nearest valid name (issue 43)."""
    import sandbox

    cases = [
        (["check", "melting_blok"], "unknown scene 'melting_blok'; did you mean 'melting_block'?"),
        (["check", "candle", "--set", "bodies.0.materal=wax"], "unknown key; did you mean 'material'?"),
        (["check", "candle", "--set", "bodies.0.material=wox"], "unknown material 'wox'; did you mean 'wax'?"),
    ]
    for argv, says in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and says in err[0], err
    with pytest.raises(SandboxError, match="did you mean 'ice_cube'"):
        sandbox.load("ice_cub")
