"""Issue 74: the classroom on worlds. A world host (serve_worlds.py) holds a scene's tabs as the worlds of one
simulation; here one runs in this process over a stand-in pipe. Each tab is its own world: what one tab does
(sliders, a tool, undo, a load, pause) changes nothing in another's, a tab that asks for few pictures keeps its
scene's pace, tabs come and go while the others run on, and every tab is sent frames of its own world alone."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("starlette")

from sandbox.app.serve_pipe import HOST, SLOT  # noqa: E402
from sandbox.render.particle_frame import decode  # noqa: E402

from . import test_serve_hosts  # noqa: E402

pytestmark = [pytest.mark.xdist_group("serve"), pytest.mark.long]  # a host's build: `python3 -m pytest -m long`


class Collect(test_serve_hosts.Collect):
    """The host's pipe end as the host sees it (test_serve_hosts.Collect), read by slot."""

    def said(self, slot: int = HOST) -> list[dict]:
        return [json.loads(b[1:]) for s, b in self.sent if s == slot and b[:1] == b"J"]

    def frames(self, slot: int) -> list[dict]:
        return [decode(b) for s, b in self.sent if s == slot and b[:1] == b"P"]


def order(host, slot: int, message: dict) -> None:
    host.receive(SLOT.pack(slot) + json.dumps(message).encode())


@pytest.fixture
def host():
    """A world host of melting_block holding up to 4 tabs, three slots given out (each test its own: every test
    gets a fresh Taichi runtime, tests/conftest.py)."""
    from sandbox.app.serve_worlds import WorldHost

    host = WorldHost(Collect(), "melting_block", 320, 180, 30.0, 4)
    for _ in range(3):
        order(host, HOST, {"t": "grow"})
    return host


def frames(host, count: int, asking=(0, 1, 2)) -> list[int]:
    """`count` frames of the host, each of the scene's own steps (the wall clock's would follow this machine), the
    tabs in `asking` asking for a picture before each; the steps each frame took."""
    taken = []
    for _ in range(count):
        for slot in asking:
            order(host, slot, {"t": "ready"})
        before = host.sim.step_count
        host.clock.owed = 0.0
        host.turns.allowed = float("inf")
        host.frame(None)
        taken.append(host.sim.step_count - before)
    return taken


def lone_run(steps: list[int], changes=()):
    """The scene alone, stepped as the host stepped (`steps` a frame), `changes`: (frame, function of the lone
    controller) applied before that frame."""
    from sandbox.app.controller import Controller, open_scene

    lone = Controller(open_scene("melting_block", restart=False))
    todo = dict(changes)
    for frame, n in enumerate(steps):
        if frame in todo:
            todo[frame](lone)
        lone.advance(n)
    return lone.sim


def test_a_tabs_world_is_its_own_and_keeps_its_pace_however_few_pictures_it_asks_for(host):
    """Two tabs attached: each is told its scene and sent frames of its world alone (its particle count, its clock);
    one moves the air slider and holds the heat tool, then undoes the stroke; the other tab's world runs on as the
    scene alone, to the bit. A third tab asking for a picture every fourth frame sees its world at the same pace."""
    conn = host.conn
    for slot in (0, 1, 2):
        order(host, HOST, {"t": "attach", "slot": slot})
    assert [host.tabs[s].world for s in (0, 1, 2)] == [0, 1, 2] and host.sim.live_worlds == 3
    assert conn.said(1)[0]["t"] == "scene" and "erase" not in conn.said(1)[0]["tools"]
    steps = frames(host, 3)
    order(host, 0, {"t": "set", "key": "air", "value": 60.0, "seq": 4})
    order(host, 0, {"t": "tool", "tool": "heat", "x": 0.5, "y": 0.8, "radius": 1.0, "down": True})
    steps += frames(host, 2)
    order(host, 0, {"t": "tool", "tool": "heat", "x": 0.5, "y": 0.8, "radius": 1.0, "down": False})
    order(host, 0, {"t": "action", "name": "undo"})
    steps += frames(host, 2, asking=(0, 1))
    for _ in range(2):  # the slow tab asks every fourth frame
        steps += frames(host, 3, asking=(0, 1))
        steps += frames(host, 1, asking=(0, 1, 2))
    assert host.sim.world(0).controls.values()["heat.ambient"] == 60.0
    assert host.sim.world(1).controls.values()["heat.ambient"] == 20.0
    alone = lone_run(steps)
    quiet = host.sim.world(1)
    assert quiet.time == pytest.approx(alone.time, rel=1e-12) and alone.time > 0
    assert np.array_equal(quiet.positions(), alone.positions())
    assert np.array_equal(quiet.temperatures(), alone.temperatures())
    fast, slow = conn.frames(1), conn.frames(2)
    assert len(slow) <= len(fast) - 5  # the slow tab was sent fewer pictures of a world at the same pace
    assert slow[-1]["time"] == fast[-1]["time"] == pytest.approx(alone.time, rel=1e-12)
    assert fast[-1]["n"] == alone.state.live_count()  # its own world's particles, not the simulation's
    heated = [m for m in conn.said(0) if m.get("t") == "notice"]
    assert heated and heated[-1]["key"] == "undone"


