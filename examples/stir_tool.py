"""A tool added from outside the package, as docs/architecture.md's "Adding a tool" shows: one kernel and one
`register(Tool(...))`. Importing this module adds "stir" to every front-end (the window's Tab and help, the
classroom page's tool list, the controller): it swirls the particles under the brush counter-clockwise about the
cursor, fastest halfway to the brush's edge. tests/test_controller.py imports it."""

import taichi as ti

from sandbox.app.tool_table import Tool, register

SWIRL_SPEED = 40.0  # added tangential speed per second at full strength (length / time per time)


@ti.kernel
def swirl(x: ti.template(), v: ti.template(), n: ti.i32, cx: float, cy: float, radius: float, dv: float):
    """Turn velocities counter-clockwise about (cx, cy) in the x-y plane: up to dv, zero at the centre and edge."""
    for i in range(n):
        dx, dy = x[i][0] - cx, x[i][1] - cy
        r = ti.sqrt(dx * dx + dy * dy)
        if 1e-9 < r < radius:
            w = 1.0 - ti.abs(2.0 * r / radius - 1.0)
            v[i][0] += -dv * w * dy / r
            v[i][1] += dv * w * dx / r


def stir(tools, centre, radius: float, dt: float, strength: float, material) -> None:
    """One frame of `dt` seconds of the stir tool held at `centre` (scene units) with `radius`."""
    p = tools.sim.state.particles
    swirl(p.x, p.v, int(p.n[None]), float(centre[0]), float(centre[1]), float(radius), SWIRL_SPEED * strength * dt)


STIR = register(Tool("stir", stir))
