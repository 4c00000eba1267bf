"""The one controller every front-end drives (app/controller.py): strokes and undo, run controls, live settings,
gravity, state files and readouts, measured on a small simulation without a screen or a browser."""

import json
import math

import numpy as np
import pytest

from sandbox.app import panel
from sandbox.app.controller import Controller
from sandbox.config.scene import load_scene
from sandbox.errors import SandboxError
from sandbox.simulation import Simulation

from .conftest import SCENES


def _block() -> Simulation:
    """A small wax block on the hot plate (springs, heat and gravity)."""
    return Simulation(load_scene(SCENES / "melting_block.toml", ["bodies.0.hi=[50.0, 6.0]", "world.precision=f64"]))


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def test_a_stroke_acts_while_held_paused_or_not_and_undoes_as_one():
    control = Controller(_block())
    sim = control.sim
    before = sim.snapshot()
    centre = sim.positions().mean(axis=0)
    control.pause()
    t0 = sim.time
    for _ in range(3):  # one stroke over three frames: the state before it is kept once
        control.press("heat", centre, 4.0)
        assert control.advance() == 0  # paused: no steps, yet the heat goes in
    control.release()
    assert sim.time == t0 and len(control.history) == 1
    assert sim.stats().mean_temperature > Simulation(sim.scene).stats().mean_temperature + 0.5
    assert control.undo().key == "undone" and _same(sim.snapshot(), before)
    assert control.undo().key == "nothing_to_undo"
    with pytest.raises(SandboxError, match="no material .lava."):
        control.press("spawn", centre, 2.0, material="lava")
    with pytest.raises(SandboxError, match="no teleport tool"):
        control.press("teleport", centre, 2.0)


def test_single_steps_pause_and_play_resumes_the_frames():
    control = Controller(_block())
    sim = control.sim
    control.step_once()
    control.step_once()
    assert control.paused
    assert [control.advance() for _ in range(3)] == [1, 1, 0] and sim.step_count == 2
    control.play()
    substeps = sim.frame_substeps()[0]
    assert control.advance() == substeps and sim.step_count == 2 + substeps
    control.reset()
    assert sim.step_count == 0 and len(control.history) == 0


def test_settings_are_declared_once_clamped_and_refused_by_name():
    control = Controller(_block())
    sim = control.sim
    keys = [s.key for s in control.settings()]
    assert keys == ["air", "source0", "attraction", "repulsion", "gravity", "gravity_angle", "dt_scale"]
    control.set("air", 1e6)  # clamped to the slider's top
    assert sim.terms.heat.sources.ambient[None] == 300.0
    with pytest.raises(ValueError, match="no setting 'wind'"):
        control.set("wind", 1.0)
    g = float(np.linalg.norm(sim.scene.world.gravity))
    control.set("gravity_angle", 90.0)  # turned a quarter: it pulls along +x at the same strength
    assert sim.model.gravity.to_numpy() == pytest.approx([g, 0.0], abs=1e-9)
    control.set("gravity", 2 * g)
    assert sim.model.gravity.to_numpy() == pytest.approx([2 * g, 0.0], abs=1e-9)
    control.steer_gravity(on=False)
    assert not np.any(sim.model.gravity.to_numpy())
    control.steer_gravity(on=True, angle=0.0)
    assert sim.model.gravity.to_numpy() == pytest.approx([0.0, -2 * g], abs=1e-9)
    shown = {s["key"]: s for s in json.loads(json.dumps(panel.as_json(control.settings())))}  # as the page gets it
    assert shown["gravity"]["value"] == pytest.approx(2 * g) and shown["gravity_angle"]["value"] == 0.0
    assert shown["air"] == {"key": "air", "words": "air temperature", "value": 300.0, "lo": -50.0, "hi": 300.0,
                            "unit": "C", "step": 1.0}  # fmt: skip


def test_a_loaded_state_brings_its_gravity_and_the_readouts_follow(tmp_path):
    control = Controller(_block())
    sim = control.sim
    g = float(np.linalg.norm(sim.scene.world.gravity))
    control.set("gravity", 3 * g)
    sim.step(10)
    path = control.save(tmp_path / "s.npz")
    other = Controller(Simulation(sim.scene))
    other.load(path)
    assert other.gravity_strength == pytest.approx(3 * g) and other.sim.step_count == 10
    readouts = {r.key: r for r in other.readouts(other.sim.stats())}
    assert readouts["time"].value == pytest.approx(sim.time) and readouts["particles"].value == sim.particles.n[None]
    summary = other.summary(other.sim.stats())
    assert summary["key"] == "summary_heat" and summary["trend"] == "steady"
    assert math.isfinite(summary["temperature"])


