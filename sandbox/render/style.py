"""The renderer's constants (drawing styles, blend modes, sizes, overlay colours) and its one free helper."""

import taichi as ti

COLOR_MODES = {"temperature": 0, "material": 1, "speed": 2, "phase": 3}
DRAW = {"dot": 0, "splat": 1, "sphere": 2}
BLEND = {"opaque": 0, "alpha": 1, "additive": 2}
R_MIN = 0.7  # pixels: the smallest drawn radius
OUTPUTS = ("image", "picture", "rgba")  # see the module docstring
ROW_MAJOR = "ji"  # image fields are indexed [x, y] (GGUI's convention) but stored row by row, as the output is
MIN_FADE = 0.25  # the least opacity factor of an opaque or translucent particle smaller than R_MIN
SPLINE_SEGMENTS = 4  # chords per curved (spline) motion-blur streak
TILE = 16  # 2D: pixels per side of the tiles the compositing pass skips when nothing was drawn in them
MAX_OVERLAYS = 4  # 2D: rectangles redrawn every frame whatever moved (chart, potential panel, legend, clock)
SPRING_COLOR = (0.55, 0.6, 0.7)
SPRING_OPACITY = 0.6
BRUSH_COLOR = (0.92, 0.92, 0.92)  # the window's tool outline
LID_COLOR = (0.85, 0.85, 0.9)  # the molecular model's lid, 2D and 3D
WALL_GAIN, WALL_LIFT = 2.2, 0.04  # 2D: the walls' faint frame is the background x gain + lift (caches use it too)
BRUSH_OPACITY = 0.85


@ti.func
def _add(layer: ti.template(), x, y, value, plain):
    """layer[x, y] += value: by a plain load and store when `plain` (no other thread writes that pixel meanwhile),
    else atomically (on the CPU a float atomic add is a compare-and-swap loop)."""
    if plain:
        layer[x, y] = layer[x, y] + value
    else:
        layer[x, y] += value
