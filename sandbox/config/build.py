"""Bodies → particles and springs, as NumPy arrays (no Taichi here, so it is quick to test and to reason about).

Every body is a Bravais lattice clipped by a shape. Springs join lattice sites closer than `spring_radius` spacings;
they are found by index offsets on the lattice, so building is exact and linear in the particle count.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
from PIL import Image

from ..errors import SandboxError, SceneError
from .scene_tables import Body, Scene

LATTICE_BASIS = {
    "square": np.array([[1.0, 0.0], [0.0, 1.0]]),
    "hex": np.array([[1.0, 0.0], [0.5, math.sqrt(3) / 2]]),
    "cubic": np.eye(3),
    "fcc": np.array([[0.0, 0.5, 0.5], [0.5, 0.0, 0.5], [0.5, 0.5, 0.0]]) * math.sqrt(2),
}


@dataclass
class Particles:
    """Initial particle and spring arrays. N particles, S springs, D dimensions."""

    x: np.ndarray  # (N, D) positions
    v: np.ndarray  # (N, D) velocities
    mass: np.ndarray  # (N,)
    radius: np.ndarray  # (N,)
    temperature: np.ndarray  # (N,) degrees
    material: np.ndarray  # (N,) int32 index into Scene.used_materials()
    body: np.ndarray  # (N,) int32 index into Scene.bodies
    solid: np.ndarray  # (N,) bool: built as a solid (the body has springs); the rest start liquid
    spring_i: np.ndarray  # (S,) int32
    spring_j: np.ndarray  # (S,) int32
    rest_length: np.ndarray  # (S,)
    stiffness: np.ndarray  # (S,) base stiffness k_s
    damping: np.ndarray  # (S,) damping k_d

    @property
    def count(self) -> int:
        return len(self.x)

    @property
    def spring_count(self) -> int:
        return len(self.spring_i)

    def max_bonds(self) -> int:
        """Largest number of springs at one particle (0 without springs)."""
        if self.spring_count == 0:
            return 0
        deg = np.bincount(np.concatenate([self.spring_i, self.spring_j]), minlength=self.count)
        return int(deg.max())

    @staticmethod
    def side_by_side(builds: list[Particles], stride: int = 0) -> Particles:
        """The builds of a scene's worlds one after the other (world k's particle i at k N + i, or at k stride + i
        with a `stride`: each world's rows padded with zeros to it), each world's springs joining its own particles
        (`[built] * K`: K copies); ValueError where they differ in particle count or springs (what a world may vary:
        its bodies' temperatures and velocities, not its structure)."""
        first = builds[0]
        if len(builds) == 1:
            return first
        for k, other in enumerate(builds[1:], 1):
            same = other.count == first.count and np.array_equal(other.spring_i, first.spring_i)
            if not same or not np.array_equal(other.spring_j, first.spring_j):
                raise ValueError(f"world {k} is built of other particles or springs than world 0; expected the same")
        stride = stride or first.count
        per_particle = [f.name for f in dataclasses.fields(Particles) if not f.name.startswith(("spring_", "rest_"))]
        per_particle = [name for name in per_particle if name not in ("stiffness", "damping")]

        def padded(b: Particles, name: str) -> np.ndarray:
            rows = getattr(b, name)
            return np.concatenate([rows, np.zeros((stride - len(rows), *rows.shape[1:]), rows.dtype)])

        def rows(b: Particles, name: str) -> np.ndarray:
            return padded(b, name) if name in per_particle else getattr(b, name)

        joined = {f.name: np.concatenate([rows(b, f.name) for b in builds]) for f in dataclasses.fields(Particles)}
        shifts = np.repeat(np.arange(len(builds), dtype=np.int32) * stride, first.spring_count)
        for name in ("spring_i", "spring_j"):
            joined[name] = joined[name] + shifts
        return Particles(**joined)


def lattice_sites(body: Body, dim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lattice sites inside the body's shape: (positions (N, D), integer indices (N, D), basis (D, D) scaled)."""
    basis = LATTICE_BASIS[body.lattice] * body.spacing
    s = body.spacing
    if body.shape in ("disk", "sphere"):
        origin = np.asarray(body.center)
        blo, bhi = origin - body.radius, origin + body.radius
    else:
        blo, bhi = np.asarray(body.lo), np.asarray(body.hi)
        origin = blo + 0.5 * s
    corners = np.array(list(itertools.product(*zip(blo, bhi))))
    idx_corners = np.linalg.solve(basis.T, (corners - origin).T).T
    lo_idx = np.floor(idx_corners.min(axis=0)).astype(int) - 1
    hi_idx = np.ceil(idx_corners.max(axis=0)).astype(int) + 1
    axes = [np.arange(a, b + 1) for a, b in zip(lo_idx, hi_idx)]
    idx = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)
    pos = origin + idx @ basis
    inside = _inside(body, pos, s)
    return pos[inside], idx[inside], basis


def _inside(body: Body, pos: np.ndarray, s: float) -> np.ndarray:
    eps = 1e-9 * max(1.0, s)
    if body.shape == "box":
        lo = np.asarray(body.lo) + 0.5 * s - eps
        hi = np.asarray(body.hi) - 0.5 * s + eps
        return np.all((pos >= lo) & (pos <= hi), axis=1)
    if body.shape in ("disk", "sphere"):
        return np.linalg.norm(pos - np.asarray(body.center), axis=1) <= body.radius + eps
    return _inside_mask(body, pos)


def _inside_mask(body: Body, pos: np.ndarray) -> np.ndarray:
    image = load_mask(body.mask)  # (W, H) bool, [0, 0] at the bottom-left
    w, h = image.shape
    lo, hi = np.asarray(body.lo), np.asarray(body.hi)
    in_box = np.all((pos >= lo) & (pos < hi), axis=1)
    uv = (pos - lo) / (hi - lo)
    px = np.clip((uv[:, 0] * w).astype(int), 0, w - 1)
    py = np.clip((uv[:, 1] * h).astype(int), 0, h - 1)
    return in_box & image[px, py]


def load_mask(path: str) -> np.ndarray:
    """A PNG as a boolean (width, height) array, [0, 0] at the bottom-left: alpha > 50% if it has alpha, else
    luminance > 50%."""
    try:
        with Image.open(path) as img:
            if min(img.size) == 0:
                raise SandboxError(f"{path}: cannot read the mask image; expected a valid PNG")
            alpha = "A" in img.mode or "transparency" in img.info
            pixels = np.asarray(img.convert("RGBA" if alpha else "RGB"))  # (H, W, C), top row first
    except (OSError, ValueError, Image.DecompressionBombError) as exc:  # a damaged PNG, or not an image at all
        raise SandboxError(f"{path}: cannot read the mask image ({type(exc).__name__}); expected a valid PNG") from None
    inside = pixels[:, :, 3] > 127 if alpha else pixels.mean(axis=2) > 127
    return np.ascontiguousarray(inside[::-1].T)  # (W, H): x first, y up


def _lattice_springs(idx: np.ndarray, basis: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of sites whose lattice offset is shorter than `radius`, found by shifting an index grid."""
    dim = idx.shape[1]
    lo = idx.min(axis=0)
    shape = tuple(idx.max(axis=0) - lo + 1)
    grid = np.full(shape, -1, dtype=np.int64)
    grid[tuple((idx - lo).T)] = np.arange(len(idx))
    reach = min(int(math.ceil(radius / np.min(np.linalg.norm(basis, axis=1)))) + 1, max(shape))  # within the body
    pi, pj = [], []
    for off in itertools.product(range(-reach, reach + 1), repeat=dim):
        nz = [o for o in off if o != 0]
        if not nz or nz[0] < 0:
            continue  # each unordered offset once
        if np.linalg.norm(np.asarray(off) @ basis) > radius + 1e-9 or any(abs(k) >= n for k, n in zip(off, shape)):
            continue  # too long, or longer than the body: no pair of its sites is this far apart
        src = tuple(slice(max(0, -k), n - max(0, k)) for k, n in zip(off, shape))
        dst = tuple(slice(max(0, k), n - max(0, -k)) for k, n in zip(off, shape))
        a, b = grid[src].ravel(), grid[dst].ravel()
        keep = (a >= 0) & (b >= 0)
        pi.append(a[keep])
        pj.append(b[keep])
    if not pi:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(pi), np.concatenate(pj)


def build_particles(scene: Scene) -> Particles:
    """Every body of the scene as particles (and springs for solid bodies). Raises SceneError for an empty body or
    one that lies partly outside the domain."""
    dim = scene.dim
    mat_index = {name: k for k, name in enumerate(scene.used_materials())}
    ambient = scene.heat.ambient if scene.heat else 20.0
    parts: dict[str, list] = {
        k: [] for k in ("x", "v", "m", "r", "T", "mat", "body", "solid", "si", "sj", "l0", "ks", "kd")
    }
    offset = 0
    for b_index, body in enumerate(scene.bodies):
        key = f"bodies[{b_index}]"
        pos, idx, basis = lattice_sites(body, dim)
        n = len(pos)
        if n == 0:
            raise SceneError(
                str(scene.path), key, "the shape holds no lattice site; expected a larger shape or a smaller spacing"
            )
        rng = np.random.default_rng(body.seed)
        if body.jitter > 0:
            pos = pos + rng.uniform(-0.5, 0.5, pos.shape) * body.jitter * body.spacing
        lo, hi = np.asarray(scene.world.lo), np.asarray(scene.world.hi)
        outside = np.any((pos < lo) | (pos > hi), axis=1)
        if outside.any():
            raise SceneError(
                str(scene.path),
                key,
                f"{int(outside.sum())} of {n} particles lie outside the domain "
                f"{list(lo)}..{list(hi)}; expected the body inside world.lo..world.hi",
            )
        material = scene.materials[body.material]
        cell_volume = abs(np.linalg.det(basis))
        mass = material.particle_mass if material.particle_mass is not None else material.density * cell_volume
        vel = np.tile(np.asarray(body.velocity, dtype=float), (n, 1))
        if body.random_velocity > 0:
            noise = rng.normal(0.0, body.random_velocity, (n, dim))
            vel += noise - noise.mean(axis=0)
        parts["x"].append(pos)
        parts["v"].append(vel)
        parts["m"].append(np.full(n, mass))
        parts["r"].append(np.full(n, 0.5 * body.spacing))
        parts["T"].append(np.full(n, ambient if body.temperature is None else body.temperature))
        parts["mat"].append(np.full(n, mat_index[body.material], dtype=np.int32))
        parts["body"].append(np.full(n, b_index, dtype=np.int32))
        parts["solid"].append(np.full(n, body.springs))
        if body.springs:
            i, j = _lattice_springs(idx, basis, body.spring_radius * body.spacing + 1e-9)
            parts["si"].append(i + offset)
            parts["sj"].append(j + offset)
            parts["l0"].append(np.linalg.norm(pos[j] - pos[i], axis=1))
            parts["ks"].append(np.full(len(i), material.stiffness))
            parts["kd"].append(np.full(len(i), material.damping))
        offset += n

    def cat(name, dtype=np.float64, width=None):
        if parts[name]:
            return np.concatenate(parts[name]).astype(dtype)
        return np.zeros((0,) if width is None else (0, width), dtype=dtype)

    return Particles(
        x=cat("x", width=dim),
        v=cat("v", width=dim),
        mass=cat("m"),
        radius=cat("r"),
        temperature=cat("T"),
        material=cat("mat", np.int32),
        body=cat("body", np.int32),
        solid=cat("solid", bool),
        spring_i=cat("si", np.int32),
        spring_j=cat("sj", np.int32),
        rest_length=cat("l0"),
        stiffness=cat("ks"),
        damping=cat("kd"),
    )
