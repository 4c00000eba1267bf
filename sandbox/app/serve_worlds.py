"""A classroom host whose tabs are the worlds of one simulation (core/worlds.py): thirty tabs of a scene are thirty
worlds stepped by the same kernels, one launch a pass for all, instead of thirty simulations each launching its
own (a lone melting_block's step is mostly launches: `sandbox bench --worlds 30 melting_block`).

It speaks the pipe protocol of serve_host.py's Host (grow, attach, detach; a tab's messages by slot), so the server
(serve_slots.py) holds it as it holds a host of sessions: a slot is a tab's place, built at once (the simulation and
its kernels are built with the host); attaching takes the next world into use (Simulation.add_world: the scene as
it starts), detaching takes it out (the last world in use moves into its index: its tab's controller follows).

The host steps every world in use together at the scene's pace by the wall clock (pacing.SceneClock; where the
machine is short, pacing.Turns slows all alike), whatever each tab's speed: a tab is sent the newest frame of its
world when it has asked for one (a "ready" credit), so a slow device sees its scene at its pace in fewer pictures.
A paused tab's world is held out of the simulation (world_view.HeldWorld: its sliders, undo, reset and state files
act on the held state; the others step on) and goes back on play; a single step while paused lets it run one frame.

What a tab is sent is a session's (serve_session.py): the scene message, the backdrop, page frames of its world
alone (particle_frame.FramePacker.world), its readouts, settings and charts (each tab keeps its charts' history and its
language; the host's one renderer draws them in turn). Scenes whose particles the page cannot draw (server pictures) or
that cannot run as worlds (the empty canvas, an implicit stepper: assembly.refuse_worlds) are held by hosts of sessions
instead.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import time

from ..world_state import start_world
from .pacing import SceneClock, Turns
from .serve_drawing import page_packer
from .serve_pipe import HOST, SLOT, SlotConn
from .serve_session import SMOOTH_FPS
from .serve_words import chart_words
from .serve_world_tab import WorldTab


def build_batch(scene_name: str, capacity: int):
    """A simulation holding `capacity` worlds of the shipped scene `scene_name`, one of them in use; SandboxError
    where the scene cannot run as worlds (one line naming what it has)."""
    from ..config.resources import shipped_scene
    from ..config.scene import load_scene
    from ..core import runtime
    from ..errors import SandboxError
    from ..simulation import Simulation

    path = shipped_scene(scene_name)
    if path is None:
        raise SandboxError(f"no shipped scene {scene_name!r}")
    scene = load_scene(path)  # an empty scene (its tabs spawn particles) is refused by the assembly, as any scene
    runtime.require("cpu", scene.world.precision)
    sim = Simulation(scene, worlds=max(capacity, 2))
    for k in range(sim.worlds - 1, 0, -1):  # the last world each time: nothing moves
        sim.world(k).remove()
    return sim


class WorldHost:
    """The tabs of one scene as the worlds of one simulation (module docstring); `conn`: the pipe to the server."""

    def __init__(self, conn, scene: str, width: int, height: int, max_fps: float, capacity: int, pinning=None) -> None:
        """`capacity`: the tabs (worlds) it holds at most; `pinning`: serve_host.Pinning, its core in turn."""
        from ..errors import SandboxError
        from ..render.raster import Renderer
        from .tools import Tools

        self.conn, self.scene_name, self.pinning = conn, scene, pinning
        self.sim = sim = build_batch(scene, capacity)
        words_off = dataclasses.replace(sim.scene.render, title=False, clock=False, legend=False)
        self.renderer = Renderer(sim.model, sim.state, width, height, words_off, output="picture")
        sim.state.carry(self.renderer.tails)  # motion-blur tails move with the particles an emitter's world compacts
        self.packer = page_packer(self.renderer, webgl=True)
        if self.packer is None:
            raise SandboxError(f"{scene}: the page cannot draw its particles as the renderer does")
        self.light = getattr(self.packer, "light", None)  # where particles glow, the light frames (each tab's world)
        self.tools = Tools(sim)  # one set of brushes for every tab (each Tools compiles its kernels)
        self.interval = 1.0 / max_fps
        self.tabs: list[WorldTab] = []  # by slot
        self.owners: list[WorldTab | None] = [None]  # by world in use: the tab whose world it is
        self.clock, self.turns = SceneClock(self.interval), Turns(SMOOTH_FPS)
        self.due = time.perf_counter()
        painter = self.renderer.painter
        self.initial_camera = (painter.eye_np.copy(), painter.target_np.copy(), painter.fov) if sim.dim == 3 else None
        self.warm_up()

    def warm_up(self) -> None:
        """Compile what a class's first seconds would (every tab would wait for each kernel): a frame stepped, the
        passes between steps, a tab's page frame, readouts and charts, a world added, reset, held and put back."""
        first, second = WorldTab(self, _Nowhere(), -1), WorldTab(self, _Nowhere(), -1)
        self.attach_tab(first)
        self.sim.step(self.sim.steps_to_every_pass())
        self.frame(None)
        first.readouts()
        first.pause()
        first.play()
        self.attach_tab(second)
        second.control.reset()
        self.frame(None)
        self.detach_tab(second)
        self.detach_tab(first)
        self.clock = SceneClock(self.interval)

    # ------------------------------------------------------------------ the pipe (serve_host.Host's protocol)
    def loop(self) -> None:
        """Messages first, then the worlds' frame when it is due; then wait for the next frame or message."""
        while True:
            while self.conn.poll(0):
                self.receive(self.conn.recv_bytes())
            attached = [tab for tab in self.tabs if tab.attached]
            if attached and self.pinning is not None:
                self.pinning.pin()
            now = time.perf_counter()
            if attached and self.due <= now:
                self.frame(now)
                self.due = max(self.due + self.interval, now - self.interval)
            wait = min(self.due - time.perf_counter(), 1.0) if attached else 1.0
            if wait > 0:
                self.conn.poll(wait)

    def receive(self, data: bytes) -> None:
        (slot,) = SLOT.unpack_from(data)
        message = json.loads(data[SLOT.size :])
        if slot != HOST:
            tab = self.tabs[slot] if slot < len(self.tabs) else None
            if tab is not None and tab.attached:
                self.guarded(tab, lambda: tab.handle(message))
            return
        kind, index = message["t"], message.get("slot", -1)
        if kind == "grow":
            self.grow()
        elif kind == "attach" and 0 <= index < len(self.tabs):
            self.guarded(self.tabs[index], lambda: self.attach_tab(self.tabs[index]))
        elif kind == "detach" and 0 <= index < len(self.tabs):
            self.guarded(self.tabs[index], lambda: self.detach_tab(self.tabs[index]))

    def grow(self) -> None:
        """One more slot (a tab's place: nothing to build), said to the server as built; "failed" beyond the
        simulation's worlds."""
        slot = len(self.tabs)
        if slot >= self.sim.worlds:
            self.tell({"t": "failed", "slot": slot, "text": f"the {self.sim.worlds} worlds of this host are taken"})
            return
        self.tabs.append(WorldTab(self, SlotConn(self.conn, slot), slot))
        self.tell({"t": "built", "slot": slot, "worlds": True})

    def guarded(self, tab: WorldTab, act) -> None:
        """act(); where it raises, the tab ends (the server tells it) and the others run on."""
        try:
            act()
        except (EOFError, BrokenPipeError):
            raise
        except Exception as exc:  # noqa: BLE001 - one tab's failure must not end the others'
            with contextlib.suppress(Exception):
                self.detach_tab(tab)
            self.tell({"t": "ended", "slot": tab.slot, "text": f"{type(exc).__name__}: {exc}"})

    def tell(self, message: dict) -> None:
        self.conn.send_bytes(SLOT.pack(HOST) + b"J" + json.dumps(message).encode())

    # ------------------------------------------------------------------ worlds
    def take_world(self, tab: WorldTab) -> int:
        """A world in use for `tab`: world 0 where it is in use by no tab, else the next one (the scene as it
        starts)."""
        if len(self.owners) == 1 and self.owners[0] is None:
            start_world(self.sim, 0)
            self.owners[0] = tab
            return 0
        k = self.sim.add_world().index
        self.owners.append(tab)
        return k

    def give_back(self, k: int) -> None:
        """World k's tab has left or paused: the world goes out of use (the last one moves into k)."""
        if len(self.owners) == 1:
            self.owners[0] = None  # a simulation keeps one world: it waits for the next tab
            return
        last = len(self.owners) - 1
        self.sim.world(k).remove()
        moved = self.owners.pop()
        if k != last:
            self.owners[k] = moved
            moved.moved_to(k)

    def attach_tab(self, tab: WorldTab) -> None:
        tab.conn.muted = False
        tab.start(self.take_world(tab))

    def detach_tab(self, tab: WorldTab) -> None:
        if tab.world is not None:
            self.give_back(tab.world)
        tab.world, tab.attached, tab.conn.muted = None, False, True

    # ------------------------------------------------------------------ a frame
    def frame(self, now: float | None) -> None:
        """Step every world in use by the steps the scene's clock owes (each tab's held stroke first), then send each
        tab that has asked its world's frame. A blow-up starts every world in use again, each tab told."""
        from ..errors import SimulationError

        running = [tab for tab in self.owners if tab is not None]
        if running:
            substeps = int(self.sim.scene.world.substeps)
            owed, elapsed = self.clock.owes(now, substeps)
            steps = self.turns.limit(owed, substeps)
            for tab in running:  # each tab's stroke (the simulation's steps are this host's); one that fails ends alone
                self.guarded(tab, tab.control.advance)
            running = [tab for tab in self.owners if tab is not None]
            stepping = time.perf_counter()
            try:
                self.renderer.begin_frame()  # the tails of motion-blur streaks: where the particles were before
                blurred = self.sim.scene.render.motion_blur  # (the bend of a curved streak)
                self.sim.advance_frame(steps, self.renderer.mid_frame if blurred else None)
            except SimulationError as exc:
                for tab in running:
                    tab.tell({"t": "error", "text": f"{exc} - the scene starts again"})
                    tab.control.reset()
                return
            self.clock.paid(steps)
            self.turns.record(elapsed, steps, time.perf_counter() - stepping)
        else:
            self.clock.wait()
        wall = time.perf_counter()
        self.packer.pack_every_world()  # one launch for every tab's frame
        try:
            for tab in list(self.tabs):
                if tab.attached:
                    self.guarded(tab, lambda tab=tab: tab.after_frame(wall))
        finally:
            self.packer.batch = None

    def draw_for(self, tab: WorldTab):
        """The host's renderer, set with its packer to `tab`'s world, charts, language and camera (each tab's turn
        in one thread: what it draws next is that tab's)."""
        renderer = self.renderer
        renderer.words = chart_words(tab.lang)
        renderer.chart, renderer.phase_plot = tab.plots
        self.packer.world = tab.world
        if self.light is not None:
            self.light.world = tab.world
        if tab.orbit is not None:
            renderer.set_camera(tab.orbit.eye(), tab.orbit.target, renderer.painter.fov)
        return renderer


class _Nowhere:
    """A pipe end that sends nothing (the warm-up's tabs)."""

    muted = True

    def send_bytes(self, data: bytes) -> None:
        pass
