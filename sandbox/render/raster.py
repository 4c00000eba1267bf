"""The particle renderer: Taichi kernels draw particles into a float RGB image field, then pack it to 8-bit.

Every body (particle group) has a drawing style: `draw` (dot: one pixel; splat: a disc of the particle's radius;
sphere: a shaded sphere in 3D) and `blend` (opaque; alpha: translucent; additive: emits light, absorbs none).

Coverage. A particle is a segment from where it was a shutter ago to where it is (a point when still, or without
motion blur); a pixel's coverage is clamp(R + 0.5 - d, 0, 1) for its distance d to the segment, R the radius in
pixels. Particles smaller than R_MIN pixels are drawn at R_MIN with their opacity scaled by (R / R_MIN)^2 but
never below MIN_FADE, so small or distant particles fade rather than flicker or vanish. Additive particles
deposit an energy of opacity * pi R^2 (in pixel units), spread over their footprint by normalised weights: a
sub-pixel spark deposits its full intensity wherever it falls, and a streak deposits the same energy as the still
particle, brighter towards its head.

Compositing. 2D: opaque particles blend by coverage-weighted averaging (order-independent); alpha particles by
weighted averaging of colour with total alpha 1 - prod(1 - a_k) (exact product, accumulated as a sum of logs);
additive light is tone mapped, 1 - exp(-exposure L) per channel, so dense regions saturate gracefully. 3D: opaque
spheres with a depth buffer (integer atomic min of the depth bits) and ambient + diffuse + specular shading;
translucent particles are sorted back to front on the host and composited "over" in that order by a serial
kernel, with the depth test; additive light is depth-tested against the opaque spheres. With motion blur, additive
particles become streaks of light, and opaque spheres stay solid where they are and leave a translucent streak back
to where they were, depth-tested along its length and composited like 2D's translucent particles (translucent 3D
particles are drawn unblurred).
The image field is W x H with y up (Taichi's and GGUI's convention); `frame()` returns H x W x 3 uint8, top row
first. On the CPU backend the kernels write that 8-bit picture straight into a numpy array (no copy); on a GPU it
is a device array copied to the host once per picture.

Outputs (Renderer's `output`): "image" keeps the float image (tests read it; a window on a GPU shows it);
"picture" writes only the 8-bit H x W x 3 picture (headless video); "rgba" (CPU only) writes GGUI's own packed
format, a W x H uint32 array of RGBA bytes with y up, which the window hands to GGUI as it is. GGUI's
canvas.set_image of a float image runs a conversion kernel over every pixel (4.4 ms a 1280 x 720 frame on the
2-core machine) before its copy to the screen (3.0 ms); "rgba" writes only the dirty tiles, 4 bytes a pixel.

Cost. In 2D every drawing kernel stamps the 16 x 16 pixel tiles it touches, and the compositing pass visits only
the tiles drawn in this frame or the previous one (plus the chart and legend rectangles); the rest of the picture
is unchanged from the frame before. A 1,200-particle block in a 1280 x 720 frame touches a few per cent of it.
"""

import math

import numpy as np
import taichi as ti

from ..core import runtime, transfer
from ..core.oriented import data_oriented
from .chart import Chart, CurvePlot
from .flat import Flat2D
from .look import ParticleLook
from .output import Output
from .pixels import get_pixel, put_pixel
from .spheres import Spheres3D
from .strips import StripBins
from .style import BLEND, BRUSH_COLOR, BRUSH_OPACITY, COLOR_MODES, DRAW, MAX_OVERLAYS, OUTPUTS, ROW_MAJOR, TILE


