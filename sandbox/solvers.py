"""The host side of preconditioned conjugate gradients, shared by the implicit mechanical and heat steppers.

The caller owns the Taichi kernels; each writes the reductions it computes into a 4-entry f64 field `scalars`:
[0] p.Ap (matvec), [1] r.z and [2] r.r (update; also set by assemble), [3] b.b (assemble). Two host reads per
iteration are the price of not running the loop on the device.
"""

from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class CGResult:
    iterations: int
    relative_residual: float


def pcg(
    scalars,
    matvec: Callable[[], None],
    update: Callable[[float], None],
    direction: Callable[[float], None],
    tolerance: float,
    max_iterations: int,
) -> CGResult:
    """Iterate after `assemble` has set r = b, z = M^-1 r, d = z and scalars[1..3]; stops when |r| <= tol |b|."""
    rz = float(scalars[1])
    rr = float(scalars[2])
    bnorm = max(float(scalars[3]) ** 0.5, 1e-300)
    it = 0
    while it < max_iterations and rr**0.5 > tolerance * bnorm:
        matvec()
        p_ap = float(scalars[0])
        if p_ap <= 0.0:  # the search direction vanished (converged to round-off)
            break
        update(rz / p_ap)
        rz_new, rr = float(scalars[1]), float(scalars[2])
        direction(rz_new / rz if rz > 0 else 0.0)
        rz = rz_new
        it += 1
    return CGResult(it, rr**0.5 / bnorm)
