"""3D drawing: the camera (a pinhole the window can orbit without recompiling), shaded opaque spheres with a depth
buffer (an integer atomic min of the depth bits), translucent particles sorted back to front on the host and
composited "over" in that order by a serial kernel with the depth test, motion-blur ghosts of opaque spheres, and
depth-tested additive light.

With motion blur, additive particles become streaks of light, and opaque spheres stay solid where they are and leave
a translucent streak back to where they were, depth-tested along its length and composited like 2D's translucent
particles (translucent 3D particles are drawn unblurred).
"""

import math

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from ..core.worlds import at
from .camera import default_eye, look_at
from .colormaps import temperature_map
from .flat import source_table
from .style import BLEND, LID_COLOR, R_MIN


@data_oriented
class Spheres3D:
    """Draws the particles of a 3D scene onto `canvas` through a camera; `axis` (pixels, y up) is where the view's
    axis meets the picture (the middle of the part below the top band, right of a side panel); by default the
    camera looks at the middle of `view_box` (world lo, hi: the content, layout.content_box) from where it fits."""

    def __init__(self, canvas, footprint, look, model, state, cfg, axis: tuple[float, float], view_box):
        self.canvas, self.footprint, self.look = canvas, footprint, look
        self.model, self.p = model, state.particles
        self.cx, self.cy = float(axis[0]), float(axis[1])
        self.background = ti.Vector(list(cfg.background))
        lo, hi = np.asarray(model.scene.world.lo), np.asarray(model.scene.world.hi)
        centre = (np.asarray(view_box[0]) + np.asarray(view_box[1])) / 2
        target = np.asarray(cfg.camera_target) if cfg.camera_target else centre
        room = canvas.height / max(2 * self.cy, 1.0)  # back off as far as the band above takes rows from the view
        eye = np.asarray(cfg.camera_position) if cfg.camera_position else default_eye(view_box, room)
        # fields, not compile-time constants, so the window can orbit without recompiling
        self.camera = ti.Vector.field(3, ti.f32, shape=4)  # eye, right, up, forward
        self.focal_field = ti.field(ti.f32, shape=())  # pixels: focal length of the pinhole
        self.set_camera(eye, target, cfg.fov)
        light = np.asarray(cfg.light_direction, dtype=float)
        self.light_np = light / np.linalg.norm(light)  # unit vector towards the light (world)
        self.light_dir = ti.Vector(list(self.light_np))
        self.specular = float(cfg.specular)
        self.ground = bool(cfg.ground)
        self.floor_y = float(lo[1])
        self.floor_box = (float(lo[0]), float(lo[2]), float(hi[0]), float(hi[2]))  # x0, z0, x1, z1 (world)
        self.floor_lo, self.floor_hi = ti.Vector(self.floor_box[:2]), ti.Vector(self.floor_box[2:])
        self.grid_step = float(max(1.0, round(max(hi[0] - lo[0], hi[2] - lo[2]) / 12)))
        # heat sources lying on the floor are drawn on it in the colour bar's colour for their temperature
        heat = model.scene.heat
        sources = [s for s in (heat.sources if heat else []) if s.lo[1] <= lo[1] + 1 and s.visible]
        self.n_src = len(sources)
        table = source_table(cfg, sources, [[s.lo[0], s.lo[2]] for s in sources], [[s.hi[0], s.hi[2]] for s in sources])
        (self.src_lo, _), (self.src_hi, _), (self.src_t, _) = table
        transfer.upload(table)
        # the molecular model's lid (physics/lid.py): its outline drawn at its height, in front of what lies behind it
        lid = state.entry("lid.height")
        self.lid = lid.owner if lid is not None else None  # its height: world 0's where there are many
        self.has_lid = lid is not None
        if canvas.has_alpha:
            self.order = ti.field(ti.i32, shape=model.capacity)  # translucent particles, back to front
            self.n_order = ti.field(ti.i32, shape=())

    def set_camera(self, eye, target, fov_degrees: float) -> None:
        """Place the camera (world units) looking at target with a vertical field of view in degrees."""
        eye, target = np.asarray(eye, dtype=float), np.asarray(target, dtype=float)
        right, true_up, fwd = look_at(eye, target)
        self.eye_np, self.fwd_np, self.target_np = eye, fwd, target
        self.right_np, self.up_np = right, true_up
        focal = 0.5 * self.canvas.height / math.tan(math.radians(fov_degrees) / 2)
        transfer.upload([(self.camera, np.array([eye, right, true_up, fwd], np.float32)), (self.focal_field, focal)])
        self.fov = float(fov_degrees)

    def paint_backdrop(self, lid: bool = True) -> None:
        """The picture without particles into the image: the background, the floor and its heat sources, and
        (with `lid`) the lid."""
        self._clear_3d(int(lid))

    def draw(self) -> None:
        """Every 3D pass, into the image."""
        canvas = self.canvas
        self._clear_3d(1)
        if canvas.has_opaque:
            self._depth_3d()
            self._shade_3d()
            if self.footprint.motion_blur:
                self._ghosts_3d()
                self._resolve_ghosts_3d()
        if canvas.has_alpha:
            self._sort_translucent()
            self._composite_translucent()
        if canvas.has_additive:
            self._light_3d()
            canvas.tone_map()

    def pick_index(self, x: np.ndarray, u: float, v: float, reach_px: float = 12.0) -> int | None:
        """Of the 3D positions x (N, 3), the index of the nearest drawn within reach_px pixels of the picture point
        (u, v) (fractions of width and height from the bottom left, as GGUI's cursor), or None."""
        if len(x) == 0:
            return None
        width, height = self.canvas.width, self.canvas.height
        rel = x - self.eye_np
        z = rel @ self.fwd_np
        focal = 0.5 * height / math.tan(math.radians(self.fov) / 2)
        front = z > 1e-6
        sx = self.cx + focal * (rel @ self.right_np) / np.where(front, z, 1.0)
        sy = self.cy + focal * (rel @ self.up_np) / np.where(front, z, 1.0)
        near = front & ((sx - u * width) ** 2 + (sy - v * height) ** 2 <= reach_px**2)
        if not near.any():
            return None
        candidates = np.flatnonzero(near)
        return int(candidates[np.argmin(z[candidates])])

    @ti.func
    def _project(self, pos):
        rel = ti.cast(pos, ti.f32) - self.camera[0]
        z = rel.dot(self.camera[3])
        sx = self.cx + self.focal_field[None] * rel.dot(self.camera[1]) / ti.max(z, 1e-6)
        sy = self.cy + self.focal_field[None] * rel.dot(self.camera[2]) / ti.max(z, 1e-6)
        return ti.Vector([sx, sy]), z

    @ti.kernel
    def _clear_3d(self, lid: ti.i32):
        canvas = self.canvas
        for x, y in canvas.image:
            shade = 0.75 + 0.25 * y / canvas.height
            c = self.background * shade
            if ti.static(self.ground):
                # the floor plane y = floor_y, with a faint grid so depth reads
                ray = (
                    self.camera[3] * self.focal_field[None]
                    + self.camera[1] * (x + 0.5 - self.cx)
                    + self.camera[2] * (y + 0.5 - self.cy)
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
                                t = (self.src_t[k] - self.look.t_lo[None]) / (
                                    self.look.t_hi[None] - self.look.t_lo[None]
                                )
                                c = c * 0.6 + 0.3 * (temperature_map(ti.math.clamp(t, 0.0, 1.0)))
            depth = 2147483647
            if ti.static(self.has_lid):
                if lid:  # 0: for a page that draws the lid itself (render/sphere_frame.py)
                    c, depth = self._lid(x, y, c, depth)
            canvas.image[x, y] = c
            canvas.depth[x, y] = depth
            if ti.static(canvas.has_additive):
                canvas.light[x, y] = ti.Vector([0.0, 0.0, 0.0])

    @ti.func
    def _lid(self, x, y, c, depth):
        """Pixel (x, y) of the lid at its height: a faint tint over the box's cross-section and its outline, which
        keeps the depth of the lid (an atom behind the lid's edge is hidden by it, one in front draws over it)."""
        ray = (
            self.camera[3] * self.focal_field[None]
            + self.camera[1] * (x + 0.5 - self.cx)
            + self.camera[2] * (y + 0.5 - self.cy)
        ).normalized()
        height = ti.cast(at(self.lid.height, 0), ti.f32)
        if ti.abs(ray[1]) > 1e-6:
            s = (height - self.camera[0][1]) / ray[1]
            if s > 0.0:
                hit = self.camera[0] + s * ray
                u = ti.Vector([hit[0], hit[2]])
                if (u >= self.floor_lo).all() and (u <= self.floor_hi).all():
                    edge = ti.min((u - self.floor_lo).min(), (self.floor_hi - u).min())
                    pixel_size = s / self.focal_field[None]
                    c = c * 0.85 + 0.1
                    if edge < 1.5 * pixel_size:
                        c = ti.Vector(LID_COLOR)
                        depth = ti.bit_cast(s * ray.dot(self.camera[3]), ti.i32)
        return c, depth

    @ti.func
    def _sphere_disc(self, i, z):
        """Particle i at camera depth z: its drawn radius (world) and the radius of its disc on screen (px)."""
        rad = self.look.drawn_radius(i)
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
            if p.idle(i):
                continue
            if self.look.g_blend[p.group[i]] == 0:
                centre, z = self._project(p.x[i])
                if z > 1e-3:
                    rad, r = self._sphere_disc(i, z)
                    x0, x1, y0, y1 = self.canvas.box(centre, centre, r, centre)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            _, q = self._on_disc(centre, r, px, py)
                            if q <= 1.0:
                                ti.atomic_min(self.canvas.depth[px, py], self._surface_depth_key(z, rad, q))

    @ti.kernel
    def _shade_3d(self):
        p = self.p
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            g = p.group[i]
            if self.look.g_blend[g] == 0:
                centre, z = self._project(p.x[i])
                if z > 1e-3:
                    rad, r = self._sphere_disc(i, z)
                    col = self.look.color(i)
                    shaded = self.look.g_draw[g] == 2
                    x0, x1, y0, y1 = self.canvas.box(centre, centre, r, centre)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            u, q = self._on_disc(centre, r, px, py)
                            if q <= 1.0:
                                if self._surface_depth_key(z, rad, q) == self.canvas.depth[px, py]:
                                    c = col
                                    if shaded:
                                        nz = ti.sqrt(1.0 - q)
                                        normal = u[0] * self.camera[1] + u[1] * self.camera[2] - nz * self.camera[3]
                                        diffuse = ti.max(normal.dot(self.light_dir), 0.0)
                                        half = (self.light_dir - self.camera[3]).normalized()
                                        spec = ti.max(normal.dot(half), 0.0) ** 32
                                        c = col * (0.3 + 0.7 * diffuse) + self.specular * spec
                                    self.canvas.image[px, py] = c

    @ti.func
    def _streak_3d(self, i):
        """(tail, control point, head) in pixels of particle i's motion-blur streak, the depths of its tail and
        head, and whether it is drawn as a streak: motion blur on, all three points in front of the camera, moved
        over 1e-3 px and not across a periodic wrap. Otherwise tail and control point are the head."""
        head, z = self._project(self.p.x[i])
        tail, ctrl, z_tail = head, head, z
        blurred = False
        if ti.static(self.footprint.motion_blur):
            prev, zp = self._project(self.footprint.x_prev[i])
            mid, zm = 0.5 * (prev + head), zp
            if ti.static(self.footprint.spline):
                mid, zm = self._project(self.footprint.x_mid[i])
            if z > 1e-3 and zp > 1e-3 and zm > 1e-3 and self.footprint.has_tail(i):
                t, c, _ = self.footprint.streak(prev, mid, head)
                span = ti.max((t - head).norm(), (mid - head).norm())
                if (t - head).norm() > 1e-3 and span < 0.5 * self.canvas.width:
                    tail, ctrl, z_tail = t, c, z + self.footprint.shutter * (zp - z)
                    blurred = True
        return tail, ctrl, head, z_tail, z, blurred

    @ti.kernel
    def _ghosts_3d(self):
        """Motion blur of opaque spheres: a streak from where each was a shutter ago to where it is, its opacity
        falling towards the tail, depth-tested at its depth along the way (so the sphere itself, in front of the
        streak's head, stays solid, and nearer spheres hide it)."""
        p = self.p
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            g = p.group[i]
            if self.look.g_blend[g] == 0:
                tail, ctrl, head, z_tail, z, blurred = self._streak_3d(i)
                if blurred and (tail - head).norm() > 0.5:  # moved half a pixel or more
                    _, r = self._sphere_disc(i, z)
                    col = self.look.color(i)
                    if self.look.g_draw[g] == 2:  # the shade of the sphere's centre, facing the camera
                        col = col * (0.3 + 0.7 * ti.max(-self.camera[3].dot(self.light_dir), 0.0))
                    opacity = self.look.g_opacity[g]
                    x0, x1, y0, y1 = self.canvas.box(tail, head, r, ctrl)
                    for px in range(x0, x1 + 1):
                        for py in range(y0, y1 + 1):
                            w, t = self.footprint.coverage(ti.Vector([px + 0.5, py + 0.5]), tail, ctrl, head, r, True)
                            zbits = ti.bit_cast(ti.cast(z_tail + t * (z - z_tail), ti.f32), ti.i32)
                            if w > 0.0 and zbits <= self.canvas.depth[px, py]:
                                a = ti.min(w * opacity, 0.999)
                                self.canvas.a_accum[px, py] += a * col
                                self.canvas.a_weight[px, py] += a
                                self.canvas.a_log[px, py] += ti.log(1.0 - a)

    @ti.kernel
    def _resolve_ghosts_3d(self):
        canvas = self.canvas
        for x, y in canvas.image:
            canvas.image[x, y] = canvas.over_translucent(x, y, canvas.image[x, y])

    def _sort_translucent(self) -> None:
        """Order the translucent particles back to front (by distance along the view direction), on the host."""
        n = int(self.p.n[None])
        x = self.p.x.to_numpy()[:n]
        group = self.p.group.to_numpy()[:n]
        ids = np.flatnonzero(self.look.blend_table[group] == BLEND["alpha"])
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
                col = self.look.color(i)
                opacity = self.look.opacity(i)
                zbits = ti.bit_cast(ti.cast(z, ti.f32), ti.i32)
                x0, x1, y0, y1 = self.canvas.box(centre, centre, r, centre)
                for px in range(x0, x1 + 1):
                    for py in range(y0, y1 + 1):
                        w = self.footprint.weight(ti.Vector([px + 0.5, py + 0.5]), centre, centre, centre, r, False)
                        if w > 0.0 and zbits <= self.canvas.depth[px, py]:
                            a = ti.min(w * opacity, 1.0)
                            self.canvas.image[px, py] = self.canvas.image[px, py] * (1.0 - a) + col * a

    @ti.kernel
    def _light_3d(self):
        p = self.p
        for i in range(p.n[None]):
            if p.idle(i):
                continue
            g = p.group[i]
            if self.look.g_blend[g] == 2:
                tail, ctrl, head, _, z, blurred = self._streak_3d(i)
                if z > 1e-3:
                    r_true = self.look.drawn_radius(i) * self.focal_field[None] / z
                    if self.look.g_draw[g] == 0:
                        r_true = 0.5
                    r = ti.max(r_true, R_MIN)
                    energy = self.look.g_opacity[g] * math.pi * r_true * r_true
                    self.footprint.deposit_light(tail, ctrl, head, r, energy, self.look.color(i), blurred, True, z)
