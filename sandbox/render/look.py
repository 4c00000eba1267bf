"""How a particle looks: its colour (by temperature or speed: the colour bar's map, so that the bar reads a
particle's value back; by material or phase: the materials' colours), its drawn radius and opacity, fading
and shrinking over a lifetime, and each body's drawing style.

Every body (particle group) has a drawing style: `draw` (dot: one pixel; splat: a disc of the particle's radius;
sphere: a shaded sphere in 3D) and `blend` (opaque; alpha: translucent; additive: emits light, absorbs none). The
spawn tool's particles, the last group, are splats (spheres in 3D), opaque.
"""

import numpy as np
import taichi as ti

from ..core import transfer
from ..core.oriented import data_oriented
from .colormaps import speed_map, temperature_map
from .style import BLEND, COLOR_MODES, DRAW

VAPOUR_COLOR = (0.9, 0.9, 0.9)  # drawing by phase: a boiling material's vapour
# drawing by phase in the molecular model: gas, liquid, solid as physics/structure.py counts them
STRUCTURE_COLORS = ((0.85, 0.85, 0.85), (0.2, 0.5, 0.95), (0.95, 0.75, 0.3))
STRUCTURE_WORDS = ("gas", "liquid", "solid")


@data_oriented
class Look:
    """Colours, sizes and opacities of the particles of `state` (its `model` for materials and the phase law), with
    the [render] settings `cfg`."""

    def __init__(self, model, state, cfg):
        self.model, self.p = model, state.particles
        bodies = model.scene.groups  # every body, then every emitter, then (last) the spawn tool's particles
        self.n_groups = len(bodies) + 1
        self.g_draw = ti.field(ti.i32, shape=self.n_groups)
        self.g_blend = ti.field(ti.i32, shape=self.n_groups)
        self.g_opacity = ti.field(ti.f32, shape=self.n_groups)
        self.g_fade = ti.field(ti.i32, shape=self.n_groups)  # colour fades over the lifetime
        self.g_shrink = ti.field(ti.i32, shape=self.n_groups)  # drawn radius shrinks over the lifetime
        draw = [DRAW[b.draw] for b in bodies] + [DRAW["splat" if model.dim == 2 else "sphere"]]  # + the spawn tool's
        self.blend_table = np.array([BLEND[b.blend] for b in bodies] + [BLEND["opaque"]], np.int32)
        transfer.upload(
            [
                (self.g_fade, np.array([int(getattr(b, "fade", False)) for b in bodies], np.int32)),
                (self.g_shrink, np.array([int(getattr(b, "shrink", False)) for b in bodies], np.int32)),
                (self.g_draw, np.array(draw, np.int32)),
                (self.g_blend, self.blend_table),
                (self.g_opacity, np.array([b.opacity for b in bodies] + [1.0], np.float32)),
            ]
        )
        self.blends = {b.blend for b in bodies} | ({"opaque"} if model.scene.palette else set())
        self.has_lifetimes = self.p.lifetimes
        self.has_heat = self.p.heat
        self.color_mode = COLOR_MODES[cfg.color_by]
        self.t_lo = ti.field(ti.f32, shape=())
        self.t_hi = ti.field(ti.f32, shape=())
        self.speed_hi = ti.field(ti.f32, shape=())
        t_lo, t_hi = cfg.temperature_range
        transfer.upload([(self.t_lo, t_lo), (self.t_hi, t_hi), (self.speed_hi, cfg.speed_range)])
        self.particle_scale = float(cfg.particle_scale)
        self.boils = self.has_heat and any(m.boils for m in model.material_list)
        self.has_structure = self.p.structure  # the molecular model: phases measured from structure

    @ti.func
    def life_left(self, i):
        """1 at birth falling to 0 at death for particles with a lifetime, else 1."""
        left = 1.0
        if ti.static(self.has_lifetimes):
            life = self.p.lifetime[i]
            if life > 0.0:
                left = ti.max(1.0 - self.p.age[i] / life, 0.0)
        return left

    @ti.func
    def drawn_radius(self, i):
        """Drawn radius (length): the particle's radius times render.particle_scale, shrinking with age if asked."""
        r = self.p.radius[i] * self.particle_scale
        if ti.static(self.has_lifetimes):
            if self.g_shrink[self.p.group[i]]:
                r *= self.life_left(i)
        return r

    @ti.func
    def color(self, i):
        """Drawing colour: the colour map's, darkened over the lifetime when fading (not for alpha: see opacity)."""
        c = self._base_color(i)
        if ti.static(self.has_lifetimes):
            g = self.p.group[i]
            if self.g_fade[g] and self.g_blend[g] != BLEND["alpha"]:
                c *= self.life_left(i)
        return c

    @ti.func
    def opacity(self, i):
        """Opacity of particle i's group; a fading translucent particle grows fainter rather than darker."""
        g = self.p.group[i]
        a = self.g_opacity[g]
        if ti.static(self.has_lifetimes):
            if self.g_fade[g] and self.g_blend[g] == BLEND["alpha"]:
                a *= self.life_left(i)
        return a

    @ti.func
    def _base_color(self, i):
        p = self.p
        base = p.color[i]
        c = base
        if ti.static(self.color_mode == 0 and self.has_heat):  # the colour bar's map, whatever the material
            c = temperature_map((p.T[i] - self.t_lo[None]) / (self.t_hi[None] - self.t_lo[None]))
        elif ti.static(self.color_mode == 2):
            c = speed_map(p.v[i].norm() / self.speed_hi[None])
        elif ti.static(self.color_mode == 3 and self.has_heat):
            phi = self.model.phase.fraction(p.h[i], p.material[i])
            c = (1.0 - phi) * base + phi * self.model.materials.liquid_color[p.material[i]]
            if ti.static(self.boils):  # vapour: pale grey, mixed in by the gas fraction
                psi = self.model.phase.gas(p.h[i], p.material[i])
                c = (1.0 - psi) * c + psi * ti.Vector(VAPOUR_COLOR)
        elif ti.static(self.color_mode == 3 and self.has_structure):
            kind = p.kind[i]
            c = ti.Vector(STRUCTURE_COLORS[0])
            if kind == 1:
                c = ti.Vector(STRUCTURE_COLORS[1])
            elif kind == 2:
                c = ti.Vector(STRUCTURE_COLORS[2])
        return c