@pytest.mark.parametrize("scene", ["block", pytest.param("pressure_cooker", marks=pytest.mark.long)])
def test_every_sliders_value_survives_save_then_load(tmp_path, scene):
    """A plate set to 50 C came back at 200 C after save and load, and the gravity slider read 0 degrees after a
    state saved at 30 (issue 73): each slider is moved off its value, the state saved, and a fresh controller that
    loads it shows every slider where it was (the pair law's scales and the step's scale among them)."""
    sim = _block() if scene == "block" else Simulation(load_scene(SCENES / "pressure_cooker.toml"))
    control = Controller(sim)
    moved = {}
    for s in control.settings():
        value = s.lo + 0.3 * (s.hi - s.lo) if s.value != s.lo + 0.3 * (s.hi - s.lo) else s.lo + 0.6 * (s.hi - s.lo)
        control.set(s.key, value)
        moved[s.key] = value
    assert len(moved) >= 2
    sim.step(3)
    path = control.save(tmp_path / "s.npz")
    other = Controller(Simulation(sim.scene))
    other.load(path)
    shown = {s.key: s.value for s in other.settings()}
    assert shown == pytest.approx(moved, rel=1e-6, abs=1e-9)  # f32 fields
    if "attraction" in moved:  # the pair law's sliders are the live control pair.scale
        assert other.sim.controls.values()["pair.scale"] == pytest.approx([moved["attraction"], moved["repulsion"]])
    if "dt_scale" in moved:
        assert other.sim.dt == pytest.approx(other.base_dt * moved["dt_scale"])
    other.sim.step(2)  # the schedules do not take a slider's value back
    assert {s.key: s.value for s in other.settings()} == pytest.approx(moved, rel=1e-6, abs=1e-9)  # f32 fields


def test_live_controls_are_namespaced_refused_by_name_and_never_collide():
    from sandbox.core import controls

    sim = _block()
    assert sim.controls.values() == {
        "world.gravity": pytest.approx([0.0, -9.8]),
        "world.drag": 0.0,
        "pair.scale": [1.0, 1.0],
        "heat.ambient": 20.0,
        "heat.sources": [200.0],  # the plate, as its slider reads and a state file keeps it
        "heat.by_hand": [0.0],
    }
    sim.controls.set({"heat.ambient": 35.0, "pair.scale": [2.0, 1.0]})
    assert sim.terms.heat.sources.ambient[None] == 35.0 and sim.terms.pair.scale == (2.0, 1.0)
    before = sim.controls.values()
    for bad, words in (({"ambient": 1.0}, "no live control 'ambient'"), ({"world.gravity": 1.0}, "shaped like")):
        with pytest.raises(SandboxError, match=words):
            sim.controls.set({"heat.ambient": 99.0, **bad})  # checked whole before anything changes
        assert sim.controls.values() == before
    twin = type("Twin", (), {"key": "heat", "controls": lambda self: {}})()
    with pytest.raises(ValueError, match="named 'heat'"):
        controls.gather(sim.model, [*sim.terms, twin])


def test_the_quantities_are_declared_once_and_everything_is_derived_from_them():
    """The CSV columns, the Stats record, the chart series and docs/physics.md's table come from
    config/quantities.py; a name declared twice is refused when the table is built."""
    import dataclasses

    from sandbox.config.quantities import CHART_SERIES, QUANTITIES, Quantity, _checked, markdown_table
    from sandbox.measure.stats import STAT_COLUMNS, Stats

    from .conftest import ROOT

    names = [q.name for q in QUANTITIES]
    assert STAT_COLUMNS == ("frame", *names, "step_seconds")
    assert [f.name for f in dataclasses.fields(Stats)] == names
    assert set(CHART_SERIES) - {"phase_diagram"} <= set(names)
    assert markdown_table() in (ROOT / "docs" / "physics.md").read_text()
    twice = Quantity("pressure", "pressure", "pressure again", "a second declaration", lambda s: 0.0)
    with pytest.raises(ValueError, match="'pressure' is declared twice"):
        _checked((*QUANTITIES, twice))
    stats = _block().stats()
    assert stats.total_energy == pytest.approx(stats.kinetic_energy + stats.potential_energy)
    assert stats.potential_energy == pytest.approx(stats.spring_energy + stats.pair_energy + stats.gravity_energy)


