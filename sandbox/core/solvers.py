"""The host side of preconditioned conjugate gradients, shared by the implicit mechanical and heat steppers and the
smoke projection.

The caller owns the Taichi kernels; each adds the sums it computes into a CGSums: p.Ap (matvec), r.z and r.r
(update; also set by assemble) and b.b (assemble). Two host reads per iteration are the price of not running the
loop on the device.
"""

from collections.abc import Callable
from dataclasses import dataclass

import taichi as ti

from .oriented import data_oriented


@dataclass
class CGResult:
    iterations: int
    relative_residual: float


@data_oriented
class CGSums:
    """The sums of a CG iteration, a 0-d f64 field each (kernels add with `sums.rr[None] += ...`). Taichi adds into
    a 0-d field per thread and once per thread at a parallel loop's end, where `scalars[k] += ...` on one field of
    four is a contended atomic per item: a sum over 100,000 items 570 -> 140 us on the 2-core machine."""

    def __init__(self):
        self.p_ap = ti.field(ti.f64, shape=())  # p . A p
        self.rz = ti.field(ti.f64, shape=())  # r . z (z = M^-1 r)
        self.rr = ti.field(ti.f64, shape=())  # r . r
        self.bb = ti.field(ti.f64, shape=())  # b . b

    @ti.func
    def clear_for_assembly(self):
        """Before an assembly adds its r.z, r.r and b.b terms."""
        self.rz[None] = 0.0
        self.rr[None] = 0.0
        self.bb[None] = 0.0

    @ti.func
    def clear_for_update(self):
        """Before an update adds its r.z and r.r terms."""
        self.rz[None] = 0.0
        self.rr[None] = 0.0


def pcg(
    sums: CGSums,
    matvec: Callable[[], None],
    update: Callable[[float], None],
    direction: Callable[[float], None],
    tolerance: float,
    max_iterations: int,
) -> CGResult:
    """Iterate after `assemble` has set r = b, z = M^-1 r, d = z and sums rz, rr, bb; stops when |r| <= tol |b|.
    `matvec` sets Ad and sums.p_ap, `update(alpha)` steps x, r and z and sets sums.rz and sums.rr, `direction(beta)`
    sets d = z + beta d."""
    rz = float(sums.rz[None])
    rr = float(sums.rr[None])
    bnorm = max(float(sums.bb[None]) ** 0.5, 1e-300)
    it = 0
    while it < max_iterations and rr**0.5 > tolerance * bnorm:
        matvec()
        p_ap = float(sums.p_ap[None])
        if p_ap <= 0.0:  # the search direction vanished (converged to round-off)
            break
        update(rz / p_ap)
        rz_new, rr = float(sums.rz[None]), float(sums.rr[None])
        direction(rz_new / rz if rz > 0 else 0.0)
        rz = rz_new
        it += 1
    return CGResult(it, rr**0.5 / bnorm)
