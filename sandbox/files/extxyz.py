"""Extended XYZ frames for analysis tools (ASE, OVITO): one frame per call, appended to a text file.

Each frame is the particle count, a comment line of key=value pairs (the box as `Lattice`, its corner as `Origin`,
`Time`, `Step`, the `Properties` that name the columns), then a line per particle in id order:

    id:I:1  material:S:1  pos:R:3  velo:R:3  temperature:R:1  melt_fraction:R:1

Positions and velocities are always three components (a 2D scene has z = 0 and a unit-thick box in z), as both tools
expect. `material` is a custom string column rather than `species`, which ASE would read as chemical elements.
Springs can follow as a `Bonds` key: the live springs as space-separated `i-j` pairs of particle ids.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

PROPERTIES = "id:I:1:material:S:1:pos:R:3:velo:R:3:temperature:R:1:melt_fraction:R:1"


def _vec3(a: np.ndarray) -> np.ndarray:
    """(N, D) -> (N, 3), zero-padded."""
    out = np.zeros((len(a), 3))
    out[:, : a.shape[1]] = a
    return out


def frame_text(
    particles: dict[str, np.ndarray],
    material_names: list[str],
    lo: tuple[float, ...],
    hi: tuple[float, ...],
    periodic: bool,
    time: float,
    step: int,
    bonds: np.ndarray | None = None,
) -> str:
    """One extended-XYZ frame of `particles` (Simulation.particles()); `bonds`: (M, 2) particle ids, or None."""
    dim = len(lo)
    extent = [h - l for l, h in zip(lo, hi)] + [1.0] * (3 - dim)
    origin = list(lo) + [0.0] * (3 - dim)
    lattice = " ".join(f"{extent[a] if a == b else 0.0:.9g}" for a in range(3) for b in range(3))
    pbc = " ".join(("T" if periodic and a < dim else "F") for a in range(3))
    keys = [
        f'Lattice="{lattice}"',
        f'Origin="{" ".join(f"{o:.9g}" for o in origin)}"',
        f"Properties={PROPERTIES}",
        f"Time={time:.9g}",
        f"Step={step}",
        f'pbc="{pbc}"',
    ]
    if bonds is not None:
        pairs = " ".join(f"{int(i)}-{int(j)}" for i, j in bonds)
        keys.append(f'Bonds="{pairs}"')
    ids = particles["id"]
    names = np.asarray(material_names, dtype=object)[particles["material"]]
    pos, vel = _vec3(particles["position"]), _vec3(particles["velocity"])
    temp, phi = particles["temperature"], particles["melt_fraction"]
    lines = [str(len(ids)), " ".join(keys)]
    for k in range(len(ids)):
        p, v = pos[k], vel[k]
        lines.append(
            f"{ids[k]} {names[k]} {p[0]:.9g} {p[1]:.9g} {p[2]:.9g} {v[0]:.9g} {v[1]:.9g} {v[2]:.9g} "
            f"{temp[k]:.9g} {phi[k]:.9g}"
        )
    return "\n".join(lines) + "\n"


def append_frame(path: str | Path, text: str) -> None:
    """Append one frame's text to `path` (created when missing)."""
    with open(path, "a") as out:
        out.write(text)
