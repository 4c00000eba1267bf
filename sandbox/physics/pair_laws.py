"""Pair laws, each written once: its energy U(r) and its radial force factor g(r) = U'(r) / r per unit mass product
(the force on i from j is m_i m_j g(r) d, d = x_j - x_i, so g > 0 attracts), as functions of `ops` (NUMPY or TAICHI),
so that the same lines run in NumPy (the tables the term precomputes: the cutoff's energy and force shifts, the core
cap, the window's curve) and inside Taichi kernels (the step's forces, the measured energy).

A law gives only its formula, its three coefficients (from the materials or the [pair] table) and which of them the
pair-force sliders scale; the term (physics/pair.py) applies the cutoff, the energy shift (pair.shift), the force
shift (pair.force_shift), the core cap and the viscous term for any law. A new law is a class here, chosen by
law_for, with its keys in the [pair] table (config/scene_tables.py).

    power   alpha / (r + eps)^a - beta / r^b: the 12-6 Lennard-Jones force is a = 8, b = 14, eps = 0, alpha = 24 e s^6,
            beta = 48 e s^12 (unit masses); materials mix alpha and beta geometrically, eps arithmetically
    morse   U(r) = D ((1 - e^(-w (r - r0)))^2 - 1): a well of depth D at r0, width 1/w (the [pair] table's depth,
            width and distance, the same for every pair of materials)
"""

import math  # no `from __future__ import annotations`: Taichi reads ti.template() annotations as objects

import numpy as np
import taichi as ti


@ti.func
def powneg(x, e: ti.template()):
    """x^(-e): repeated multiplication when e is a whole number (exact and fast), else pow."""
    result = 0.0 * x
    if ti.static(float(e).is_integer() and e >= 0):
        inv = 1.0 / x
        result = 1.0 + 0.0 * x
        for _ in ti.static(range(int(e))):
            result *= inv
    else:
        result = ti.pow(x, -e)
    return result


@ti.func
def ipow(x, n: ti.template()):
    """x^n for a whole number n >= 0, by binary exponentiation unrolled at compile time."""
    result = 1.0 + 0.0 * x
    base = x
    for bit in ti.static(range(max(int(n).bit_length(), 1))):
        if ti.static((int(n) >> bit) & 1):
            result *= base
        if ti.static((int(n) >> (bit + 1)) > 0):
            base = base * base
    return result


class NUMPY:
    """The operations a law uses, on NumPy arrays or floats."""

    sqrt, log, exp = staticmethod(np.sqrt), staticmethod(np.log), staticmethod(np.exp)

    @staticmethod
    def powneg(x, e):
        return 1.0 / np.power(x, e)

    @staticmethod
    def ipow(x, n):
        return np.power(x, n)


class TAICHI:
    """The same operations inside a Taichi kernel (a law's function is called while the kernel is compiled)."""

    sqrt, log, exp = staticmethod(ti.sqrt), staticmethod(ti.log), staticmethod(ti.exp)
    powneg, ipow = staticmethod(powneg), staticmethod(ipow)