def test_a_paused_tab_holds_its_world_while_the_others_run_and_plays_on_from_it(host):
    """Pause takes tab 0's world out of the simulation (the others run on, the simulation steps fewer worlds); a
    slider moved while paused applies when it plays; play puts its world back as it was paused."""
    for slot in (0, 1, 2):
        order(host, HOST, {"t": "attach", "slot": slot})
    tab = host.tabs[0]
    frames(host, 2)
    held = host.sim.world(tab.world)
    at_pause = (held.positions(), held.time)
    order(host, 0, {"t": "action", "name": "pause"})
    assert tab.world is None and host.sim.live_worlds == len([t for t in host.tabs if t.world is not None])
    small = tab.thumbnail()  # the teacher's picture of a paused tab: its last frame's particles over its backdrop
    bare = np.asarray(Image.fromarray(tab.page.under).resize((240, 135), Image.Resampling.BILINEAR))
    assert small.shape == bare.shape == (135, 240, 3) and np.abs(small.astype(int) - bare).max() > 50
    others = {s: host.sim.world(host.tabs[s].world).time for s in (1, 2) if host.tabs[s].world is not None}
    frames(host, 3)
    assert all(host.sim.world(host.tabs[s].world).time > t for s, t in others.items())
    order(host, 0, {"t": "set", "key": "air", "value": 35.0, "seq": 9})
    assert host.conn.said(0)[-1]["t"] != "error"
    order(host, 0, {"t": "action", "name": "play"})
    back = host.sim.world(tab.world)
    assert back.time == at_pause[1] and np.array_equal(back.positions(), at_pause[0])
    assert back.controls.values()["heat.ambient"] == 35.0
    said = [m for m in host.conn.said(0) if m.get("t") == "paused"]
    assert [m["paused"] for m in said[-2:]] == [True, False]


def test_a_tab_that_leaves_gives_its_world_back_and_the_last_world_moves_into_its_place(host):
    """Tab 0 leaves: the last world in use moves into its index and its tab follows it (the same state, clock and
    settings); a tab attached later gets a fresh world, its scene as it starts."""
    for slot in (0, 1, 2):
        order(host, HOST, {"t": "attach", "slot": slot})
    order(host, 2, {"t": "set", "key": "air", "value": 5.0, "seq": 1})
    frames(host, 1)
    last = host.tabs[2]
    k = last.world
    state = (host.sim.world(k).positions(), host.sim.world(k).time)
    leaving = host.tabs[0].world
    mover = next(t for t in host.tabs if t.world == host.sim.live_worlds - 1)
    order(host, HOST, {"t": "detach", "slot": 0})
    assert mover is host.tabs[0] or mover.world == leaving  # the last world took the leaving tab's index
    now = host.sim.world(last.world)
    assert now.time == state[1] and np.array_equal(now.positions(), state[0])
    assert now.controls.values()["heat.ambient"] == 5.0
    order(host, HOST, {"t": "attach", "slot": 0})
    fresh = host.sim.world(host.tabs[0].world)
    assert fresh.time == 0.0 and fresh.controls.values()["heat.ambient"] == 20.0
    assert [m["t"] for m in host.conn.said(0)][-1] == "scene"


