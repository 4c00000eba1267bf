"""One tab of a classroom world host (serve_worlds.py): its world of the host's simulation, its controller (tools,
undo, sliders and state files of its world alone), its charts and language, its credits of pictures, and what the
page is sent, as serve_session.Session sends it: the scene message, the backdrop, page frames of its world, its
readouts and settings. A paused tab's world is held out of the simulation (world_view.HeldWorld) until play."""

from __future__ import annotations

import struct
import time

from .serve_drawing import PageDrawing, picture_point
from .serve_messages import FIRST_CREDITS, PageMessages
from .serve_session import CHART_EVERY, READOUT_SECONDS
from .serve_words import chart_words, page_lesson

SEQ_AT = struct.calcsize("<cI")  # where a page frame's header (particle_frame.HEADER: kind, frame, seq ...) holds seq


class WorldTab(PageMessages):
    """One tab's world of a WorldHost: its controller (tools, undo, sliders, state files of its world), charts,
    credits and clock of pictures, and what the page is sent (serve_session.Session's messages)."""

    def __init__(self, host, conn, slot: int) -> None:
        """`host`: the serve_worlds.WorldHost whose simulation holds its world; `conn`: its slot's pipe end."""
        self.host, self.conn, self.slot = host, conn, slot
        self.attached, self.world, self.held, self.step_held = False, None, None, False
        self.control = None
        self.orbit = None

    sim = property(lambda self: self.host.sim)

    def start(self, world: int) -> None:
        """The tab's scene as it opens, in world `world` (taken into use for it)."""
        from ..render.overlays import Overlays
        from .controller import Controller
        from .window_parts import OrbitCamera

        host, renderer = self.host, self.host.renderer
        self.attached, self.world, self.held, self.step_held = True, world, None, False
        self.control = Controller(self.sim, world, tools=host.tools)
        self.credits, self.watched, self.frames, self.seq = FIRST_CREDITS, False, 0, 0
        self.pointer, self.lang, self.last_readouts, self.last_frame = None, "en", -1e9, b""
        renderer.words = chart_words(self.lang)
        renderer.set_chart(tuple(renderer.cfg.chart), keep_history=False)
        self.plots = (renderer.chart, renderer.phase_plot)
        self.orbit = None
        if host.initial_camera is not None:
            eye, target, _ = host.initial_camera
            self.orbit = OrbitCamera(eye, target)
        scene, sim = self.sim.scene, self.sim
        self.legend_source = Overlays(scene.render, renderer.overlays.layout, sim.state, sim.model, host.scene_name)
        self.page = PageDrawing(self.conn, renderer, host.packer)
        self.tell(
            {
                "t": "scene",
                "scene": host.scene_name,
                "lesson": page_lesson(scene.lesson),
                "tools": self.control.tool_names(),
                "tool": self.control.first_tool() if self.sim.dim == 2 else "none",
                "materials": list(self.sim.material_names),
                "dim": self.sim.dim,
                "draw": "page",
            }
        )
        host.draw_for(self)
        self.page.send_backdrop(time.perf_counter())

    def moved_to(self, world: int) -> None:
        """Another tab's world left: this one's moved into index `world`."""
        self.world = world
        self.control.move_to(world)

    @property
    def time(self) -> float:
        """The tab's scene's clock: its world's, or the held world's while paused."""
        return self.held.time if self.held is not None else self.sim.world(self.world).time

    # ------------------------------------------------------------------ pictures
    def after_frame(self, now: float) -> None:
        """The host has stepped its worlds: the tab's frame, if it has asked for one (a credit)."""
        if self.step_held:  # a single step while paused: the world ran this frame, and is held again
            self.step_held = False
            self.pause()
        if self.credits <= 0:
            return
        self.credits -= 1
        self.frames += 1
        if self.held is not None and self.last_frame:  # held: its last frame again, with the newest setting's number
            frame = bytearray(self.last_frame)
            struct.pack_into("<I", frame, SEQ_AT, self.seq & 0xFFFFFFFF)
            if now - self.last_readouts >= READOUT_SECONDS:
                self.last_readouts = now
                self.tell({"t": "info", "time": self.time, "frame": self.frames, "seq": self.seq, **self.settings()})
            self.conn.send_bytes(bytes(frame))
            return
        renderer = self.host.draw_for(self)
        if renderer.plots() and self.frames % CHART_EVERY == 0:
            renderer.record(self.stats_now())
        if now - self.last_readouts >= READOUT_SECONDS:
            self.last_readouts = now
            self.tell({"t": "info", "time": self.time, "frame": self.frames, "seq": self.seq, **self.readouts()})
        self.last_frame = self.page.send(now, self.frames, self.seq, self.time)

    def settings(self) -> dict:
        from . import panel

        return {"settings": panel.as_json(self.control.settings())}

    def stats_now(self):
        """The readouts' measurements now."""
        return self.sim.stats(pair_energy=False, world=self.world)

    def world_at(self, fx: float, fy: float):
        """The scene point under the picture fraction (fx, fy) (serve_drawing.picture_point, its 3D camera the
        tab's); None while the world is held (paused: out of the simulation, so no tool acts on it)."""
        if self.held is not None:
            return None
        return picture_point(self.host.draw_for(self), fx, fy)

    # ------------------------------------------------------------------ the page's messages (serve_messages.py)
    def no_webgl(self) -> None:
        if self.sim.dim == 3:  # a world is drawn by the page alone
            self.tell({"t": "error", "key": "nogl", "text": "this 3D scene needs a browser with WebGL2"})

    def set_words(self) -> None:
        """The charts' words in the tab's language, their history kept."""
        renderer = self.host.draw_for(self)
        renderer.set_chart(tuple(renderer.cfg.chart), keep_history=True)
        self.plots = (renderer.chart, renderer.phase_plot)
        self.page.band_due = True

    def open_scene(self, name: str) -> None:
        """Nothing: the server moves a tab that asks for another scene to that scene's host."""

    def scene_time(self) -> float:
        return self.time

    def action(self, name: str) -> None:
        if name == "pause":
            self.pause()
        elif name == "play":
            self.play()
        elif name == "step" and self.held is not None:
            self.play()
            self.step_held = True
        elif name == "reset":
            self.control.reset()
        elif name == "undo":
            self.tell({"t": "notice", "key": self.control.undo().key})
        self.tell({"t": "paused", "paused": self.held is not None})

    def pause(self) -> None:
        """Hold the tab's world out of the simulation (module docstring); the others step on."""
        from ..world_view import HeldWorld

        if self.held is not None:
            return
        self.held = HeldWorld.take(self.sim, self.world)
        self.host.give_back(self.world)
        self.world = None
        self.control.hold(self.held)

    def play(self) -> None:
        """Put the held world back into use, as it was held."""
        if self.held is None:
            return
        k = self.host.take_world(self)
        self.held.put(k)
        self.world, self.held = k, None
        self.control.move_to(k)

    def view(self, move: str, dx: float, dy: float) -> None:
        """Turn, zoom or pan the tab's own 3D camera (nothing in 2D)."""
        if self.orbit is None:
            return
        self.orbit.drag([move == "orbit", move == "zoom", move == "pan"], dx, dy)
        self.page.camera_moved()

    def thumbnail(self):
        """The teacher's small picture of this tab's world (240 x 135): from its page frame in 2D, else the picture
        under its particles made small."""
        import numpy as np
        from PIL import Image

        from ..render.particle_frame import frame_records, small_picture

        if self.world is not None and self.page.under is not None and self.sim.dim == 2:
            self.host.draw_for(self)
            return self.page.thumbnail(240, 135)
        if self.held is not None and self.last_frame[:1] == b"P" and self.page.under is not None:  # its last frame
            return small_picture(self.page.under, frame_records(self.last_frame), 240, 135)
        base = self.page.under if self.page.under is not None else np.zeros((135, 240, 3), np.uint8)
        return np.asarray(Image.fromarray(base).resize((240, 135), Image.Resampling.BILINEAR))