class PowerLaw:
    """g(r) = alpha / (r + eps)^a - beta / r^b; coefficients (alpha, beta, eps)."""

    name = "power"
    scaled = {"attraction": 0, "repulsion": 1}  # what the pair-force sliders scale
    attraction = 0  # the coefficient vapour does not feel (a material that boils)

    def __init__(self, a: float, b: float, soft: bool = True) -> None:
        """Exponents `a` and `b`; `soft`: some material pair has eps != 0 (else, with even exponents, the forces are
        powers of 1/r^2 and need no square root)."""
        self.a, self.b = float(a), float(b)
        self.even = not soft and self.a % 2 == 0 and self.b % 2 == 0

    def coefficients(self, materials, pair) -> list[np.ndarray]:
        """The (n, n) tables of alpha, beta and eps of every pair of `materials`."""
        alpha = np.array([m.pair_alpha for m in materials])
        beta = np.array([m.pair_beta for m in materials])
        eps = np.array([m.pair_soft for m in materials])
        return [np.sqrt(np.outer(alpha, alpha)), np.sqrt(np.outer(beta, beta)), 0.5 * (eps[:, None] + eps[None, :])]

    def g(self, r2, c, ops):
        alpha, beta, eps = c[0], c[1], c[2]
        if self.even:
            inv2 = 1.0 / r2
            return alpha * ops.ipow(inv2, self.a // 2) - beta * ops.ipow(inv2, self.b // 2)
        r = ops.sqrt(r2)
        return alpha * ops.powneg(r + eps, self.a) - beta * ops.powneg(r, self.b)

    def u(self, r, c, ops):
        """The unshifted potential: alpha A(r) + beta R(r) with A' = r / (r + eps)^a, R' = -r / r^b."""
        alpha, beta, eps = c[0], c[1], c[2]
        s = r + eps
        if self.a == 2.0:
            att = ops.log(s) + eps / s
        elif self.a == 1.0:
            att = s - eps * ops.log(s)
        else:
            att = ops.powneg(s, self.a - 2.0) / (2.0 - self.a) - eps * ops.powneg(s, self.a - 1.0) / (1.0 - self.a)
        if self.b == 2.0:
            rep = -beta * ops.log(r)
        else:
            rep = beta * ops.powneg(r, self.b - 2.0) / (self.b - 2.0)
        return alpha * att + rep

    def attracting(self, c) -> list:
        """The coefficients of the attraction alone (beta taken out): what a vapour share does not feel."""
        return [c[0], 0.0 * c[1], c[2]]

    def equilibrium(self, c) -> float:
        """The r where the force vanishes (alpha/(r+eps)^a = beta/r^b), by bisection; inf without attraction."""
        alpha, beta, eps = (float(x) for x in c)
        if alpha <= 0:
            return math.inf
        if beta <= 0:
            return 0.0
        f = lambda r: math.log(alpha) - self.a * math.log(r + eps) - math.log(beta) + self.b * math.log(r)  # noqa: E731
        lo, hi = 1e-6, 1.0
        while f(hi) < 0:
            hi *= 2
            if hi > 1e12:
                return math.inf
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
        return 0.5 * (lo + hi)

    def words(self) -> str:
        return f"a={self.a:g}, b={self.b:g}"


class MorseLaw:
    """U(r) = D ((1 - e^(-w (r - r0)))^2 - 1), so g(r) = 2 D w e^(-w (r - r0)) (1 - e^(-w (r - r0))) / r;
    coefficients (D, w, r0) from the [pair] table."""

    name = "morse"
    scaled = {"attraction": 0}  # the well's depth
    attraction = None  # no attraction apart from the rest: materials that boil need the power law

    def __init__(self, pair) -> None:
        """`pair`: the scene's [pair] table (its depth, width and distance)."""
        self.pair = pair

    def coefficients(self, materials, pair) -> list[np.ndarray]:
        n = len(materials)
        return [np.full((n, n), float(v)) for v in (pair.depth, pair.width, pair.distance)]

    def g(self, r2, c, ops):
        depth, width, r0 = c[0], c[1], c[2]
        r = ops.sqrt(r2)
        e = ops.exp(-width * (r - r0))
        return 2.0 * depth * width * e * (1.0 - e) / r

    def u(self, r, c, ops):
        depth, width, r0 = c[0], c[1], c[2]
        e = ops.exp(-width * (r - r0))
        return depth * (1.0 - e) * (1.0 - e) - depth

    def equilibrium(self, c) -> float:
        return float(c[2]) if c[0] > 0 else math.inf

    def words(self) -> str:
        return f"Morse: depth {self.pair.depth:g}, width {self.pair.width:g}, at {self.pair.distance:g}"


def law_for(pair, soft: bool):
    """The law the scene's [pair] table names; `soft`: some material pair has a softening eps != 0."""
    return MorseLaw(pair) if pair.law == MorseLaw.name else PowerLaw(pair.a, pair.b, soft)
