"""Make the strips of stills the README and docs/ show (docs/ice_cube.png, docs/candle.png, docs/freeze_thaw.png,
docs/smoke_vortex.png, docs/states_of_matter.png), each still as `sandbox run` draws it:
`python benchmarks/doc_pictures.py [NAME ...]`."""

import sys
from pathlib import Path

import numpy as np
import this_tree  # noqa: F401  (this checkout's sandbox, not the installed one)
from PIL import Image

import sandbox

DOCS = Path(__file__).resolve().parent.parent / "docs"
# scene: (seconds at which a still is taken, width, height of each still[, stills per row])
STRIPS = {
    "ice_cube": ((0.2, 3.0, 4.6, 9.0), 480, 270),
    "candle": ((0.4, 3.0, 6.0, 9.0), 480, 270),
    "freeze_thaw": ((1.0, 3.0, 5.0, 7.0), 480, 270),
    "smoke_vortex": ((10.0,), 480, 270),
    "states_of_matter": ((0.2, 4.0, 12.0, 34.0), 800, 450, 2),
}


def strip(name: str) -> Path:
    """Run the scene and put its stills side by side (in rows of `per_row`), 4 pixels apart."""
    times, width, height, *rest = STRIPS[name]
    per_row = rest[0] if rest else len(times)
    sim = sandbox.load(name)
    stills = []
    for t in times:
        while sim.time < t - 1e-9:
            sim.run(1)
        stills.append(sim.picture(width, height))
    gap = np.full((height, 4, 3), 255, np.uint8)
    rows = []
    for k in range(0, len(stills), per_row):
        rows.append(np.concatenate([x for still in stills[k : k + per_row] for x in (still, gap)][:-1], axis=1))
        rows.append(np.full((4, rows[-1].shape[1], 3), 255, np.uint8))
    path = DOCS / f"{name}.png"
    Image.fromarray(np.concatenate(rows[:-1], axis=0)).save(path, optimize=True)
    return path


if __name__ == "__main__":
    for name in sys.argv[1:] or STRIPS:
        print(strip(name))
