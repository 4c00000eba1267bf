"""The particle renderer: Taichi kernels splat particles into a float RGB image field, then pack it to 8-bit.

2D: an orthographic view of the whole domain (fitted, centred), each particle an anti-aliased disc whose edge
coverage is clamp(R + 0.5 - distance, 0, 1); overlapping discs blend by coverage-weighted averaging, which is
order-independent. Heat sources are drawn as rectangles in their glow colour, the domain as a faint frame.
3D: a perspective camera; each particle is a shaded sphere impostor (ambient + diffuse + specular), with a depth
buffer (integer atomic min of the depth bits) so the nearest sphere wins each pixel.
The image field is W x H with y up (Taichi's and GGUI's convention); `frame()` returns H x W x 3 uint8, top row
first, copied to the host once.
"""

import math

import numpy as np
import taichi as ti

from .colormaps import glow, glow_over_base, speed_map

COLOR_MODES = {"temperature": 0, "material": 1, "speed": 2, "phase": 3}


@ti.data_oriented
class Renderer:
    """Draws a Simulation's particles into `self.image` (W x H RGB floats)."""

    def __init__(self, sim, width: int, height: int, render_cfg):
        self.sim = sim
        self.cfg = render_cfg
        self.width, self.height = width, height
        self.dim = sim.dim
        self.image = ti.Vector.field(3, ti.f32, shape=(width, height))  # linear RGB in [0, 1]
        self.accum = ti.Vector.field(3, ti.f32, shape=(width, height))  # coverage-weighted colour sum (2D)
        self.weight = ti.field(ti.f32, shape=(width, height))  # coverage sum (2D)
        self.depth = ti.field(ti.i32, shape=(width, height))  # depth bits of the nearest surface (3D)
        self.packed = ti.field(ti.u8, shape=(height, width, 3))  # 8-bit output, top row first
        self.color_mode = COLOR_MODES[render_cfg.color_by]
        self.t_lo = ti.field(ti.f32, shape=())
        self.t_hi = ti.field(ti.f32, shape=())
        self.t_lo[None], self.t_hi[None] = render_cfg.temperature_range
        self.speed_hi = ti.field(ti.f32, shape=())
        self.speed_hi[None] = render_cfg.speed_range
        self.background = ti.Vector(list(render_cfg.background))
        self.particle_scale = float(render_cfg.particle_scale)
        self.has_heat = sim.heat is not None
        self._setup_view()

    # ------------------------------------------------------------------ view
    def _setup_view(self):
        lo, hi = np.asarray(self.sim.scene.world.lo), np.asarray(self.sim.scene.world.hi)
        if self.dim == 2:
            extent = hi - lo
            scale = min(self.width / extent[0], self.height / extent[1]) * 0.98
            self.px_per_unit = float(scale)
            centre_px = np.array([self.width, self.height]) / 2
            self.offset = ti.Vector(list(centre_px - scale * (lo + hi) / 2))
            self.px_lo = ti.Vector(list(centre_px - scale * extent / 2))
            self.px_hi = ti.Vector(list(centre_px + scale * extent / 2))
            src = self.sim.scene.heat.sources if self.sim.scene.heat else []
            self.n_src = len(src)
            ns = max(self.n_src, 1)
            self.src_lo = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_hi = ti.Vector.field(2, ti.f32, shape=ns)
            self.src_t = ti.field(ti.f32, shape=ns)
            for k, s in enumerate(src):
                self.src_lo[k] = centre_px + scale * (np.asarray(s.lo) - (lo + hi) / 2)
                self.src_hi[k] = centre_px + scale * (np.asarray(s.hi) - (lo + hi) / 2)
                self.src_t[k] = s.temperature
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
            self.light = ti.Vector(list(light / np.linalg.norm(light)))

    def set_camera(self, eye, target, fov_degrees: float) -> None:
        """3D: place the camera (world units) looking at target with a vertical field of view in degrees."""
        eye, target = np.asarray(eye, dtype=float), np.asarray(target, dtype=float)
        fwd = target - eye
        fwd /= np.linalg.norm(fwd)
        up = np.array([0.0, 1.0, 0.0])
        right = np.cross(fwd, up)
        if np.linalg.norm(right) < 1e-6:
            right = np.array([1.0, 0.0, 0.0])
        right /= np.linalg.norm(right)
        true_up = np.cross(right, fwd)
        self.cam_eye = ti.Vector(list(eye))
        self.cam_right = ti.Vector(list(right))
        self.cam_up = ti.Vector(list(true_up))
        self.cam_fwd = ti.Vector(list(fwd))
        self.focal = 0.5 * self.height / math.tan(math.radians(fov_degrees) / 2)

    # ------------------------------------------------------------------ drawing
    def render(self) -> None:
        """Draw the current state into self.image."""
        if self.dim == 2:
            self._clear_2d()
            self._splat_2d()
            self._resolve_2d()
        else:
            self._clear_3d()
            self._depth_3d()
            self._shade_3d()

    def frame(self) -> np.ndarray:
        """Render and return the picture as an (H, W, 3) uint8 array, top row first."""
        self.render()
        self._pack()
        return self.packed.to_numpy()

    @ti.func
    def particle_color(self, i):
        p = self.sim.particles
        base = p.color[i]
        c = base
        if ti.static(self.color_mode == 0 and self.has_heat):
            t = (p.T[i] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
            c = glow_over_base(base, t)
        elif ti.static(self.color_mode == 2):
            c = speed_map(p.v[i].norm() / self.speed_hi[None])
        elif ti.static(self.color_mode == 3 and self.has_heat):
            if p.T[i] >= self.sim.materials.melt[p.material[i]]:
                c = ti.Vector([1.0, 0.45, 0.1])
        return c

    @ti.kernel
    def _clear_2d(self):
        for x, y in self.image:
            self.accum[x, y] = ti.Vector([0.0, 0.0, 0.0])
            self.weight[x, y] = 0.0
            pix = ti.Vector([x + 0.5, y + 0.5])
            c = self.background
            inside = (
                pix[0] >= self.px_lo[0]
                and pix[0] <= self.px_hi[0]
                and pix[1] >= self.px_lo[1]
                and pix[1] <= self.px_hi[1]
            )
            if not inside:
                c = self.background * 0.6
            for k in range(self.n_src):
                if (
                    pix[0] >= self.src_lo[k][0] - 1
                    and pix[0] <= self.src_hi[k][0] + 1
                    and pix[1] >= self.src_lo[k][1] - 2
                    and pix[1] <= self.src_hi[k][1] + 1
                ):
                    t = (self.src_t[k] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None])
                    c = glow(ti.max(t, 0.35)) if t > 0.05 else ti.Vector([0.3, 0.55, 1.0])
            self.image[x, y] = c

    @ti.kernel
    def _splat_2d(self):
        p = self.sim.particles
        for i in range(p.n[None]):
            centre = p.x[i] * self.px_per_unit + self.offset
            r = ti.max(p.radius[i] * self.px_per_unit * self.particle_scale, 0.5)
            col = self.particle_color(i)
            x0 = ti.max(ti.cast(ti.floor(centre[0] - r - 1), ti.i32), 0)
            x1 = ti.min(ti.cast(ti.ceil(centre[0] + r + 1), ti.i32), self.width - 1)
            y0 = ti.max(ti.cast(ti.floor(centre[1] - r - 1), ti.i32), 0)
            y1 = ti.min(ti.cast(ti.ceil(centre[1] + r + 1), ti.i32), self.height - 1)
            for px in range(x0, x1 + 1):
                for py in range(y0, y1 + 1):
                    d = (ti.Vector([px + 0.5, py + 0.5]) - centre).norm()
                    cov = ti.math.clamp(r + 0.5 - d, 0.0, 1.0)
                    if cov > 0.0:
                        self.accum[px, py] += cov * col
                        self.weight[px, py] += cov

    @ti.kernel
    def _resolve_2d(self):
        for x, y in self.image:
            w = self.weight[x, y]
            if w > 0.0:
                a = ti.min(w, 1.0)
                self.image[x, y] = self.image[x, y] * (1.0 - a) + self.accum[x, y] / w * a

    @ti.kernel
    def _clear_3d(self):
        for x, y in self.image:
            shade = 0.75 + 0.25 * y / self.height
            self.image[x, y] = self.background * shade
            self.depth[x, y] = 2147483647

    @ti.func
    def _project(self, pos):
        rel = pos - self.cam_eye
        z = rel.dot(self.cam_fwd)
        sx = self.width * 0.5 + self.focal * rel.dot(self.cam_right) / ti.max(z, 1e-6)
        sy = self.height * 0.5 + self.focal * rel.dot(self.cam_up) / ti.max(z, 1e-6)
        return ti.Vector([sx, sy]), z

    @ti.kernel
    def _depth_3d(self):
        p = self.sim.particles
        for i in range(p.n[None]):
            centre, z = self._project(p.x[i])
            if z > 1e-3:
                rad = p.radius[i] * self.particle_scale
                r = ti.max(rad * self.focal / z, 0.7)
                x0 = ti.max(ti.cast(ti.floor(centre[0] - r), ti.i32), 0)
                x1 = ti.min(ti.cast(ti.ceil(centre[0] + r), ti.i32), self.width - 1)
                y0 = ti.max(ti.cast(ti.floor(centre[1] - r), ti.i32), 0)
                y1 = ti.min(ti.cast(ti.ceil(centre[1] + r), ti.i32), self.height - 1)
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
            centre, z = self._project(p.x[i])
            if z > 1e-3:
                rad = p.radius[i] * self.particle_scale
                r = ti.max(rad * self.focal / z, 0.7)
                col = self.particle_color(i)
                x0 = ti.max(ti.cast(ti.floor(centre[0] - r), ti.i32), 0)
                x1 = ti.min(ti.cast(ti.ceil(centre[0] + r), ti.i32), self.width - 1)
                y0 = ti.max(ti.cast(ti.floor(centre[1] - r), ti.i32), 0)
                y1 = ti.min(ti.cast(ti.ceil(centre[1] + r), ti.i32), self.height - 1)
                for px in range(x0, x1 + 1):
                    for py in range(y0, y1 + 1):
                        u = (ti.Vector([px + 0.5, py + 0.5]) - centre) / r
                        q = u.dot(u)
                        if q <= 1.0:
                            zs = z - rad * ti.sqrt(1.0 - q)
                            bits = ti.bit_cast(ti.cast(ti.max(zs, 0.0), ti.f32), ti.i32)
                            if bits == self.depth[px, py]:
                                nz = ti.sqrt(1.0 - q)
                                normal = u[0] * self.cam_right + u[1] * self.cam_up - nz * self.cam_fwd
                                diffuse = ti.max(normal.dot(self.light), 0.0)
                                half = (self.light - self.cam_fwd).normalized()
                                spec = ti.max(normal.dot(half), 0.0) ** 32
                                self.image[px, py] = col * (0.3 + 0.7 * diffuse) + 0.25 * spec

    @ti.kernel
    def _pack(self):
        for x, y in self.image:
            c = self.image[x, y]
            for k in ti.static(range(3)):
                self.packed[self.height - 1 - y, x, k] = ti.cast(ti.math.clamp(c[k], 0.0, 1.0) * 255.0 + 0.5, ti.u8)