def test_a_molecular_scene_runs_as_worlds_each_tab_with_its_own_lid_and_heater():
    """states_of_matter_atoms (3D, velocity Verlet, a lid and a heater) is held as worlds, not sessions: a tab's
    heavier lid (both lifted, then falling) is its world's alone, each tab's sphere frames carry its own world's atoms
    and its own lid's height (the page draws the lid), and the other tab's world is the scene run alone, stepped as
    the host stepped it."""
    from sandbox.app.controller import Controller, open_scene
    from sandbox.app.serve_worlds import WorldHost
    from sandbox.render.sphere_frame import decode as decode_spheres

    pipe = Collect()
    host = WorldHost(pipe, "states_of_matter_atoms", 320, 180, 30.0, 2)
    for slot in (0, 1):
        order(host, HOST, {"t": "grow"})
        order(host, HOST, {"t": "attach", "slot": slot})
    order(host, 1, {"t": "set", "key": "lid", "value": 0.15, "seq": 3})
    sim = host.sim
    sim.terms.lid.height.from_numpy(np.full(2, 20.0, np.float32))  # both lids lifted: they fall on the atoms
    steps = frames(host, 6, asking=(0, 1))
    pressures = [sim.world(k).controls.values()["lid.pressure"] for k in (0, 1)]
    assert pressures[1] == 0.15 and pressures[0] < 0.15
    each = sim.state.particles.world_size
    heights = []
    for slot in (0, 1):
        last = decode_spheres([b for s, b in pipe.sent if s == slot and b[:1] == b"S"][-1])
        world = host.tabs[slot].world
        assert len(last["x"]) == each
        assert last["camera"][20] == 1.0 and last["camera"][21] == pytest.approx(sim.terms.lid.height_of(world))
        heights.append(last["camera"][21])
    assert heights[1] < heights[0] - 2.0  # the heavier lid fell faster
    lone = Controller(open_scene("states_of_matter_atoms", restart=False))
    lone.sim.terms.lid.height[None] = 20.0
    for n in steps:
        lone.advance(n)
    world = sim.world(host.tabs[0].world)
    assert np.array_equal(world.positions(), lone.sim.positions())
    assert np.array_equal(world.velocities(), lone.sim.velocities())


def test_a_scene_with_emitters_runs_as_worlds_each_tab_seeing_its_own_sparks():
    """fireworks (emitters, lifetimes, additive light, motion blur) is held as worlds, not sessions: each tab's
    light frame carries its own world's sparks alone (a tab whose world started again has none until its own first
    burst), and the other tab's world is the scene run alone, stepped as the host stepped it."""
    from sandbox.app.controller import Controller, open_scene
    from sandbox.app.serve_worlds import WorldHost
    from sandbox.render.light_frame import LightFrame, decode_light
    from sandbox.render.raster import Renderer

    pipe = Collect()
    host = WorldHost(pipe, "fireworks", 320, 180, 30.0, 2)
    for slot in (0, 1):
        order(host, HOST, {"t": "grow"})
        order(host, HOST, {"t": "attach", "slot": slot})
    steps = frames(host, 12, asking=(0, 1))  # past the first burst (0.1 s): 700 sparks in each world
    order(host, 1, {"t": "action", "name": "reset"})
    steps += frames(host, 2, asking=(0, 1))
    sim = host.sim
    lights = {slot: [decode_light(b) for s, b in pipe.sent if s == slot and b[:1] == b"L"][-1] for slot in (0, 1)}
    assert sim.state.particles.block(host.tabs[0].world)[1] >= 700 and len(lights[0]["intensity"]) > 600
    assert len(lights[1]["intensity"]) == 0  # tab 1's world started again 2 frames ago: no burst yet on its clock
    lone = Controller(open_scene("fireworks", restart=False))
    look = dataclasses.replace(lone.sim.scene.render, title=False, clock=False, legend=False)  # the host's
    drawn = Renderer(lone.sim.model, lone.sim.state, 320, 180, look, output="picture")
    for count in steps:
        drawn.begin_frame()
        lone.advance(count, drawn.mid_frame)
    world = sim.world(host.tabs[0].world)
    n = lone.sim.state.live_count()
    order_by_id = np.argsort(lone.sim.particles.ident.to_numpy()[:n], kind="stable")
    assert np.array_equal(world.positions(), lone.sim.positions()[order_by_id])
    alone = decode_light(LightFrame(drawn).encode())  # the lone run's light, as a session would send it
    assert np.array_equal(np.sort(lights[0]["intensity"]), np.sort(alone["intensity"]))
