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

from .. import runtime
from ..oriented import data_oriented
from .chart import Chart, CurvePlot
from .colormaps import GLOW_STOPS, SPEED_STOPS, glow, glow_over_base, ramp_np, speed_map
from .pixels import draw_text, get_pixel, put_pixel
from .strips import StripBins

COLOR_MODES = {"temperature": 0, "material": 1, "speed": 2, "phase": 3}
DRAW = {"dot": 0, "splat": 1, "sphere": 2}
BLEND = {"opaque": 0, "alpha": 1, "additive": 2}
R_MIN = 0.7  # pixels: the smallest drawn radius
OUTPUTS = ("image", "picture", "rgba")  # see the module docstring
ROW_MAJOR = "ji"  # image fields are indexed [x, y] (GGUI's convention) but stored row by row, as the output is
MIN_FADE = 0.25  # the least opacity factor of an opaque or translucent particle smaller than R_MIN
SPLINE_SEGMENTS = 4  # chords per curved (spline) motion-blur streak
TILE = 16  # 2D: pixels per side of the tiles the compositing pass skips when nothing was drawn in them
MAX_OVERLAYS = 4  # 2D: rectangles redrawn every frame whatever moved (chart, potential panel, legend)
SPRING_COLOR = (0.55, 0.6, 0.7)
SPRING_OPACITY = 0.6
BRUSH_COLOR = (0.92, 0.92, 0.92)  # the window's tool outline
BRUSH_OPACITY = 0.85