def test_a_tool_added_in_one_place_reaches_every_front_end_and_turns_the_fluid():
    """examples/stir_tool.py registers a tool: the controller offers and applies it (angular momentum about the
    cursor grows), the classroom accepts its name, the window's help lists it."""
    import importlib.util

    from sandbox.app import serve_protocol, tool_table
    from sandbox.app.window_state import help_lines

    from .conftest import ROOT

    spec = importlib.util.spec_from_file_location("stir_tool", ROOT / "examples" / "stir_tool.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    try:
        sim = Simulation(load_scene(SCENES / "lj_box.toml", ["world.precision=f64"]))
        control = Controller(sim)
        assert "stir" in control.tool_names() and "stir" in help_lines()[3]
        message = '{"t": "tool", "tool": "stir", "x": 0.5, "y": 0.5, "radius": 4, "down": true}'
        assert serve_protocol.parse(message, ["lj_box"])["tool"] == "stir"
        x0 = sim.positions()
        centre = (np.asarray(sim.scene.world.lo) + np.asarray(sim.scene.world.hi)) / 2
        r = x0 - centre
        mass = sim.particles.mass.to_numpy()[: len(x0)]

        def spin() -> float:
            v = sim.velocities()
            return float(np.sum(mass * (r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0])))

        before = spin()
        control.pause()
        control.press("stir", centre, 0.4 * float(np.min(np.subtract(sim.scene.world.hi, sim.scene.world.lo))))
        control.advance()
        control.release()
        assert spin() - before > 0  # counter-clockwise
        assert np.array_equal(sim.positions(), x0)  # paused: it changed velocities only
    finally:
        tool_table.unregister("stir")
    assert "stir" not in tool_table.names()


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_the_centre_of_mass_height_falls_as_a_free_body_does():
    """The readout added in one place (config/quantities.py, from the mass-weighted height every simulation sums):
    a springy block falling freely drops by g t^2 / 2 whatever its springs do inside it (velocity Verlet is exact for
    constant acceleration; the internal forces cancel pairwise)."""
    sim = Simulation(
        load_scene(
            SCENES / "melting_block.toml",
            ["bodies.0.hi=[50.0, 6.0]", "bodies.0.lo=[30.0, 40.0]", "bodies.0.hi=[40.0, 46.0]",
             "world.precision=f64", "world.integrator=velocity_verlet", "heat.sources=[]"],
        )
    )  # fmt: skip
    g = float(np.linalg.norm(sim.scene.world.gravity))
    h0 = sim.stats().centre_of_mass_height
    assert h0 == pytest.approx(43.0, abs=0.6)
    sim.step(200)
    t = sim.time
    stats = sim.stats()
    assert stats.centre_of_mass_height == pytest.approx(h0 - 0.5 * g * t * t, abs=1e-9 * h0)
    assert 0.5 * g * t * t > 0.05


def test_terms_run_in_named_stages_and_an_unknown_stage_is_refused():
    """The term protocol: build and hook order come from named stages (physics/term.py's STAGES), in the order the
    plan shows; a term naming a stage that does not exist is refused when it registers."""
    from sandbox.physics.term import STAGES, Term, register

    sim = Simulation(load_scene(SCENES / "candle.toml"))
    built = [STAGES.index(t.stage) for t in sim.terms]
    assert built == sorted(built)
    before = [STAGES.index(getattr(t, "before_stage", t.stage)) for t in sim.plan.before]
    assert len(before) >= 2 and before == sorted(before)
    with pytest.raises(ValueError, match="'breeze': after_stage 'afterwards'"):
        register(type("Breeze", (Term,), {"key": "breeze", "after_stage": "afterwards"}))


def test_a_scene_key_is_one_declaration_checked_against_the_scenes_dimension():
    """docs/architecture.md's "Adding a scene key": a table field declared with spec() is parsed, range-checked,
    refused by name when unknown and, declared with length="dim", checked against world.dim by one walker."""
    import dataclasses

    from sandbox.config.schema import check_lengths, parse_table, spec
    from sandbox.errors import SceneError

    @dataclasses.dataclass(frozen=True)
    class Breeze:  # what a new [breeze] table would declare
        velocity: tuple[float, ...] = spec((), doc="the air's velocity", length="dim")
        gust: float = spec(0.0, doc="gust strength (1/s)")

    table = parse_table(Breeze, {"velocity": [1.0, 0.5]}, "scene.toml", "breeze")
    check_lengths(table, 2, "scene.toml", "breeze")
    with pytest.raises(SceneError, match=r"breeze.velocity.*expected 3 numbers \(world.dim = 3\), got 2"):
        check_lengths(table, 3, "scene.toml", "breeze")
    with pytest.raises(SceneError, match="breeze.gust.*expected 0 or a number of magnitude"):
        parse_table(Breeze, {"gust": 1e300}, "scene.toml", "breeze")
    with pytest.raises(SceneError, match="did you mean 'gust'"):
        parse_table(Breeze, {"gusts": 1.0}, "scene.toml", "breeze")


def test_a_renamed_measure_stops_the_build_naming_it(monkeypatch):
    """Quantities read the terms' measures by name (`s.m.get("pair", 0.0)`): a term renaming its measure made the
    pair energy read 0 for ever, silently (issue 73). Every name a quantity reads is checked against every name a
    term declares when the diagnostics are built."""
    from sandbox.measure import diagnostics
    from sandbox.physics.pair import PairForce
    from sandbox.physics.term import Measure

    assert {"pair", "pair_virial", "ke", "n"} <= diagnostics.declared_measures()
    monkeypatch.setattr(PairForce, "measures", (Measure("pair_energy", "sum", "pairs"), PairForce.measures[1]))
    with pytest.raises(ValueError, match="reads the measure 'pair', which no term declares"):
        _block()
