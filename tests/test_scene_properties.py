"""Property tests over the scene schema (issue 54): any value of any key, as `--set` gives it, is either a valid
scene or one SceneError line naming the key; hostile numbers in any numeric key build and step to finite values or
are refused by name. The keys come from the schema itself (tests/schema_keys.py), so a new key is covered at once.
SANDBOX_FUZZ=campaign runs thousands of examples."""

from __future__ import annotations

import math
import os
import typing

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sandbox.config.scene import load_scene
from sandbox.config.schema import toml_value
from sandbox.core import runtime
from sandbox.errors import SandboxError, SceneError
from sandbox.simulation import Simulation

from .conftest import SCENES
from .schema_keys import is_numeric, scene_keys

CAMPAIGN = os.environ.get("SANDBOX_FUZZ") == "campaign"
KEYS = scene_keys()
NUMERIC = [(k, h) for k, h in KEYS if is_numeric(h)]
# candle: bodies, emitters, fields, heat, pair; melting_block: heat sources; smoke_vortex: smoke
SCENE_FILES = [SCENES / f"{name}.toml" for name in ("candle", "melting_block", "smoke_vortex")]
EXTREMES = [
    1e308,
    -1e308,
    1e-300,
    -1e-300,
    1e12,
    -1e12,
    1e9,
    -1e9,
    1e-9,
    5e-324,
    0.0,
    -0.0,
    math.inf,
    -math.inf,
    math.nan,
]
BIG_INTS = [2**63 - 1, -(2**63), 2**31, 2**31 - 1, 0, -1, 10**30]

ANY_VALUE = st.one_of(
    st.sampled_from(EXTREMES),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(BIG_INTS),
    st.integers(),
    st.booleans(),
    st.text(max_size=12),
    st.lists(st.one_of(st.sampled_from(EXTREMES), st.floats(-1e3, 1e3), st.integers(-5, 5)), max_size=4),
)


@settings(max_examples=5000 if CAMPAIGN else 300, deadline=None)
@given(scene=st.sampled_from(SCENE_FILES), key=st.sampled_from([k for k, _ in KEYS]), value=ANY_VALUE)
def test_any_value_of_any_key_is_a_scene_or_one_line_naming_the_key(scene, key, value):
    """Nothing but a Scene or a SceneError comes out (no traceback of another kind), and the error is one line that
    names the key or the table it would be in."""
    try:
        load_scene(scene, [f"{key}={toml_value(value)}"])
    except SceneError as exc:
        text = str(exc)
        named = f"'{key.split('.')[0]}" in text or key in text  # the key or its table, or the key a bound names
        assert "\n" not in text and named, text


@settings(
    max_examples=600 if CAMPAIGN else 3,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    scene=st.sampled_from(SCENE_FILES[:2]), item=st.sampled_from(NUMERIC), value=st.sampled_from(EXTREMES + BIG_INTS)
)
def test_hostile_numbers_in_any_key_build_and_step_finite_or_are_refused(scene, item, value):
    """1e308, 1e-300, 2**63-1 ... in dt, skin, spacing, cutoff, spring_radius, heat.radius, lifetimes, seeds and
    every other numeric key: a SandboxError in one line, or a simulation whose first frame is finite."""
    key, hint = item
    text = f"[{', '.join([toml_value(value)] * 2)}]" if typing.get_origin(hint) is tuple else toml_value(value)
    runtime.reset()
    try:
        sim = Simulation(load_scene(scene, [f"{key}={text}"]), arch="cpu")
        sim.run(1)
    except SandboxError as exc:
        assert "\n" not in str(exc)
        return
    assert np.isfinite(sim.particles()["position"]).all()


@pytest.mark.parametrize(
    "override",
    [
        "emitters.0.refill_density=1e9",  # its population was left out of the budget: a 10**10-cell grid, a segfault
        "world.dt=1e308",
        "world.dt=1e-300",
        "world.skin=1e308",
        "pair.cutoff=1e-300",
        "bodies.0.spacing=1e-300",
        "bodies.0.spring_radius=1e308",
        "heat.radius=1e308",
        "emitters.0.lifetime=1e308",
        "bodies.0.seed=9223372036854775807",
    ],
)
def test_the_reported_hostile_values_are_refused_in_one_line(override):
    with pytest.raises(SceneError) as caught:
        load_scene(SCENES / "candle.toml", [override])
    assert "\n" not in str(caught.value) and override.split("=")[0].split(".")[0] in str(caught.value)


def test_a_huge_domain_builds_a_bounded_grid_or_is_refused_when_periodic():
    """A walled box 1e12 wide: its cell grid's size was an int64 product that overflowed past the bound (a
    traceback in Taichi); now it builds and steps. A periodic one keeps every cell, so it is refused by name."""
    runtime.reset()
    sim = Simulation(load_scene(SCENES / "candle.toml", ["world.hi=[1e12, 1e12]"]), arch="cpu")
    sim.run(1)
    assert np.isfinite(sim.particles()["position"]).all()
    with pytest.raises(SceneError, match="world.hi.*a periodic box of about"):
        load_scene(SCENES / "lj_box.toml", ["world.hi=[1e12, 1e12]"])
