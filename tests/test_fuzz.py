"""Property-based fuzzing: hostile scenes and command lines end in one clean line, or in a short sane run.

Mutations of the shipped scenes (deleted keys, swapped types, zero, negative, NaN, inf, huge and tiny numbers,
reversed boxes) and of the run's command line. The property: a SceneError or one `error:` line with exit 2, or a
short run whose every recorded value is finite (exit 0), or the blow-up guard's stop (exit 3) with only sane rows.

The default profile keeps the suite quick (well under a minute); SANDBOX_FUZZ=campaign runs a long campaign:
    SANDBOX_FUZZ=campaign python3 -m pytest tests/test_fuzz.py
"""

from __future__ import annotations

import copy
import csv
import math
import os
import sys

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from sandbox.app.cli import EXIT_BAD_INPUT, EXIT_STOPPED, main  # noqa: E402
from sandbox.config.budget import body_particles  # noqa: E402
from sandbox.config.build import build_particles  # noqa: E402
from sandbox.config.scene import scene_from_dict  # noqa: E402
from sandbox.core import runtime  # noqa: E402
from sandbox.errors import SandboxError, SceneError  # noqa: E402
from tests.conftest import SCENES  # noqa: E402

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

CAMPAIGN = os.environ.get("SANDBOX_FUZZ") == "campaign"
settings.register_profile("scenes", max_examples=2000 if CAMPAIGN else 250, deadline=None)
# Runs cost seconds each: a campaign reports its first failure as found instead of shrinking it for hours.
NO_SHRINK = [Phase.explicit, Phase.reuse, Phase.generate]
settings.register_profile("runs", max_examples=300 if CAMPAIGN else 12, deadline=None, phases=NO_SHRINK)
QUIET = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.filter_too_much]

RAW = {p.stem: tomllib.loads(p.read_text()) for p in sorted(SCENES.glob("*.toml"))}
HOSTILE = [0, -1, -7.5, 1e-30, -1e-30, 1e30, -1e30, 10**12, math.nan, math.inf, -math.inf, "text", True, [], [1.0], {}]
HOSTILE_TOML = ["0", "-1", "-7.5", "1e-30", "1e30", "-1e30", "1000000000000", "nan", "inf", "-inf", '"text"', "true"]
HOSTILE_TOML += ["[]", "[1.0]", "[1e30, 1e30]", "[nan, 0.0]", "{}"]


def _leaves(node, path=()):
    """Every (path, value) below a TOML table; a path is a tuple of keys and list indices."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(node, list) and node and isinstance(node[0], dict):
        for i, v in enumerate(node):
            yield from _leaves(v, (*path, i))
    else:
        yield path, node


def _tables_with_boxes(node, path=()):
    if isinstance(node, dict):
        if "lo" in node and "hi" in node:
            yield path
        for k, v in node.items():
            yield from _tables_with_boxes(v, (*path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _tables_with_boxes(v, (*path, i))


def _at(data, path):
    for k in path:
        data = data[k]
    return data


@st.composite
def mutated_scene(draw):
    name = draw(st.sampled_from(sorted(RAW)))
    data = copy.deepcopy(RAW[name])
    for _ in range(draw(st.integers(1, 3))):
        leaves = list(_leaves(data))
        boxes = list(_tables_with_boxes(data))
        kind = draw(st.sampled_from(["delete", "replace", "replace", "reverse"] if boxes else ["delete", "replace"]))
        if kind == "reverse":
            table = _at(data, draw(st.sampled_from(boxes)))
            table["lo"], table["hi"] = table["hi"], table["lo"]
            continue
        if not leaves:
            break
        path, _ = draw(st.sampled_from(leaves))
        parent = _at(data, path[:-1])
        if kind == "delete":
            del parent[path[-1]]
        else:
            parent[path[-1]] = draw(st.sampled_from(HOSTILE))
    return name, data


def _one_line(message: str) -> None:
    assert message and "\n" not in message and "Traceback" not in message, message


@settings(settings.get_profile("scenes"), suppress_health_check=QUIET)
@given(mutated_scene())
def test_mutated_scenes_validate_cleanly_and_valid_ones_build_finite_particles(case):
    name, data = case
    try:
        scene = scene_from_dict(data, SCENES / f"{name}.toml")
    except SceneError as exc:
        _one_line(str(exc))
        assert str(exc).startswith(str(SCENES / f"{name}.toml"))
        return
    if sum(body_particles(b, scene.dim) for b in scene.bodies) > 200_000:
        return  # valid and large: building it is the benchmarks' business, not a quick test's
    try:
        built = build_particles(scene)
    except SandboxError as exc:
        _one_line(str(exc))
        return
    for array in (built.x, built.v, built.mass, built.temperature, built.rest_length, built.stiffness):
        assert np.all(np.isfinite(array))


RUN_OPTIONS = {
    "--frames": ["0", "-1", "1", "2", "1000001", "x"],
    "--substeps": ["0", "-3", "1", "3", "100001"],
    "--width": ["0", "-5", "15", "33", "64", "100000"],
    "--height": ["0", "48", "9000"],
    "--fps": ["0", "nan", "inf", "-1", "24", "1e9"],
    "--still-frame": ["-1", "0", "1", "5"],
}
RUN_SCENES = sorted(RAW) if CAMPAIGN else ["spring_lattice", "ice_cube"]  # a campaign mutates every shipped scene
SCENE_KEYS = {name: [".".join(map(str, p)) for p, _ in _leaves(RAW[name])] for name in RUN_SCENES}


@st.composite
def hostile_run(draw):
    name = draw(st.sampled_from(sorted(SCENE_KEYS)))
    args = []
    for option in draw(st.lists(st.sampled_from(sorted(RUN_OPTIONS)), max_size=2, unique=True)):
        args += [option, draw(st.sampled_from(RUN_OPTIONS[option]))]
    for _ in range(draw(st.integers(0, 2))):
        key = draw(st.sampled_from(SCENE_KEYS[name]))
        args += ["--set", f"{key}={draw(st.sampled_from(HOSTILE_TOML))}"]
    return name, args


@settings(settings.get_profile("runs"), suppress_health_check=QUIET)
@given(hostile_run())
def test_hostile_command_lines_end_in_one_line_or_a_sane_short_run(tmp_path_factory, capsys, case):
    name, args = case
    runtime.reset()  # each run builds fields of its own: a runtime holds a few hundred field trees at most
    folder = tmp_path_factory.mktemp("run")
    out, stats = folder / "still.png", folder / "stats.csv"
    size = [] if {"--width", "--height"} & set(args) else ["--width", "32", "--height", "32"]
    frames = [] if "--frames" in args else ["--frames", "2"]
    argv = ["run", name, "--headless", "--quiet", *frames, *size, *args, "--out", str(out), "--stats", str(stats)]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse: a value of the wrong type (usage and one error line)
        assert exc.code == EXIT_BAD_INPUT
        assert "error: argument" in capsys.readouterr().err
        return
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if code == EXIT_BAD_INPUT:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), lines
        assert not stats.exists() and not out.exists()
        return
    assert code in (0, EXIT_STOPPED), err
    if code == EXIT_STOPPED:
        assert "error: the blow-up guard stopped the run" in err
    with open(stats) as f:
        rows = list(csv.DictReader(f))
    assert code == EXIT_STOPPED or rows  # a finished run recorded its frames
    for row in rows:
        assert all(math.isfinite(float(v)) for v in row.values() if v != ""), row
