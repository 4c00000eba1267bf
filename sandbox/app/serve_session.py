"""One browser tab's sandbox: in the classroom, one of the sessions a host process holds (serve_host.py: one Taichi
runtime for many tabs of a scene; a blow-up is caught in its session, which starts its scene again, and a session
that fails ends alone).

The server (serve.py) and the session talk over a multiprocessing pipe in bytes: the server sends JSON commands
(already validated by serve_protocol.py); the session answers b"J" + JSON (readouts, messages) or a picture, which
the server passes to the page as it is:

- where the page draws (`draw="page"`: a 2D scene of discs, render/particle_frame.py, whose glowing particles' light
  the page adds with WebGL2, render/light_frame.py, or a 3D scene of opaque spheres on a page with WebGL2,
  render/sphere_frame.py): b"B" + a PNG of the picture without its particles (the domain, walls, heat sources, floor
  and charts) when a scene opens (in 3D again after the camera moves), b"C" + the charts' band (x0, row0: two u16,
  then a PNG) a few times a second, and b"P" + a particle frame (a few kB; after b"L" + its light frame where
  particles glow) or b"S" + a sphere frame a picture;
- else (motion blur of particles that do not glow, a moving lid, a page without WebGL2 for 3D or light, or
  `draw="server"`): b"F" + the renderer's picture as a JPEG.

The scene keeps its own clock (pacing.SceneClock): a frame of it is stepped every 1 / max_fps seconds whether or not
the page has asked for a picture, and a frame is drawn and sent only when the page has asked (a "ready" credit), so a
slow device or a background tab gets fewer pictures of a scene at its pace, each the newest (it used to step one
frame a picture: a tab asking five times a second ran at a fiftieth of the pace). A frame that comes late (a host's
other tabs had their turns first) takes the steps of the time since the last. Where the core is short of CPU, every
tab on it takes fewer steps a frame alike (pacing.Turns: slow motion at SMOOTH_FPS pictures a second, never a
backlog).
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

from .pacing import SceneClock, Turns
from .serve_drawing import PageDrawing, jpeg, page_packer, picture_point
from .serve_messages import FIRST_CREDITS, PageMessages
from .serve_words import chart_words, page_lesson

MAX_FPS = 30.0  # pictures a second at most (serve --max-fps): more shows a class nothing new, and takes a core
JPEG_QUALITY = 80
READOUTS_EVERY = 6  # pictures between the readouts sent with them (JPEG pictures)
READOUT_SECONDS = 0.3  # seconds between the readouts sent with particle frames
CHART_EVERY = 3  # pictures between the charts' samples (a sample costs a pass over the particles)
WARM_UP_SECONDS = 5.0  # simulated seconds a warm-up runs at most, for its emitters' first spawn and retirement
SMOOTH_FPS = 20.0  # pictures a second a tab keeps, where the machine is short of CPU, by stepping less a picture
# what a session sends a picture: a JPEG, or a frame the page draws (render/particle_frame.PAGE_FRAMES, not imported:
# the server's process never loads Taichi)
FRAMES = (b"F", b"P", b"S")
PICTURES = (*FRAMES, b"B", b"C", b"L")  # and the backdrops and bands a page draws its frames over, and their light
DRAWS = ("page", "server")  # who draws the particles: the page (particle or sphere frames) or the session (JPEG)


class Session(PageMessages):
    """The simulation, its tools and its undo ring, driven by the server's commands (module docstring)."""

    def __init__(
        self,
        conn,
        scene: str,
        width: int,
        height: int,
        max_fps: float = MAX_FPS,
        draw: str = "page",
        shared: bool = False,
        canvas=None,
    ):
        """`shared`: the session lives in a classroom host beside others of its scene (serve_host.py): Taichi is not
        restarted to open it, and it never switches scenes (the server moves its tab to another host instead);
        `canvas`: the host's other sessions' picture canvas, which this one's renderer draws in too."""
        if draw not in DRAWS:
            raise ValueError(f"draw: expected one of {', '.join(DRAWS)}, got {draw!r}")
        self.conn = conn
        self.shared, self.canvas = shared, canvas
        self.draw_by = draw
        self.page: PageDrawing | None = None  # what a page that draws the particles is sent (serve_drawing.py)
        self.packer, self.packer_key = None, None  # ... and what packs its frames, with the renderer it is for
        self.webgl = True  # the page can draw spheres (it says "nogl" where it cannot: then 3D comes as pictures)
        self.interval = 1.0 / max_fps
        self.width, self.height = width, height
        self.credits = FIRST_CREDITS
        self.watched = False  # a page has asked for a picture: from then on the scene runs by its clock (a warm
        # session waiting for its tab draws its first pictures and waits)
        self.control = None  # the Controller: the simulation's tools, run controls, settings and readouts
        self.lang = "en"  # the page's language, which the picture's chart words follow
        self.pointer: tuple[float, float] | None = None  # picture fraction under the pointer (the probe)
        self.frames = 0
        # the steps a picture shows: what the scene's clock owes, fewer where the tabs taking turns on this core would
        # get fewer than SMOOTH_FPS pictures a second (the class sees smooth motion in slow motion rather than jerks)
        self.turns = Turns(SMOOTH_FPS)  # a host's sessions share the host's (serve_host.Host.grow)
        self.clock = SceneClock(self.interval)  # the steps the scene is owed by the wall clock
        self.last_readouts = -1e9  # when the readouts were last sent with a page's frame (wall seconds)
        self.seq = 0  # the last "set" message's sequence number, echoed in the readouts
        self.load(scene)

    # ------------------------------------------------------------------ the scene
    def load(self, scene: str) -> None:
        """Open the shipped scene `scene` as the window's scene picker does (Taichi restarted, so switching scenes
        frees the last one's fields; not in a host, where the runtime is shared), with this session's own renderer
        at its picture size."""
        from ..render.raster import Renderer
        from .controller import Controller

        if self.control is None:
            self.control = Controller.open(scene, restart=not self.shared)
        else:
            self.control.switch(scene)
        self.scene_name = scene
        self.initial_controls = self.sim.controls.values()  # what restart() puts back
        # the page shows the title, clock and legend itself, in its language; the picture keeps the scene's charts
        # (the phase diagram among them: the page draws only the temperature's)
        words_off = dataclasses.replace(self.sim.scene.render, title=False, clock=False, legend=False)
        size = (self.width, self.height)
        self.renderer = Renderer(self.sim.model, self.sim.state, *size, words_off, output="picture", canvas=self.canvas)
        painter = self.renderer.painter
        self.initial_camera = (
            (painter.eye_np.copy(), painter.target_np.copy(), painter.fov) if self.sim.dim == 3 else None
        )
        self.sim.state.carry(self.renderer.tails)
        self.open_view()

    def restart(self) -> None:
        """The scene as it opened, for the next tab of a host's session: its state, live settings, tools, undo
        ring, clock, camera, charts and language as a freshly built session has them (its fields and compiled
        kernels kept: nothing is built again)."""
        self.sim.controls.set(self.initial_controls)
        self.sim.reset()
        self.control.bind(self.sim)
        self.control.paused, self.control.pending_steps = False, 0
        self.credits, self.watched, self.frames, self.seq = FIRST_CREDITS, False, 0, 0
        self.clock = SceneClock(self.interval)  # the scene's clock starts with the tab
        self.pointer, self.lang, self.last_readouts, self.webgl = None, "en", -1e9, True
        if self.initial_camera is not None:
            self.renderer.set_camera(*self.initial_camera)
        self.renderer.set_chart(tuple(self.renderer.cfg.chart), keep_history=False)
        self.open_view()

    def open_view(self) -> None:
        """What the page is told and sent of the scene as it opens: the legend's source, who draws, the camera's
        orbit, the scene message and the backdrop."""
        from ..render.overlays import Overlays
        from .window_parts import OrbitCamera

        scene = self.scene_name
        # the page's legend: what the scene's own settings would draw (the picture draws none)
        self.legend_source = Overlays(
            self.sim.scene.render, self.renderer.overlays.layout, self.sim.state, self.sim.model, scene
        )
        packer = self.page_packer() if self.draw_by == "page" else None
        self.page = PageDrawing(self.conn, self.renderer, packer) if packer is not None else None
        self.set_words()
        painter = self.renderer.painter
        self.orbit = OrbitCamera(painter.eye_np, painter.target_np) if self.sim.dim == 3 else None
        self.tell(
            {
                "t": "scene",
                "scene": scene,
                "lesson": self.lesson(),
                "tools": self.tool_names(),
                "tool": self.first_tool(),
                "materials": list(self.sim.material_names),
                "dim": self.sim.dim,  # 3: a drag turns, zooms or pans the picture's camera
                "draw": "page" if self.page else "server",
            }
        )
        if self.page:  # what does not move with the particles, once
            self.page.send_backdrop(time.perf_counter())

    def page_packer(self):
        """What packs this session's renderer's particles for the page (serve_drawing.page_packer), made once per
        renderer and page kind: a new one compiled its kernels again for every tab a host's session was given."""
        key = (self.renderer, self.webgl)  # the renderer itself (compared by identity), not its id: a freed one's id
        if self.packer_key != key:  # may come again
            self.packer, self.packer_key = page_packer(self.renderer, self.webgl), key
        return self.packer

    def warm_up(self) -> None:
        """Compile, before any tab has this session, the kernels a tab's first seconds would (a host's other tabs
        would wait for each one: a kernel is compiled per session): a frame stepped and sent, the steps to every
        pass between steps, the readouts with and without the pair scan, the chart's sample and the restart (which
        starts the scene's clock afresh)."""
        self.frame()
        self.warm_up_emitters()
        self.sim.step(self.sim.steps_to_every_pass())  # the passes between steps (refreezing) compile at theirs
        self.sim.stats(pair_energy=True)
        self.readouts()
        self.renderer.record(self.sim.stats(pair_energy=False))
        self.restart()

    def warm_up_emitters(self) -> None:
        """Where emitters add particles (and lifetimes retire them), frames until they have done both, at most
        WARM_UP_SECONDS simulated: spawning, retiring and the frames' packing of a scene that starts empty compile at
        their first use, which came in the class (a fireworks host's tabs stalled at the first burst)."""
        terms = self.sim.terms
        if terms.emitters is None:
            return
        last, rose, fell = self.sim.state.live_count(), False, False
        while self.sim.time < WARM_UP_SECONDS:
            self.frame()
            count = self.sim.state.live_count()
            rose, fell, last = rose or count > last, fell or count < last, count
            if rose and (fell or terms.lifetimes is None):
                return

    @property
    def sim(self):
        return self.control.sim

    def lesson(self) -> dict:
        return page_lesson(self.sim.scene.lesson)

    def tool_names(self) -> list[str]:
        """The scene's tools (in 3D they act at the particle under the pointer)."""
        return self.control.tool_names()

    def first_tool(self) -> str:
        """The tool the page starts with: the window's in 2D; none in 3D, where a drag first turns the picture."""
        return self.control.first_tool() if self.sim.dim == 2 and self.tool_names() else "none"

    # ------------------------------------------------------------------ the pipe
    def tick(self, now: float, due: float) -> float:
        """At wall time `now` (s): where a frame is `due`, step it, drawn and sent if the page has asked for a
        picture; returns when the next frame is due. A frame late by more than one interval is not made up (the
        scene slows rather than bursts)."""
        if now < due:
            return due
        if self.credits > 0:
            self.credits -= 1
            self.frame(now)
        elif self.watched:
            self.step(now)
        else:  # a warm session waiting for its tab: its scene's clock waits too
            self.clock.wait()
        return max(due + self.interval, now - self.interval)

    def no_webgl(self) -> None:
        """The page has no WebGL2: 3D scenes and light come as pictures from now on."""
        self.webgl = False
        if self.page is not None and (self.sim.dim == 3 or self.page.light is not None):
            self.page = None
            self.credits = max(self.credits, 1)  # the frame the page could not draw, again as a picture

    def open_scene(self, name: str) -> None:
        """Open another shipped scene (not in a host: the server moves a host's tab to its new scene's host)."""
        if not self.shared:
            self.load(name)

    def scene_time(self) -> float:
        return self.sim.time

    def action(self, name: str) -> None:
        control = self.control
        if name == "pause":
            control.pause()
        elif name == "play":
            control.play()
        elif name == "step":
            control.step_once()
        elif name == "reset":
            control.reset()
        elif name == "undo":
            self.tell({"t": "notice", "key": control.undo().key})
        self.tell({"t": "paused", "paused": control.paused})

    def set_words(self) -> None:
        """The picture's charts in the page's language, their history kept (a page that draws the particles gets
        the charts' band again with the next picture)."""
        self.renderer.words = chart_words(self.lang)
        self.renderer.set_chart(tuple(self.renderer.cfg.chart), keep_history=True)
        if self.page:
            self.page.band_due = True

    def view(self, move: str, dx: float, dy: float) -> None:
        """Turn (orbit), zoom or pan a 3D picture's camera by a drag of (dx, dy) picture fractions, as the window's
        mouse does; nothing in 2D."""
        if self.orbit is None:
            return
        buttons = [move == "orbit", move == "zoom", move == "pan"]
        self.orbit.drag(buttons, dx, dy)
        self.renderer.set_camera(self.orbit.eye(), self.orbit.target, self.renderer.painter.fov)
        if self.page:
            self.page.camera_moved()

    # ------------------------------------------------------------------ tools
    def world_at(self, fx: float, fy: float):
        """The world point under the picture fraction (fx, fy), rows from the top: in 2D the view's point, in 3D the
        nearest particle drawn within a few pixels of it (None where there is none)."""
        return picture_point(self.renderer, fx, fy)

    # ------------------------------------------------------------------ a frame
    def paced(self) -> bool:
        """Whether the scene's clock and the core's turns choose the steps: where they are most of a picture's cost
        (not a JPEG's), and the scene's to choose."""
        return self.page is not None and self.sim.scene.world.substeps != "auto"

    def step(self, now: float | None = None) -> tuple[int, float]:
        """One frame of the scene at wall time `now` (s; None: asked for outside the scene's clock, one frame
        interval's): where paced(), the steps its clock owes as far as this core's turns allow (pacing.SceneClock,
        Turns), else a frame's; (steps taken, seconds they took). A blow-up is said to the page and the scene starts
        again."""
        from ..errors import SimulationError

        paced = self.paced()
        steps = elapsed = None
        if paced:
            substeps = int(self.sim.scene.world.substeps)
            owed, elapsed = self.clock.owes(now, substeps)
            steps = self.turns.limit(owed, substeps)
        stepping = time.perf_counter()
        try:
            self.renderer.begin_frame()  # the tails of motion-blur streaks: where the particles were before
            blurred = self.sim.scene.render.motion_blur  # (the bend of a curved streak halves the frame's launch)
            taken = self.control.advance(steps, self.renderer.mid_frame if blurred else None)
        except SimulationError as exc:
            self.tell({"t": "error", "text": f"{exc} - the scene starts again"})
            self.control.reset()
            return 0, 0.0
        stepped = time.perf_counter() - stepping
        if paced:
            self.clock.paid(steps)
            self.turns.record(elapsed, taken, stepped)
        return taken, stepped

    def frame(self, now: float | None = None) -> None:
        """One frame stepped (at wall time `now`, s: see step()), then drawn and sent (or its particles sent, where
        the page draws them)."""
        wall = time.perf_counter()
        self.step(now)
        self.frames += 1
        if self.page:
            self.send_page_frame(wall)
        else:
            self.send_picture()

    def send_page_frame(self, now: float) -> None:
        """The frame the page draws (it carries the clock), and at their own rates the readouts, the charts' band and
        the backdrop (serve_drawing.py)."""
        sim = self.sim
        self.record_charts()
        if now - self.last_readouts >= READOUT_SECONDS:
            self.last_readouts = now
            self.tell({"t": "info", "time": sim.time, "frame": self.frames, "seq": self.seq, **self.readouts()})
        self.page.send(now, self.frames, self.seq, sim.time)

    def send_picture(self) -> None:
        """The renderer's picture as a JPEG, with the clock (and every few pictures the readouts)."""
        sim = self.sim
        picture = self.draw()
        info = {"t": "info", "time": sim.time, "frame": self.frames, "seq": self.seq}
        if self.frames % READOUTS_EVERY == 1:  # the page shows readouts a few times a second, not every frame
            info.update(self.readouts())
        self.tell(info)
        self.conn.send_bytes(b"F" + jpeg(picture, JPEG_QUALITY))

    def record_charts(self) -> None:
        """A sample of the charts' series every CHART_EVERY pictures."""
        if self.renderer.plots() and self.frames % CHART_EVERY == 0:
            self.renderer.record(self.sim.stats(pair_energy=False))

    def draw(self):
        """This moment's whole picture: the renderer's own buffer, encoded before the next frame (no copy)."""
        self.record_charts()
        if self.page:  # the renderer has not drawn the frames the page drew: every tile again
            self.renderer.full_refresh = True
        return self.renderer.frame()

    def thumbnail(self) -> np.ndarray:
        """The teacher's small picture of this session (240 x 135): from the particle frame where the page draws (a
        few milliseconds), else the renderer's picture made small."""
        from PIL import Image

        small = self.page.thumbnail(240, 135) if self.page else None
        if small is not None:
            return small
        return np.asarray(Image.fromarray(self.draw()).resize((240, 135), Image.Resampling.BILINEAR))

    def stats_now(self):
        """The readouts' measurements now."""
        return self.sim.stats(pair_energy=False)


def scratch_dir() -> Path:
    """The server's own new folder for state files in transit (never a name a client chose; made with a name no
    one else can have picked; removed when the server stops)."""
    return Path(tempfile.mkdtemp(prefix="sandbox-serve-"))
