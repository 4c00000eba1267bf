"""3D drawing: projection, shaded opaque spheres with a depth buffer, translucent particles sorted and composited
back to front, motion-blur ghosts of opaque spheres, and depth-tested additive light. A mixin of Renderer."""

import math

import numpy as np
import taichi as ti

from .colormaps import glow
from .style import BLEND, R_MIN


class Spheres3D:
    """Renderer's 3D passes."""

    # ------------------------------------------------------------------ 3D
    @ti.func
    def _project(self, pos):
        rel = ti.cast(pos, ti.f32) - self.camera[0]
        z = rel.dot(self.camera[3])
        sx = self.cx + self.focal_field[None] * rel.dot(self.camera[1]) / ti.max(z, 1e-6)
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
                    + self.camera[1] * (x + 0.5 - self.cx)
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

    @ti.func
    def _sphere_disc(self, i, z):
        """Particle i at camera depth z: its drawn radius (world) and the radius of its disc on screen (px)."""
        rad = self.drawn_radius(i)
        return rad, ti.max(rad * self.focal_field[None] / z, R_MIN)

    @ti.func
    def _on_disc(self, centre, r, px, py):
        """Pixel (px, py) against a disc of radius r (px) at centre: the offset u in radii and q = |u|^2 (on the
        disc when q <= 1)."""
        u = (ti.Vector([px + 0.5, py + 0.5]) - centre) / r
        return u, u.dot(u)

    @ti.func
    def _surface_depth_key(self, z, rad, q):
        """The depth of a sphere's front surface where the disc's q (<= 1) is, as the depth buffer's i32 key."""
        zs = z - rad * ti.sqrt(1.0 - q)
        return ti.bit_cast(ti.cast(ti.max(zs, 0.0), ti.f32), ti.i32)

    @ti.kernel
    def _depth_3d(self):
        p = self.p
        for i in range(p.n[None]):
            if self.g_blend[p.group[i]] == 0:
                centre, z = self._project(p.x[i])
                if z > 1e-3:
                    rad, r = self._sphere_disc(i, z)
                    x0, x1, y0, y1 = self._box(centre, centre, r, centre)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            _, q = self._on_disc(centre, r, px, py)
                            if q <= 1.0:
                                ti.atomic_min(self.depth[px, py], self._surface_depth_key(z, rad, q))

    @ti.kernel
    def _shade_3d(self):
        p = self.p
        for i in range(p.n[None]):
            g = p.group[i]
            if self.g_blend[g] == 0:
                centre, z = self._project(p.x[i])
                if z > 1e-3:
                    rad, r = self._sphere_disc(i, z)
                    col = self.particle_color(i)
                    shaded = self.g_draw[g] == 2
                    x0, x1, y0, y1 = self._box(centre, centre, r, centre)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            u, q = self._on_disc(centre, r, px, py)
                            if q <= 1.0:
                                if self._surface_depth_key(z, rad, q) == self.depth[px, py]:
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
        head, z = self._project(self.p.x[i])
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
        p = self.p
        for i in range(p.n[None]):
            g = p.group[i]
            if self.g_blend[g] == 0:
                tail, ctrl, head, z_tail, z, blurred = self._streak_3d(i)
                if blurred and (tail - head).norm() > 0.5:  # moved half a pixel or more
                    _, r = self._sphere_disc(i, z)
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
        n = int(self.p.n[None])
        x = self.p.x.to_numpy()[:n]
        group = self.p.group.to_numpy()[:n]
        blend = self.g_blend.to_numpy()
        ids = np.flatnonzero(blend[group] == BLEND["alpha"])
        depth = (x[ids] - self.eye_np) @ self.fwd_np
        order = ids[np.argsort(-depth, kind="stable")].astype(np.int32)
        full = np.zeros(self.model.capacity, dtype=np.int32)
        full[: len(order)] = order
        self.order.from_numpy(full)
        self.n_order[None] = len(order)

    @ti.kernel
    def _composite_translucent(self):
        p = self.p
        ti.loop_config(serialize=True)  # "over" compositing must follow the back-to-front order
        for k in range(self.n_order[None]):
            i = self.order[k]
            centre, z = self._project(p.x[i])
            if z > 1e-3:
                _, r = self._sphere_disc(i, z)
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
        p = self.p
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