@data_oriented
class Renderer(ParticleLook, Flat2D, Spheres3D, Output):
    """Draws the particles of a State (with its Model) into `self.image` (W x H RGB floats)."""

    def __init__(
        self,
        model,
        state,
        width: int,
        height: int,
        render_cfg,
        output: str = "image",
        strip_splat: bool = True,
        panel: float = 0.0,
    ) -> None:
        """output: what render() leaves (see OUTPUTS in the module docstring); "image" packs the 8-bit picture from
        the float image only when picture() asks, "picture" and "rgba" have 2D compositing write it directly.
        strip_splat=False draws every 2D particle with atomic adds (the reference the strip binning is tested
        against). panel: the fraction of the width on the left that a side panel covers (the window's); the scene
        and the chart are drawn right of it."""
        if output not in OUTPUTS:
            raise ValueError(f"unknown renderer output '{output}'; expected one of {', '.join(OUTPUTS)}")
        self.on_cpu = runtime.running_arch() == "cpu"
        if output == "rgba" and not self.on_cpu:
            raise ValueError("the packed 'rgba' output is a host array: CPU backend only")
        self.model, self.state, self.p = model, state, state.particles
        self.strip_splat = strip_splat
        self.output = output
        self.keep_image = output == "image"
        self.cfg = render_cfg
        self.width, self.height = width, height
        self.panel_px = int(round(panel * width))  # pixels on the left under a side panel
        self.cx = self.panel_px + 0.5 * (width - self.panel_px)  # 3D: where the view's axis meets the picture
        self.dim = model.dim
        # The tables go to their fields in one copy kernel when the block ends: a host write of a field element
        # compiles a writer kernel of its own (about 20 ms each at start-up). Nothing in the block reads them.
        with transfer.batched():
            bodies = model.scene.groups  # every body, then every emitter, then (last) the spawn tool's particles
            self.n_groups = len(bodies) + 1
            self.g_draw = ti.field(ti.i32, shape=self.n_groups)
            self.g_blend = ti.field(ti.i32, shape=self.n_groups)
            self.g_opacity = ti.field(ti.f32, shape=self.n_groups)
            self.g_fade = ti.field(ti.i32, shape=self.n_groups)  # colour fades over the lifetime
            self.g_shrink = ti.field(ti.i32, shape=self.n_groups)  # drawn radius shrinks over the lifetime
            self.has_lifetimes = state.particles.lifetimes
            draw = [DRAW[b.draw] for b in bodies] + [DRAW["splat" if self.dim == 2 else "sphere"]]  # + the spawn tool's
            transfer.upload(
                [
                    (self.g_fade, np.array([int(getattr(b, "fade", False)) for b in bodies], np.int32)),
                    (self.g_shrink, np.array([int(getattr(b, "shrink", False)) for b in bodies], np.int32)),
                    (self.g_draw, np.array(draw, np.int32)),
                    (self.g_blend, np.array([BLEND[b.blend] for b in bodies] + [BLEND["opaque"]], np.int32)),
                    (self.g_opacity, np.array([b.opacity for b in bodies] + [1.0], np.float32)),
                ]
            )
            blends = {b.blend for b in bodies} | ({"opaque"} if model.scene.palette else set())
            self.has_opaque, self.has_alpha, self.has_additive = (
                "opaque" in blends,
                "alpha" in blends,
                "additive" in blends,
            )
            self.image = self._layer(3)  # linear RGB in [0, 1]
            self.accum = self._layer(3)  # opaque: coverage-weighted colour sum
            self.weight = self._layer()  # opaque: coverage sum
            self.motion_blur = bool(render_cfg.motion_blur)
            # 3D opaque spheres with motion blur leave a translucent streak behind the sphere, composited order-
            # independently in the same layers as 2D's translucent particles
            self.ghosts = self.motion_blur and self.dim == 3 and self.has_opaque
            if self.has_alpha or self.ghosts:
                self.a_accum = self._layer(3)  # alpha-weighted colour sum (2D; 3D streaks)
                self.a_weight = self._layer()  # alpha sum
                self.a_log = self._layer()  # sum of log(1 - alpha): log transmittance
            if self.has_alpha:
                self.order = ti.field(ti.i32, shape=model.capacity)  # 3D: translucent particles, back to front
                self.n_order = ti.field(ti.i32, shape=())
            if self.has_additive:
                self.light = self._layer(3)  # additive light (unbounded)
            self.depth = self._layer(dtype=ti.i32)  # depth bits of the nearest opaque surface (3D)
            # The 8-bit picture, (H, W, 3) top row first, or with output "rgba" GGUI's (W, H) packed RGBA, y up. On
            # the CPU it is a numpy array the kernels write straight into (no copy to the host at all); elsewhere a
            # device ndarray copied to the host once per picture().
            if output == "rgba":
                self.out = np.zeros((width, height), np.uint32)
            elif self.on_cpu:
                self.out = np.zeros((height, width, 3), np.uint8)
            else:
                self.out = runtime.ndarray(ti.u8, (height, width, 3))
            if self.motion_blur:
                self.x_prev = ti.Vector.field(self.dim, ti.f32, shape=model.capacity)  # positions a frame ago
                self.shutter = float(render_cfg.shutter)
            self.spline = self.motion_blur and render_cfg.motion_path == "spline"
            # per-particle drawing state that must move with the particles when the state sorts or compacts them: the
            # window and the runner attach them to the state (state.carry(renderer.tails))
            self.tails = [self.x_prev] if self.motion_blur else []
            if self.spline:
                self.x_mid = ti.Vector.field(self.dim, ti.f32, shape=model.capacity)  # positions at the frame's middle
                self.tails.append(self.x_mid)
                self.mid_captured = False
            self.color_mode = COLOR_MODES[render_cfg.color_by]
            self.t_lo = ti.field(ti.f32, shape=())
            self.t_hi = ti.field(ti.f32, shape=())
            self.speed_hi = ti.field(ti.f32, shape=())
            t_lo, t_hi = render_cfg.temperature_range
            transfer.upload([(self.t_lo, t_lo), (self.t_hi, t_hi), (self.speed_hi, render_cfg.speed_range)])
            self.exposure = float(render_cfg.exposure)
            self.background = ti.Vector(list(render_cfg.background))
            self.particle_scale = float(render_cfg.particle_scale)
            self.has_heat = state.particles.heat
            self.draw_springs = bool(render_cfg.draw_springs) and state.springs is not None and self.dim == 2
            self.brush: tuple[float, float, float] | None = None  # see set_brush
            self.chart = None
            self.potential = None  # the window's potential panel (a CurvePlot), when shown
            if render_cfg.chart:
                self.chart = Chart(
                    self.image, width, height, tuple(render_cfg.chart), self._scene_in_image(), self.panel_px
                )
            self._setup_view()
        if self.dim == 2:
            # the walls and heat sources do not move: paint them once (refresh_backdrop() after changing a source)
            self.backdrop = self._layer(3)
            if self.draw_springs:
                self.spring_log = self._layer()  # sum of log(1 - coverage) of the spring lines: log transmittance
            # Dirty tiles: every kernel that draws stamps the tiles its footprint touches with the frame number; the
            # compositing pass visits only tiles drawn in this frame or the last (to wipe what moved away), so a
            # small scene in a large picture costs little. The picture outside those tiles is kept from before.
            self.tiles_x, self.tiles_y = -(-width // TILE), -(-height // TILE)
            self.tile_stamp = ti.field(ti.i32, shape=(self.tiles_x, self.tiles_y))
            self.tile_stamp.fill(-2)
            self.strips = StripBins(width, model.capacity)
            self.stamp = ti.field(ti.i32, shape=())
            self.dirty = ti.field(ti.i32, shape=self.tiles_x * self.tiles_y)
            self.n_dirty = ti.field(ti.i32, shape=())
            self.overlay = ti.Vector.field(4, ti.i32, shape=MAX_OVERLAYS)  # tile ranges tx0, tx1, ty0, ty1
            self.n_overlay = ti.field(ti.i32, shape=())
            self.refresh_backdrop()
            self._overlays_changed()

    def _layer(self, channels: int = 1, dtype=ti.f32):
        """A W x H image field (indexed [x, y], stored row by row)."""
        shape = (self.width, self.height)
        if channels == 1:
            return ti.field(dtype, shape=shape, order=ROW_MAJOR)
        return ti.Vector.field(channels, dtype, shape=shape, order=ROW_MAJOR)

    def refresh_backdrop(self) -> None:
        """Repaint the static 2D backdrop (domain, walls, heat sources), e.g. after a source's temperature changed."""
        self._paint_backdrop()
        self.full_refresh = True

    def _overlays_changed(self) -> None:
        """The chart, potential panel or legend came or went: composite the whole picture once, and from now on
        redraw their rectangles every frame (their content changes whether or not particles move there)."""
        self.full_refresh = True
        if self.dim != 2:
            return
        rects = []  # (x0, x1, row0, row1) in pixels, rows counted from the top
        for plot in (self.chart, self.potential):
            if plot is not None and plot.fits:
                rects.append(plot.drawn_rect())
        if self._legend_shown():
            rects.append(self._legend_rect())
        if self.cfg.clock:
            rects.append(self._clock_rect())
        table = np.zeros((MAX_OVERLAYS, 4), np.int32)
        for k, (x0, x1, r0, r1) in enumerate(rects[:MAX_OVERLAYS]):
            y0, y1 = self.height - 1 - r1, self.height - 1 - r0  # rows from the top -> y up
            table[k] = (max(x0, 0) // TILE, x1 // TILE, max(y0, 0) // TILE, y1 // TILE)
        transfer.upload([(self.overlay, table), (self.n_overlay, min(len(rects), MAX_OVERLAYS))])  # one copy kernel

    @ti.kernel
    def _paint_backdrop(self):
        for x, y in self.backdrop:
            self.backdrop[x, y] = self._background(x, y)

    # ------------------------------------------------------------------ view
    def _setup_view(self):
        lo, hi = np.asarray(self.model.scene.world.lo), np.asarray(self.model.scene.world.hi)
        self.lo_np, self.hi_np = lo, hi
        if self.dim == 2:
            extent = hi - lo
            free = self.width - self.panel_px  # the width right of a side panel
            scale = min(free / extent[0], self.height / extent[1]) * 0.98
            self.px_per_unit = float(scale)
            centre_px = np.array([self.panel_px + free / 2, self.height / 2])
            self.offset = ti.Vector(list(centre_px - scale * (lo + hi) / 2))
            self.px_lo = ti.Vector(list(centre_px - scale * extent / 2))
            self.px_hi = ti.Vector(list(centre_px + scale * extent / 2))
            heat = self.model.scene.heat
            src = [s for s in heat.sources if s.visible] if heat else []
            self.n_src = len(src)
            ns = max(self.n_src, 1)
            self.src_lo = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_hi = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_t = ti.field(ti.f32, shape=ns)
            corners = [
                (
                    centre_px + scale * (np.asarray(s.lo) - (lo + hi) / 2),
                    centre_px + scale * (np.asarray(s.hi) - (lo + hi) / 2),
                )
                for s in src
            ]
            self._upload_sources(src, [c[0] for c in corners], [c[1] for c in corners])
        else:
            cfg = self.cfg
            centre = (lo + hi) / 2
            size = float(np.linalg.norm(hi - lo))
            target = np.asarray(cfg.camera_target) if cfg.camera_target else centre
            eye = (
                np.asarray(cfg.camera_position)
                if cfg.camera_position
                else centre + np.array([0.35, 0.45, 1.0]) * size * 0.9
            )
            self.set_camera(eye, target, cfg.fov)
            light = np.asarray(cfg.light_direction, dtype=float)
            self.light_dir = ti.Vector(list(light / np.linalg.norm(light)))
            self.specular = float(cfg.specular)
            self.ground = bool(cfg.ground)
            self.floor_y = float(lo[1])
            self.floor_lo = ti.Vector([float(lo[0]), float(lo[2])])
            self.floor_hi = ti.Vector([float(hi[0]), float(hi[2])])
            self.grid_step = float(max(1.0, round(max(hi[0] - lo[0], hi[2] - lo[2]) / 12)))
            # heat sources lying on the floor are drawn on it in their glow colour
            heat = self.model.scene.heat
            src = [s for s in (heat.sources if heat else []) if s.lo[1] <= lo[1] + 1 and s.visible]
            self.n_src = len(src)
            ns = max(self.n_src, 1)
            self.src_lo = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_hi = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_t = ti.field(ti.f32, shape=ns)
            self._upload_sources(src, [[s.lo[0], s.lo[2]] for s in src], [[s.hi[0], s.hi[2]] for s in src])

    def _upload_sources(self, sources: list, lows: list, highs: list) -> None:
        """The drawn heat sources' corners (pixels in 2D; x, z on the floor in 3D) and temperatures (degrees)."""
        # a power source has no temperature of its own: drawn hot if it heats, cold if it cools
        cold, hot = self.cfg.temperature_range
        temps = [s.temperature if s.temperature is not None else (hot if s.power >= 0 else cold) for s in sources]
        transfer.upload(
            [
                (self.src_lo, np.array(lows, np.float32).reshape(-1, 2)),
                (self.src_hi, np.array(highs, np.float32).reshape(-1, 2)),
                (self.src_t, np.array(temps, np.float32)),
            ]
        )

    def set_camera(self, eye, target, fov_degrees: float) -> None:
        """3D: place the camera (world units) looking at target with a vertical field of view in degrees."""
        eye, target = np.asarray(eye, dtype=float), np.asarray(target, dtype=float)
        fwd = target - eye
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, np.array([0.0, 1.0, 0.0]))
        if np.linalg.norm(right) < 1e-6:
            right = np.array([1.0, 0.0, 0.0])
        right /= np.linalg.norm(right)
        true_up = np.cross(right, fwd)
        self.eye_np, self.fwd_np, self.target_np = eye, fwd, target
        self.right_np, self.up_np = right, true_up
        if not hasattr(self, "camera"):
            # fields, not compile-time constants, so the window can orbit without recompiling
            self.camera = ti.Vector.field(3, ti.f32, shape=4)  # eye, right, up, forward
            self.focal_field = ti.field(ti.f32, shape=())  # pixels: focal length of the pinhole
        focal = 0.5 * self.height / math.tan(math.radians(fov_degrees) / 2)
        transfer.upload([(self.camera, np.array([eye, right, true_up, fwd], np.float32)), (self.focal_field, focal)])
        self.fov = float(fov_degrees)

    # ------------------------------------------------------------------ frames
    def begin_frame(self) -> None:
        """Remember positions before the simulation advances a frame (the tails of motion-blur streaks)."""
        if self.motion_blur:
            self._remember(self.x_prev)
            self.mid_captured = False

    def mid_frame(self) -> None:
        """Remember positions half-way through the frame's substeps (the bend of spline streaks); pass this as
        `midway` to Simulation.advance_frame. Without it a spline streak is drawn straight."""
        if self.spline:
            self._remember(self.x_mid)
            self.mid_captured = True

    def pick(self, u: float, v: float, reach_px: float = 12.0) -> np.ndarray | None:
        """3D: the position of the nearest particle drawn within reach_px pixels of the window point (u, v) (fractions
        of width and height, from the bottom left, as GGUI's cursor), or None: where a 3D brush acts."""
        x = self._positions().astype(float) if self.dim == 3 else np.zeros((0, 3))
        i = self._drawn_under(x, u, v, reach_px)
        return None if i is None else x[i]

    def world_point(self, u: float, v: float) -> np.ndarray:
        """2D: the world position (length units, (2,)) under the window point (u, v) (fractions from the bottom
        left, as GGUI's cursor)."""
        pixel = np.array([u * self.width, v * self.height]) - np.asarray(self.offset.to_list())
        return pixel / self.px_per_unit

    def pick_index(self, u: float, v: float, reach_px: float = 12.0) -> int | None:
        """3D: the index of the nearest particle drawn within reach_px pixels of the window point (u, v), or None."""
        return self._drawn_under(self._positions().astype(float), u, v, reach_px) if self.dim == 3 else None

    def _drawn_under(self, x: np.ndarray, u: float, v: float, reach_px: float) -> int | None:
        """Of the 3D positions x (N, 3), the index of the nearest drawn within reach_px pixels of (u, v), or None."""
        if len(x) == 0:
            return None
        rel = x - self.eye_np
        z = rel @ self.fwd_np
        focal = 0.5 * self.height / math.tan(math.radians(self.fov) / 2)
        front = z > 1e-6
        sx = self.cx + focal * (rel @ self.right_np) / np.where(front, z, 1.0)
        sy = self.height * 0.5 + focal * (rel @ self.up_np) / np.where(front, z, 1.0)
        near = front & ((sx - u * self.width) ** 2 + (sy - v * self.height) ** 2 <= reach_px**2)
        if not near.any():
            return None
        candidates = np.flatnonzero(near)
        return int(candidates[np.argmin(z[candidates])])

    def _positions(self) -> np.ndarray:
        """The live particles' positions, (N, D) NumPy."""
        return self.p.x.to_numpy()[: int(self.p.n[None])]

    @ti.kernel
    def _remember(self, into: ti.template()):
        for i in range(self.p.n[None]):
            into[i] = ti.cast(self.p.x[i], ti.f32)

    @ti.kernel
    def _straight_mids(self):
        for i in range(self.p.n[None]):
            self.x_mid[i] = 0.5 * (self.x_prev[i] + ti.cast(self.p.x[i], ti.f32))

    def render(self) -> None:
        """Draw the current state into self.image."""
        if self.spline and not self.mid_captured:
            self._straight_mids()  # no middle position this frame (a single step, a paused window): draw straight
            self.mid_captured = True
        if self.dim == 2:
            # The springs and splats accumulate into layers and stamp the tiles they touch; one pass over the
            # dirty tiles paints the background, composites the layers, zeroes them for the next frame and writes
            # the 8-bit picture.
            if self.draw_springs:
                self._springs_2d()
            self._splat_2d()
            self._composite()
        else:
            self._clear_3d()
            if self.has_opaque:
                self._depth_3d()
                self._shade_3d()
                if self.ghosts:
                    self._ghosts_3d()
                    self._resolve_ghosts_3d()
            if self.has_alpha:
                self._sort_translucent()
                self._composite_translucent()
            if self.has_additive:
                self._light_3d()
                self._tone_map()
        if self.chart is not None:
            self.chart.draw(self.out)
        if self.potential is not None:
            self.potential.draw(self.out)
        if self.dim == 2 and self.brush is not None:
            self._ring_2d(*self.brush, self.out)
        if self.output == "rgba" and self.dim == 3:
            self._pack(self.out)

    def set_brush(self, centre_px: tuple[float, float] | None, radius_px: float = 0.0) -> None:
        """2D: outline a tool's brush over the pictures from the next render(): a ring of radius_px pixels about
        centre_px (pixels, y up, GGUI's cursor times the picture size); None: no outline (the window's cursor).
        Drawn into the picture: GGUI's canvas.circles cost 3 ms a frame on the 2-core machine."""
        self.brush = None if centre_px is None else (float(centre_px[0]), float(centre_px[1]), float(radius_px))

    @ti.kernel
    def _ring_2d(self, cx: ti.f32, cy: ti.f32, r: ti.f32, out: ti.types.ndarray()):
        """The brush outline, anti-aliased, over the composited picture. Its tiles are stamped with this frame's
        number (compositing has moved the count on), so the next frame composites them again and wipes it."""
        x0 = ti.max(ti.cast(ti.floor(cx - r - 2.0), ti.i32), 0)
        x1 = ti.min(ti.cast(ti.ceil(cx + r + 2.0), ti.i32), self.width - 1)
        y0 = ti.max(ti.cast(ti.floor(cy - r - 2.0), ti.i32), 0)
        y1 = ti.min(ti.cast(ti.ceil(cy + r + 2.0), ti.i32), self.height - 1)
        if x0 <= x1 and y0 <= y1:
            self._stamp_tiles_as(x0, x1, y0, y1, self.stamp[None] - 1)
        for px, py in ti.ndrange((x0, x1 + 1), (y0, y1 + 1)):
            d = ti.abs((ti.Vector([px + 0.5 - cx, py + 0.5 - cy])).norm() - r)
            a = BRUSH_OPACITY * ti.math.clamp(1.25 - d, 0.0, 1.0)
            if a > 0.0:
                if ti.static(self.keep_image):
                    self.image[px, py] = self.image[px, py] * (1.0 - a) + ti.Vector(BRUSH_COLOR) * a
                else:
                    behind = get_pixel(out, self.height, px, py)
                    put_pixel(out, self.height, px, py, behind * (1.0 - a) + ti.Vector(BRUSH_COLOR) * a)

    def _scene_in_image(self) -> bool:
        """Whether the float image holds the drawn scene (else only the 8-bit output does): what a chart dims."""
        return self.keep_image or self.dim == 3

    def show_on(self, canvas) -> None:
        """Hand the last rendered picture to a GGUI canvas: the packed output as it is, else the float image."""
        if self.output == "rgba":
            from taichi.ui.utils import get_field_info

            self.label_window_output()
            canvas.canvas.set_image(get_field_info(self.out))  # what canvas.set_image does after its conversion
        else:
            canvas.set_image(self.image)

    def _composite(self) -> None:
        """2D: composite the dirty tiles (every tile after a change that affects the whole picture)."""
        self._resolve_2d(int(self.full_refresh), self.out)
        self.full_refresh = False

    def set_potential(self, values: np.ndarray | None, r_range: tuple[float, float] | None = None) -> None:
        """Show a curve (the pair force against distance, over distances r_range) in the top-right corner; None
        hides it."""
        if values is None:
            if self.potential is not None:
                self.potential = None
                self._overlays_changed()
            return
        if self.potential is None:
            self.potential = CurvePlot(self.image, self.width, self.height, self._scene_in_image())
            self._overlays_changed()
        self.potential.set_curve(values, r_range)

    def record(self, stats) -> None:
        """Give the chart (if the scene has one) this frame's measurements."""
        if self.chart is not None:
            self.chart.record(stats)

    def frame(self) -> np.ndarray:
        """Render and return the picture as an (H, W, 3) uint8 array, top row first (legend drawn on the host).
        On the CPU the array is the renderer's own buffer, valid until the next render(): copy it to keep it."""
        self.render()
        return self.picture()

    def set_chart(self, series: tuple[str, ...]) -> None:
        """Replace the chart (empty: none), e.g. the window's energy plot toggle; its history starts afresh."""

        scene_in_image = self._scene_in_image()
        self.chart = (
            Chart(self.image, self.width, self.height, tuple(series), scene_in_image, self.panel_px) if series else None
        )
        self._overlays_changed()

    def picture(self) -> np.ndarray:
        """The last rendered picture as an (H, W, 3) uint8 array (what frame() returns, without drawing again)."""
        if self.output == "rgba":  # packed already (2D compositing, or render() for 3D); unpack on the host
            rgba = self.out.view(np.uint8).reshape(self.width, self.height, 4)
            img = np.ascontiguousarray(rgba[:, ::-1, :3].transpose(1, 0, 2))
        else:
            if self.dim == 3 or self.keep_image:
                self._pack(self.out)
            img = self.out if self.on_cpu else self.out.to_numpy()
        self.draw_text_overlays(img)
        return img