@data_oriented
class Renderer:
    """Draws a Simulation's particles into `self.image` (W x H RGB floats)."""

    def __init__(
        self, sim, width: int, height: int, render_cfg, output: str = "image", strip_splat: bool = True
    ) -> None:
        """output: what render() leaves (see OUTPUTS in the module docstring); "image" packs the 8-bit picture from
        the float image only when picture() asks, "picture" and "rgba" have 2D compositing write it directly.
        strip_splat=False draws every 2D particle with atomic adds (the reference the strip binning is tested
        against)."""
        if output not in OUTPUTS:
            raise ValueError(f"unknown renderer output '{output}'; expected one of {', '.join(OUTPUTS)}")
        self.on_cpu = runtime.running_arch() == "cpu"
        if output == "rgba" and not self.on_cpu:
            raise ValueError("the packed 'rgba' output is a host array: CPU backend only")
        self.sim = sim
        self.strip_splat = strip_splat
        self.output = output
        self.keep_image = output == "image"
        self.cfg = render_cfg
        self.width, self.height = width, height
        self.dim = sim.dim
        bodies = sim.scene.groups  # every body, then every emitter, then (last) the spawn tool's particles
        self.n_groups = len(bodies) + 1
        self.g_draw = ti.field(ti.i32, shape=self.n_groups)
        self.g_blend = ti.field(ti.i32, shape=self.n_groups)
        self.g_opacity = ti.field(ti.f32, shape=self.n_groups)
        self.g_fade = ti.field(ti.i32, shape=self.n_groups)  # colour fades over the lifetime
        self.g_shrink = ti.field(ti.i32, shape=self.n_groups)  # drawn radius shrinks over the lifetime
        self.has_lifetimes = sim.has_lifetimes
        for k, body in enumerate(bodies):
            self.g_fade[k] = int(getattr(body, "fade", False))
            self.g_shrink[k] = int(getattr(body, "shrink", False))
            self.g_draw[k] = DRAW[body.draw]
            self.g_blend[k] = BLEND[body.blend]
            self.g_opacity[k] = body.opacity
        self.g_draw[len(bodies)] = DRAW["splat" if self.dim == 2 else "sphere"]
        self.g_blend[len(bodies)] = BLEND["opaque"]
        self.g_opacity[len(bodies)] = 1.0
        blends = {b.blend for b in bodies} | ({"opaque"} if sim.scene.palette else set())
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
            self.order = ti.field(ti.i32, shape=sim.capacity)  # 3D: translucent particles, back to front
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
            self.out = ti.ndarray(ti.u8, (height, width, 3))
        if self.motion_blur:
            self.x_prev = ti.Vector.field(self.dim, ti.f32, shape=sim.capacity)  # positions a frame ago
            self.shutter = float(render_cfg.shutter)
        self.spline = self.motion_blur and render_cfg.motion_path == "spline"
        self.tails = [self.x_prev] if self.motion_blur else []  # per-particle drawing state that moves with particles
        if self.spline:
            self.x_mid = ti.Vector.field(self.dim, ti.f32, shape=sim.capacity)  # positions at the frame's middle
            self.tails.append(self.x_mid)
            self.mid_captured = False
        self.color_mode = COLOR_MODES[render_cfg.color_by]
        self.t_lo = ti.field(ti.f32, shape=())
        self.t_hi = ti.field(ti.f32, shape=())
        self.t_lo[None], self.t_hi[None] = render_cfg.temperature_range
        self.speed_hi = ti.field(ti.f32, shape=())
        self.speed_hi[None] = render_cfg.speed_range
        self.exposure = float(render_cfg.exposure)
        self.background = ti.Vector(list(render_cfg.background))
        self.particle_scale = float(render_cfg.particle_scale)
        self.has_heat = sim.heat is not None
        self.draw_springs = bool(render_cfg.draw_springs) and sim.springs is not None and self.dim == 2
        self.brush: tuple[float, float, float] | None = None  # see set_brush
        self.chart = None
        self.potential = None  # the window's potential panel (a CurvePlot), when shown
        if render_cfg.chart:
            self.chart = Chart(self.image, width, height, tuple(render_cfg.chart), self._scene_in_image())
        if self.motion_blur and sim.emitters is not None:
            sim.emitters.listeners.append(self._follow_moves)
        if self.motion_blur and sim.reorder is not None:
            self.tail_scratch = ti.Vector.field(self.dim, ti.f32, shape=sim.capacity)
            sim.reorder.listeners.append(self._follow_order)
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
            self.strips = StripBins(width, sim.capacity)
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
                rects.append((plot.x0, plot.x0 + plot.box_w, plot.y_top, plot.y_top + plot.box_h + plot.label_height))
        if self._legend_shown():
            rects.append(self._legend_rect())
        table = np.zeros((MAX_OVERLAYS, 4), np.int32)
        for k, (x0, x1, r0, r1) in enumerate(rects[:MAX_OVERLAYS]):
            y0, y1 = self.height - 1 - r1, self.height - 1 - r0  # rows from the top -> y up
            table[k] = (max(x0, 0) // TILE, x1 // TILE, max(y0, 0) // TILE, y1 // TILE)
        self.overlay.from_numpy(table)
        self.n_overlay[None] = min(len(rects), MAX_OVERLAYS)

    @ti.kernel
    def _paint_backdrop(self):
        for x, y in self.backdrop:
            self.backdrop[x, y] = self._background(x, y)

    # ------------------------------------------------------------------ view
    def _setup_view(self):
        lo, hi = np.asarray(self.sim.scene.world.lo), np.asarray(self.sim.scene.world.hi)
        self.lo_np, self.hi_np = lo, hi
        if self.dim == 2:
            extent = hi - lo
            scale = min(self.width / extent[0], self.height / extent[1]) * 0.98
            self.px_per_unit = float(scale)
            centre_px = np.array([self.width, self.height]) / 2
            self.offset = ti.Vector(list(centre_px - scale * (lo + hi) / 2))
            self.px_lo = ti.Vector(list(centre_px - scale * extent / 2))
            self.px_hi = ti.Vector(list(centre_px + scale * extent / 2))
            heat = self.sim.scene.heat
            src = [s for s in heat.sources if s.visible] if heat else []
            self.n_src = len(src)
            ns = max(self.n_src, 1)
            self.src_lo = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_hi = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_t = ti.field(ti.f32, shape=ns)
            for k, s in enumerate(src):
                self.src_lo[k] = centre_px + scale * (np.asarray(s.lo) - (lo + hi) / 2)
                self.src_hi[k] = centre_px + scale * (np.asarray(s.hi) - (lo + hi) / 2)
                # a power source has no temperature of its own: drawn hot if it heats, cold if it cools
                hot, cold = self.cfg.temperature_range[1], self.cfg.temperature_range[0]
                self.src_t[k] = s.temperature if s.temperature is not None else (hot if s.power >= 0 else cold)
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
            heat = self.sim.scene.heat
            src = [s for s in (heat.sources if heat else []) if s.lo[1] <= lo[1] + 1 and s.visible]
            self.n_src = len(src)
            ns = max(self.n_src, 1)
            self.src_lo = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_hi = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_t = ti.field(ti.f32, shape=ns)
            for k, s in enumerate(src):
                self.src_lo[k] = [s.lo[0], s.lo[2]]
                self.src_hi[k] = [s.hi[0], s.hi[2]]
                hot, cold = self.cfg.temperature_range[1], self.cfg.temperature_range[0]
                self.src_t[k] = s.temperature if s.temperature is not None else (hot if s.power >= 0 else cold)

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
        for k, v in enumerate((eye, right, true_up, fwd)):
            self.camera[k] = [float(c) for c in v]
        self.focal_field[None] = 0.5 * self.height / math.tan(math.radians(fov_degrees) / 2)
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
        x = self.sim.positions().astype(float)
        if self.dim != 3 or len(x) == 0:
            return None
        rel = x - self.eye_np
        z = rel @ self.fwd_np
        focal = 0.5 * self.height / math.tan(math.radians(self.fov) / 2)
        front = z > 1e-6
        sx = self.width * 0.5 + focal * (rel @ self.right_np) / np.where(front, z, 1.0)
        sy = self.height * 0.5 + focal * (rel @ self.up_np) / np.where(front, z, 1.0)
        near = front & ((sx - u * self.width) ** 2 + (sy - v * self.height) ** 2 <= reach_px**2)
        if not near.any():
            return None
        candidates = np.flatnonzero(near)
        return x[candidates[np.argmin(z[candidates])]]

    def detach(self) -> None:
        """Stop following the simulation's particle moves (before this renderer is replaced)."""
        if self.sim.emitters is not None and self._follow_moves in self.sim.emitters.listeners:
            self.sim.emitters.listeners.remove(self._follow_moves)
        if self.sim.reorder is not None and self._follow_order in self.sim.reorder.listeners:
            self.sim.reorder.listeners.remove(self._follow_order)

    def _follow_moves(self, hole, filler, count: int) -> None:
        """Particles moved slots (retirement): move their motion-blur tails with them."""
        if count:
            self._move_tails(hole, filler, count)

    @ti.kernel
    def _follow_order(self, order: ti.template(), inverse: ti.template(), n: ti.i32):
        """The particle storage was sorted (sim.reorder): sort the motion-blur tails the same way."""
        for tail in ti.static(self.tails):
            for k in range(n):
                self.tail_scratch[k] = tail[order[k]]
            for k in range(n):
                tail[k] = self.tail_scratch[k]

    @ti.kernel
    def _move_tails(self, hole: ti.template(), filler: ti.template(), count: ti.i32):
        for m in range(count):
            for tail in ti.static(self.tails):
                tail[hole[m]] = tail[filler[m]]

    @ti.kernel
    def _remember(self, into: ti.template()):
        for i in range(self.sim.particles.n[None]):
            into[i] = ti.cast(self.sim.particles.x[i], ti.f32)

    @ti.kernel
    def _straight_mids(self):
        for i in range(self.sim.particles.n[None]):
            self.x_mid[i] = 0.5 * (self.x_prev[i] + ti.cast(self.sim.particles.x[i], ti.f32))

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

            canvas.canvas.set_image(get_field_info(self.out))  # what canvas.set_image does after its conversion
        else:
            canvas.set_image(self.image)

    def _composite(self) -> None:
        """2D: composite the dirty tiles (every tile after a change that affects the whole picture)."""
        self._resolve_2d(int(self.full_refresh), self.out)
        self.full_refresh = False

    def set_potential(self, values: np.ndarray | None) -> None:
        """Show a curve (the pair force against distance) in the top-right corner; None hides it."""
        if values is None:
            if self.potential is not None:
                self.potential = None
                self._overlays_changed()
            return
        if self.potential is None:
            self.potential = CurvePlot(self.image, self.width, self.height, self._scene_in_image())
            self._overlays_changed()
        self.potential.set_curve(values)

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
        self.chart = Chart(self.image, self.width, self.height, tuple(series), scene_in_image) if series else None
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
        if self.cfg.legend:
            self.draw_legend(img)
        if self.chart is not None:
            self.chart.label(img)
        return img

    # ------------------------------------------------------------------ shared funcs
    @ti.func
    def life_left(self, i):
        """1 at birth falling to 0 at death for particles with a lifetime, else 1."""
        left = 1.0
        if ti.static(self.has_lifetimes):
            life = self.sim.particles.lifetime[i]
            if life > 0.0:
                left = ti.max(1.0 - self.sim.particles.age[i] / life, 0.0)
        return left

    @ti.func
    def drawn_radius(self, i):
        """Drawn radius (length): the particle's radius times render.particle_scale, shrinking with age if asked."""
        r = self.sim.particles.radius[i] * self.particle_scale
        if ti.static(self.has_lifetimes):
            if self.g_shrink[self.sim.particles.group[i]]:
                r *= self.life_left(i)
        return r

    @ti.func
    def particle_color(self, i):
        """Drawing colour: the colour map's, darkened over the lifetime when fading (not for alpha: see below)."""
        c = self._base_color(i)
        if ti.static(self.has_lifetimes):
            g = self.sim.particles.group[i]
            if self.g_fade[g] and self.g_blend[g] != BLEND["alpha"]:
                c *= self.life_left(i)
        return c

    @ti.func
    def group_opacity(self, i):
        """Opacity of particle i's group; a fading translucent particle grows fainter rather than darker."""
        g = self.sim.particles.group[i]
        a = self.g_opacity[g]
        if ti.static(self.has_lifetimes):
            if self.g_fade[g] and self.g_blend[g] == BLEND["alpha"]:
                a *= self.life_left(i)
        return a

    @ti.func
    def _base_color(self, i):
        p = self.sim.particles
        base = p.color[i]
        c = base
        if ti.static(self.color_mode == 0 and self.has_heat):
            t = (p.T[i] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
            c = glow_over_base(base, t)
        elif ti.static(self.color_mode == 2):
            c = speed_map(p.v[i].norm() / self.speed_hi[None])
        elif ti.static(self.color_mode == 3 and self.has_heat):
            phi = self.sim.phase.fraction(p.h[i], p.material[i])
            c = (1.0 - phi) * base + phi * self.sim.materials.liquid_color[p.material[i]]
        return c

    @ti.func
    def _segment(self, pix, a, b):
        """(distance from pixel centre pix to segment a-b, parameter t in [0, 1] of the nearest point; t = 1 at b)."""
        ab = b - a
        l2 = ab.dot(ab)
        t = 1.0
        if l2 > 1e-12:
            t = ti.math.clamp((pix - a).dot(ab) / l2, 0.0, 1.0)
        return (pix - (a + t * ab)).norm(), t

    @ti.func
    def _curve(self, pix, a, c, b):
        """(distance from pix to the quadratic Bezier a-c-b, its parameter there), on SPLINE_SEGMENTS chords."""
        best = 1e30
        t_best = 1.0
        start = a
        for k in ti.static(range(1, SPLINE_SEGMENTS + 1)):
            t = k / SPLINE_SEGMENTS
            end = (1.0 - t) ** 2 * a + 2.0 * (1.0 - t) * t * c + t * t * b
            d, s = self._segment(pix, start, end)
            if d < best:
                best = d
                t_best = (k - 1 + s) / SPLINE_SEGMENTS
            start = end
        return best, t_best

    @ti.func
    def _streak(self, prev, mid, head):
        """(tail, control point, head) in pixels of the streak of a particle that went prev -> mid -> head over the
        frame: the last `shutter` of the straight segment, or of the quadratic through the three (spline)."""
        tail = head + self.shutter * (prev - head)
        ctrl = 0.5 * (tail + head)
        if ti.static(self.spline):
            t0 = 1.0 - self.shutter
            c = 2.0 * mid - 0.5 * (prev + head)  # the quadratic's control point: it passes through mid at t = 1/2
            tail = (1.0 - t0) ** 2 * prev + 2.0 * (1.0 - t0) * t0 * c + t0 * t0 * head
            ctrl = (1.0 - t0) * c + t0 * head  # de Casteljau: the control point of the piece from t0 to 1
        return tail, ctrl, head

    @ti.func
    def _weight(self, pix, a, c, b, r, blurred):
        """Coverage of pixel pix by the capsule of radius r (pixels) around the streak a-b (curved through control
        point c with spline motion blur), times the fall-off along a streak."""
        w, _ = self._coverage(pix, a, c, b, r, blurred)
        return w

    @ti.func
    def _coverage(self, pix, a, c, b, r, blurred):
        """(_weight, the parameter along the streak of the nearest point: 0 at the tail a, 1 at the head b)."""
        d, t = 0.0, 0.0
        if ti.static(self.spline):
            if blurred:
                d, t = self._curve(pix, a, c, b)
            else:
                d, t = self._segment(pix, a, b)
        else:
            d, t = self._segment(pix, a, b)
        w = ti.math.clamp(r + 0.5 - d, 0.0, 1.0)
        if blurred:
            w *= 0.25 + 0.75 * t
        return w, t

    @ti.func
    def _box(self, a, b, r, c):
        """Pixel bounds of the capsule around a-b (and control point c, which bounds a curve with the ends): every
        pixel whose centre lies within r + 0.5 of it (where the coverage clamp(r + 0.5 - d, 0, 1) is not zero), as
        pixel px's centre is px + 0.5."""
        lo = ti.min(ti.min(a, b), c)
        hi = ti.max(ti.max(a, b), c)
        x0 = ti.max(ti.cast(ti.ceil(lo[0] - r - 1), ti.i32), 0)
        x1 = ti.min(ti.cast(ti.floor(hi[0] + r), ti.i32), self.width - 1)
        y0 = ti.max(ti.cast(ti.ceil(lo[1] - r - 1), ti.i32), 0)
        y1 = ti.min(ti.cast(ti.floor(hi[1] + r), ti.i32), self.height - 1)
        return x0, x1, y0, y1

    @ti.func
    def _stamp_tiles(self, x0, x1, y0, y1):
        """2D: mark the tiles of pixel box [x0, x1] x [y0, y1] as drawn in this frame."""
        self._stamp_tiles_as(x0, x1, y0, y1, self.stamp[None])

    @ti.func
    def _stamp_tiles_as(self, x0, x1, y0, y1, stamp):
        """2D: mark the tiles of pixel box [x0, x1] x [y0, y1] as drawn in frame number `stamp`."""
        if ti.static(self.dim == 2):
            for tx in range(x0 // TILE, x1 // TILE + 1):
                for ty in range(y0 // TILE, y1 // TILE + 1):
                    self.tile_stamp[tx, ty] = stamp

    @ti.func
    def _deposit_light(self, a, c, b, r, energy, col, blurred, use_depth, z):
        """Spread `energy` of colour col over the capsule's footprint with normalised weights (depth-tested in 3D)."""
        x0, x1, y0, y1 = self._box(a, b, r, c)
        self._stamp_tiles(x0, x1, y0, y1)
        total = 0.0
        for px in range(x0, x1 + 1):
            for py in range(y0, y1 + 1):
                total += self._weight(ti.Vector([px + 0.5, py + 0.5]), a, c, b, r, blurred)
        if total > 0.0:
            zbits = ti.bit_cast(ti.cast(ti.max(z, 0.0), ti.f32), ti.i32)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    w = self._weight(ti.Vector([px + 0.5, py + 0.5]), a, c, b, r, blurred)
                    visible = True
                    if use_depth:
                        visible = zbits <= self.depth[px, py]
                    if w > 0.0 and visible:
                        self.light[px, py] += energy * w / total * col

    # ------------------------------------------------------------------ 2D
    @ti.func
    def _background(self, x, y):
        """The 2D backdrop at pixel (x, y): the domain, its walls as a faint frame, the heat sources."""
        pix = ti.Vector([x + 0.5, y + 0.5])
        c = self.background
        inside = (
            pix[0] >= self.px_lo[0] and pix[0] <= self.px_hi[0] and pix[1] >= self.px_lo[1] and pix[1] <= self.px_hi[1]
        )
        if not inside:
            c = self.background * 0.6
        elif (
            ti.min(pix[0] - self.px_lo[0], self.px_hi[0] - pix[0], pix[1] - self.px_lo[1], self.px_hi[1] - pix[1]) < 1.5
        ):
            c = self.background * 2.2 + 0.04  # the walls: a faint frame
        for k in range(self.n_src):
            if (
                pix[0] >= self.src_lo[k][0] - 1
                and pix[0] <= self.src_hi[k][0] + 1
                and pix[1] >= self.src_lo[k][1] - 2
                and pix[1] <= self.src_hi[k][1] + 1
            ):
                t = (self.src_t[k] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
                c = glow(ti.max(t, 0.35)) if t > 0.05 else ti.Vector([0.3, 0.55, 1.0])
        return c

    @ti.kernel
    def _springs_2d(self):
        s = self.sim.springs
        p = self.sim.particles
        for k in range(s.span[None]):
            if s.alive[k]:
                a = ti.cast(p.x[s.i[k]], ti.f32) * self.px_per_unit + self.offset
                b = ti.cast(p.x[s.j[k]], ti.f32) * self.px_per_unit + self.offset
                if (a - b).norm() < 0.25 * ti.max(self.width, self.height):  # skip periodic wrap-arounds
                    x0, x1, y0, y1 = self._box(a, b, 0.5, a)
                    self._stamp_tiles(x0, x1, y0, y1)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            d, _ = self._segment(ti.Vector([px + 0.5, py + 0.5]), a, b)
                            cov = SPRING_OPACITY * ti.math.clamp(1.0 - d, 0.0, 1.0)
                            if cov > 0.0:  # lines of one colour "over" each other: only the transmittance adds up
                                self.spring_log[px, py] += ti.log(1.0 - cov)

    @ti.kernel
    def _splat_2d(self):
        """Bin the particles by screen strip, draw the even strips, then the odd ones, with plain adds (see
        strips.py), then the particles that reach beyond their strip, with atomic adds."""
        p = self.sim.particles
        n = p.n[None]
        bins = self.strips
        bins.clear()
        self.sim.loops.light()
        for i in range(n):
            tail, ctrl, head, r, _, _ = self._splat_shape(i)
            x0, x1, _, _ = self._box(tail, head, r, ctrl)
            s = bins.strip_for(x0, x1, head[0])
            if self.g_blend[p.group[i]] == BLEND["additive"] or not ti.static(self.strip_splat):
                s = bins.wide
            bins.put(i, s)
        bins.finish(n)
        for parity in ti.static(range(2)):
            for u in range(bins.pass_iterations):
                s = bins.strip_at(u, parity)
                if s >= 0:
                    for k in range(bins.start[s], bins.start[s] + bins.count[s]):
                        self._splat_one(bins.ids[k], True)
        for k in range(bins.start[bins.wide], bins.start[bins.wide] + bins.count[bins.wide]):
            self._splat_one(bins.ids[k], False)

    @ti.func
    def _splat_shape(self, i):
        """(tail, control point, head) of particle i's streak in pixels (all at the head when it is not blurred),
        its drawn radius r >= R_MIN and true radius in pixels, and whether it is blurred."""
        head = ti.cast(self.sim.particles.x[i], ti.f32) * self.px_per_unit + self.offset
        tail, ctrl = head, head
        blurred = False
        if ti.static(self.motion_blur):
            prev = self.x_prev[i] * self.px_per_unit + self.offset
            mid = 0.5 * (prev + head)
            if ti.static(self.spline):
                mid = self.x_mid[i] * self.px_per_unit + self.offset
            tail, ctrl, head = self._streak(prev, mid, head)
            span = ti.max((tail - head).norm(), (mid - head).norm())
            blurred = (tail - head).norm() > 1e-3 and span < 0.5 * self.width  # not a periodic wrap
            if not blurred:
                tail, ctrl = head, head
        r_true = self.drawn_radius(i) * self.px_per_unit
        if self.g_draw[self.sim.particles.group[i]] == 0:  # a dot: one pixel
            r_true = 0.5
        return tail, ctrl, head, ti.max(r_true, R_MIN), r_true, blurred

    @ti.func
    def _splat_one(self, i, plain: ti.template()):
        """Add particle i's coverage to the layers: by plain load and store when `plain` (no other thread draws
        near it), else by atomic adds."""
        tail, ctrl, head, r, r_true, blurred = self._splat_shape(i)
        g = self.sim.particles.group[i]
        blend, opacity = self.g_blend[g], self.group_opacity(i)
        fade = ti.max((r_true / r) ** 2, MIN_FADE)
        col = self.particle_color(i)
        if blend == 2:
            if ti.static(self.has_additive):
                energy = opacity * math.pi * r_true * r_true
                self._deposit_light(tail, ctrl, head, r, energy, col, blurred, False, 0.0)
        else:
            x0, x1, y0, y1 = self._box(tail, head, r, ctrl)
            self._stamp_tiles(x0, x1, y0, y1)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    w = fade * self._weight(ti.Vector([px + 0.5, py + 0.5]), tail, ctrl, head, r, blurred)
                    if w > 0.0:
                        if blend == 0:
                            _add(self.accum, px, py, w * col, plain)
                            _add(self.weight, px, py, w, plain)
                        else:
                            if ti.static(self.has_alpha):
                                a = ti.min(w * opacity, 0.999)
                                _add(self.a_accum, px, py, a * col, plain)
                                _add(self.a_weight, px, py, a, plain)
                                _add(self.a_log, px, py, ti.log(1.0 - a), plain)

    @ti.kernel
    def _resolve_2d(self, full: ti.i32, out: ti.types.ndarray()):
        stamp = self.stamp[None]
        for tx, ty in self.tile_stamp:
            dirty = self.tile_stamp[tx, ty] >= stamp - 1 or full != 0
            for k in range(self.n_overlay[None]):
                o = self.overlay[k]
                if tx >= o[0] and tx <= o[1] and ty >= o[2] and ty <= o[3]:
                    dirty = True
            if dirty:
                self.dirty[ti.atomic_add(self.n_dirty[None], 1)] = tx + ty * self.tiles_x
        # A tile row per iteration: 2x faster than a pixel per iteration, and enough iterations for every thread
        # (Taichi's CPU loops hand out blocks of hundreds of iterations: a loop over tiles would run on one thread)
        for m in range(self.n_dirty[None] * TILE):
            tile = self.dirty[m // TILE]
            x0, y = tile % self.tiles_x * TILE, tile // self.tiles_x * TILE + m % TILE
            if y < self.height:
                for i in range(ti.min(TILE, self.width - x0)):
                    self._resolve_pixel(x0 + i, y, out)
        self.n_dirty[None] = 0
        self.stamp[None] = stamp + 1

    @ti.func
    def _resolve_pixel(self, x, y, out: ti.template()):
        """Composite pixel (x, y) over the backdrop, zero its layers, write it to the float image (when kept) and
        to the 8-bit picture."""
        c = self.backdrop[x, y]
        if ti.static(self.draw_springs):
            log_t = self.spring_log[x, y]
            if log_t < 0.0:
                t = ti.exp(log_t)
                c = c * t + ti.Vector(SPRING_COLOR) * (1.0 - t)
                self.spring_log[x, y] = 0.0
        w = self.weight[x, y]
        if w > 0.0:
            a = ti.min(w, 1.0)
            c = c * (1.0 - a) + self.accum[x, y] / w * a
            self.accum[x, y] = ti.Vector([0.0, 0.0, 0.0])
            self.weight[x, y] = 0.0
        if ti.static(self.has_alpha):
            c = self._over_translucent(x, y, c)
        if ti.static(self.has_additive):
            c += 1.0 - ti.exp(-self.exposure * self.light[x, y])
            self.light[x, y] = ti.Vector([0.0, 0.0, 0.0])
        c = ti.min(c, 1.0)
        if ti.static(self.keep_image):
            self.image[x, y] = c  # the window shows it; picture() packs it to 8 bits only when asked
        else:
            self._put_out(out, x, y, c)

    # ------------------------------------------------------------------ 3D
    @ti.func
    def _project(self, pos):
        rel = ti.cast(pos, ti.f32) - self.camera[0]
        z = rel.dot(self.camera[3])
        sx = self.width * 0.5 + self.focal_field[None] * rel.dot(self.camera[1]) / ti.max(z, 1e-6)
        sy = self.height * 0.5 + self.focal_field[None] * rel.dot(self.camera[2]) / ti.max(z, 1e-6)
        return ti.Vector([sx, sy]), z

    @ti.kernel
    def _clear_3d(self):
        for x, y in self.image:
            shade = 0.75 + 0.25 * y / self.height
            c = self.background * shade
            if ti.static(self.ground):
                # the floor plane y = floor_y, with a faint grid so depth reads
                ray = (
                    self.camera[3] * self.focal_field[None]
                    + self.camera[1] * (x + 0.5 - 0.5 * self.width)
                    + self.camera[2] * (y + 0.5 - 0.5 * self.height)
                ).normalized()
                if ray[1] < -1e-6:
                    s = (self.floor_y - self.camera[0][1]) / ray[1]
                    hit = self.camera[0] + s * ray
                    u = ti.Vector([hit[0], hit[2]])
                    if (u >= self.floor_lo).all() and (u <= self.floor_hi).all():
                        c = c * 1.35 + 0.015
                        f = ti.abs(u / self.grid_step - ti.round(u / self.grid_step)) * self.grid_step
                        pixel_size = s / self.focal_field[None]
                        line = ti.max(1.0 - f[0] / (1.2 * pixel_size), 1.0 - f[1] / (1.2 * pixel_size), 0.0)
                        c += 0.05 * ti.min(line, 1.0)
                        for k in range(self.n_src):
                            if (u >= self.src_lo[k]).all() and (u <= self.src_hi[k]).all():
                                t = (self.src_t[k] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
                                c = c * 0.6 + 0.3 * (glow(ti.max(t, 0.35)) if t > 0.05 else ti.Vector([0.3, 0.55, 1.0]))
            self.image[x, y] = c
            self.depth[x, y] = 2147483647
            if ti.static(self.has_additive):
                self.light[x, y] = ti.Vector([0.0, 0.0, 0.0])

    @ti.kernel
    def _depth_3d(self):
        p = self.sim.particles
        for i in range(p.n[None]):
            if self.g_blend[p.group[i]] == 0:
                centre, z = self._project(p.x[i])
                if z > 1e-3:
                    rad = self.drawn_radius(i)
                    r = ti.max(rad * self.focal_field[None] / z, R_MIN)
                    x0, x1, y0, y1 = self._box(centre, centre, r, centre)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            u = (ti.Vector([px + 0.5, py + 0.5]) - centre) / r
                            q = u.dot(u)
                            if q <= 1.0:
                                zs = z - rad * ti.sqrt(1.0 - q)
                                ti.atomic_min(self.depth[px, py], ti.bit_cast(ti.cast(ti.max(zs, 0.0), ti.f32), ti.i32))

    @ti.kernel
    def _shade_3d(self):
        p = self.sim.particles
        for i in range(p.n[None]):
            g = p.group[i]
            if self.g_blend[g] == 0:
                centre, z = self._project(p.x[i])
                if z > 1e-3:
                    rad = self.drawn_radius(i)
                    r = ti.max(rad * self.focal_field[None] / z, R_MIN)
                    col = self.particle_color(i)
                    shaded = self.g_draw[g] == 2
                    x0, x1, y0, y1 = self._box(centre, centre, r, centre)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            u = (ti.Vector([px + 0.5, py + 0.5]) - centre) / r
                            q = u.dot(u)
                            if q <= 1.0:
                                zs = z - rad * ti.sqrt(1.0 - q)
                                bits = ti.bit_cast(ti.cast(ti.max(zs, 0.0), ti.f32), ti.i32)
                                if bits == self.depth[px, py]:
                                    c = col
                                    if shaded:
                                        nz = ti.sqrt(1.0 - q)
                                        normal = u[0] * self.camera[1] + u[1] * self.camera[2] - nz * self.camera[3]
                                        diffuse = ti.max(normal.dot(self.light_dir), 0.0)
                                        half = (self.light_dir - self.camera[3]).normalized()
                                        spec = ti.max(normal.dot(half), 0.0) ** 32
                                        c = col * (0.3 + 0.7 * diffuse) + self.specular * spec
                                    self.image[px, py] = c

    @ti.func
    def _streak_3d(self, i):
        """(tail, control point, head) in pixels of particle i's motion-blur streak, the depths of its tail and
        head, and whether it is drawn as a streak: motion blur on, all three points in front of the camera, moved
        over 1e-3 px and not across a periodic wrap. Otherwise tail and control point are the head."""
        head, z = self._project(self.sim.particles.x[i])
        tail, ctrl, z_tail = head, head, z
        blurred = False
        if ti.static(self.motion_blur):
            prev, zp = self._project(self.x_prev[i])
            mid, zm = 0.5 * (prev + head), zp
            if ti.static(self.spline):
                mid, zm = self._project(self.x_mid[i])
            if z > 1e-3 and zp > 1e-3 and zm > 1e-3:
                t, c, _ = self._streak(prev, mid, head)
                span = ti.max((t - head).norm(), (mid - head).norm())
                if (t - head).norm() > 1e-3 and span < 0.5 * self.width:
                    tail, ctrl, z_tail = t, c, z + self.shutter * (zp - z)
                    blurred = True
        return tail, ctrl, head, z_tail, z, blurred

    @ti.kernel
    def _ghosts_3d(self):
        """Motion blur of opaque spheres: a streak from where each was a shutter ago to where it is, its opacity
        falling towards the tail, depth-tested at its depth along the way (so the sphere itself, in front of the
        streak's head, stays solid, and nearer spheres hide it)."""
        p = self.sim.particles
        for i in range(p.n[None]):
            g = p.group[i]
            if self.g_blend[g] == 0:
                tail, ctrl, head, z_tail, z, blurred = self._streak_3d(i)
                if blurred and (tail - head).norm() > 0.5:  # moved half a pixel or more
                    r = ti.max(self.drawn_radius(i) * self.focal_field[None] / z, R_MIN)
                    col = self.particle_color(i)
                    if self.g_draw[g] == 2:  # the shade of the sphere's centre, facing the camera
                        col = col * (0.3 + 0.7 * ti.max(-self.camera[3].dot(self.light_dir), 0.0))
                    opacity = self.g_opacity[g]
                    x0, x1, y0, y1 = self._box(tail, head, r, ctrl)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            w, t = self._coverage(ti.Vector([px + 0.5, py + 0.5]), tail, ctrl, head, r, True)
                            zbits = ti.bit_cast(ti.cast(z_tail + t * (z - z_tail), ti.f32), ti.i32)
                            if w > 0.0 and zbits <= self.depth[px, py]:
                                a = ti.min(w * opacity, 0.999)
                                self.a_accum[px, py] += a * col
                                self.a_weight[px, py] += a
                                self.a_log[px, py] += ti.log(1.0 - a)

    @ti.kernel
    def _resolve_ghosts_3d(self):
        for x, y in self.image:
            self.image[x, y] = self._over_translucent(x, y, self.image[x, y])

    @ti.func
    def _over_translucent(self, x, y, c):
        """Colour c with pixel (x, y)'s translucent layer composited over it (weighted-average colour, total alpha
        1 - prod(1 - a)); the layer is zeroed for the next frame."""
        aw = self.a_weight[x, y]
        if aw > 0.0:
            a = 1.0 - ti.exp(self.a_log[x, y])
            c = c * (1.0 - a) + self.a_accum[x, y] / aw * a
            self.a_accum[x, y] = ti.Vector([0.0, 0.0, 0.0])
            self.a_weight[x, y] = 0.0
            self.a_log[x, y] = 0.0
        return c

    def _sort_translucent(self) -> None:
        """Order the translucent particles back to front (by distance along the view direction), on the host."""
        n = int(self.sim.particles.n[None])
        x = self.sim.particles.x.to_numpy()[:n]
        group = self.sim.particles.group.to_numpy()[:n]
        blend = self.g_blend.to_numpy()
        ids = np.flatnonzero(blend[group] == BLEND["alpha"])
        depth = (x[ids] - self.eye_np) @ self.fwd_np
        order = ids[np.argsort(-depth, kind="stable")].astype(np.int32)
        full = np.zeros(self.sim.capacity, dtype=np.int32)
        full[: len(order)] = order
        self.order.from_numpy(full)
        self.n_order[None] = len(order)

    @ti.kernel
    def _composite_translucent(self):
        p = self.sim.particles
        ti.loop_config(serialize=True)  # "over" compositing must follow the back-to-front order
        for k in range(self.n_order[None]):
            i = self.order[k]
            centre, z = self._project(p.x[i])
            if z > 1e-3:
                r = ti.max(self.drawn_radius(i) * self.focal_field[None] / z, R_MIN)
                col = self.particle_color(i)
                opacity = self.group_opacity(i)
                zbits = ti.bit_cast(ti.cast(z, ti.f32), ti.i32)
                x0, x1, y0, y1 = self._box(centre, centre, r, centre)
                for px in range(x0, x1 + 1):
                    for py in range(y0, y1 + 1):
                        w = self._weight(ti.Vector([px + 0.5, py + 0.5]), centre, centre, centre, r, False)
                        if w > 0.0 and zbits <= self.depth[px, py]:
                            a = ti.min(w * opacity, 1.0)
                            self.image[px, py] = self.image[px, py] * (1.0 - a) + col * a

    @ti.kernel
    def _light_3d(self):
        p = self.sim.particles
        for i in range(p.n[None]):
            g = p.group[i]
            if self.g_blend[g] == 2:
                tail, ctrl, head, _, z, blurred = self._streak_3d(i)
                if z > 1e-3:
                    r_true = self.drawn_radius(i) * self.focal_field[None] / z
                    if self.g_draw[g] == 0:
                        r_true = 0.5
                    r = ti.max(r_true, R_MIN)
                    energy = self.g_opacity[g] * math.pi * r_true * r_true
                    self._deposit_light(tail, ctrl, head, r, energy, self.particle_color(i), blurred, True, z)

    @ti.kernel
    def _tone_map(self):
        for x, y in self.image:
            self.image[x, y] = ti.min(self.image[x, y] + 1.0 - ti.exp(-self.exposure * self.light[x, y]), 1.0)

    @ti.kernel
    def _pack(self, out: ti.types.ndarray()):
        for x, y in self.image:
            self._put_out(out, x, y, self.image[x, y])

    @ti.func
    def _put_out(self, out: ti.template(), x, y, c):
        """Write colour c (floats in [0, 1]) at pixel (x, y) (y up) of the 8-bit output (see put_pixel)."""
        put_pixel(out, self.height, x, y, c)

    # ------------------------------------------------------------------ legend (host side, on the 8-bit frame)
    def legend_colors(self, n: int) -> np.ndarray:
        """The active colour map sampled at n points, (n, 3) floats."""
        ts = np.linspace(0, 1, n)
        if self.cfg.color_by == "speed":
            return np.array([ramp_np(SPEED_STOPS, t) for t in ts])
        return np.array([ramp_np(GLOW_STOPS, t) for t in ts])

    def _legend_geometry(self) -> tuple[int, int, int, int, int]:
        """(x0, row0, bar width, bar height, text scale) of the colour bar, rows counted from the top."""
        h, w = self.height, self.width
        bar_w, bar_h = max(60, w // 6), max(6, h // 60)
        return w - bar_w - 12, h - bar_h - 16, bar_w, bar_h, max(1, h // 240)

    def _legend_rect(self) -> tuple[int, int, int, int]:
        """(x0, x1, row0, row1): the pixels the legend (bar, frame and labels) may draw on."""
        x0, y0, bar_w, bar_h, scale = self._legend_geometry()
        return x0 - 64 * scale, x0 + bar_w + 1, y0 - 1, y0 + bar_h + 4 + 5 * scale

    def _legend_shown(self) -> bool:
        """Whether the colour bar is drawn: asked for, colouring by a scale, and room for it in the picture."""
        x0, x1, row0, row1 = self._legend_rect()
        fits = x0 >= 0 and row0 >= 0 and x1 <= self.width and row1 <= self.height
        return self.cfg.legend and self.cfg.color_by in ("temperature", "speed") and fits

    def draw_legend(self, img: np.ndarray) -> None:
        """A colour bar with its range labelled, in the bottom-right corner of an (H, W, 3) uint8 frame."""
        if not self._legend_shown():
            return
        x0, y0, bar_w, bar_h, scale = self._legend_geometry()
        colors = (self.legend_colors(bar_w) * 255).astype(np.uint8)
        img[y0 : y0 + bar_h, x0 : x0 + bar_w] = colors[None, :, :]
        img[y0 - 1, x0 - 1 : x0 + bar_w + 1] = 200
        img[y0 + bar_h, x0 - 1 : x0 + bar_w + 1] = 200
        if self.cfg.color_by == "speed":
            lo, hi = 0.0, self.cfg.speed_range
        else:
            lo, hi = self.cfg.temperature_range
        draw_text(img, f"{lo:g}", x0, y0 + bar_h + 3, scale)
        label = f"{hi:g}"
        draw_text(img, label, x0 + bar_w - 4 * scale * len(label), y0 + bar_h + 3, scale)


@ti.func
def _add(layer: ti.template(), x, y, value, plain: ti.template()):
    """layer[x, y] += value: by a plain load and store when `plain` (no other thread writes that pixel meanwhile),
    else atomically (on the CPU a float atomic add is a compare-and-swap loop)."""
    if ti.static(plain):
        layer[x, y] = layer[x, y] + value
    else:
        layer[x, y] += value
