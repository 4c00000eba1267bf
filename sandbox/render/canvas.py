"""The picture being drawn: W x H float layers (y up, Taichi's and GGUI's convention), the 8-bit output, and in 2D
the tiles drawn in each frame.

Layers: `image` (linear RGB in [0, 1]); `accum` and `weight` (opaque particles: coverage-weighted colour and coverage);
`a_accum`, `a_weight`, `a_log` (translucent: alpha-weighted colour, alpha and the sum of log(1 - alpha), the log
transmittance); `light` (additive light, unbounded, tone mapped at the end); `depth` (3D: the nearest opaque
surface's depth bits). Only the layers a scene's blend modes use are allocated.

Output: "image" keeps the float image (tests read it; a window on a GPU shows it); "picture" writes only the 8-bit
H x W x 3 picture (headless video); "rgba" (CPU only) writes GGUI's own packed format, a W x H uint32 array of RGBA
bytes with y up. On the CPU the kernels write the 8-bit picture straight into a NumPy array (no copy); on a GPU it
is a device array copied to the host once per picture.

Tiles (2D): every drawing kernel stamps the 16 x 16 pixel tiles it touches with the frame number, and compositing
visits only the tiles drawn in this frame or the last (to wipe what moved away), plus the overlays' rectangles.
"""

import numpy as np
import taichi as ti

from ..core import runtime, transfer
from ..core.oriented import data_oriented
from .pixels import put_pixel
from .style import MAX_OVERLAYS, OUTPUTS, ROW_MAJOR, TILE


@data_oriented
class Canvas:
    """Layers of `width` x `height` pixels for the blend modes a scene uses, the 8-bit `out`, and (2D) tiles."""

    def __init__(self, width: int, height: int, dim: int, output: str, blends: set, ghosts: bool, exposure: float):
        """`blends`: the blend modes drawn ("opaque", "alpha", "additive"); `ghosts`: 3D motion-blur streaks of opaque
        spheres (they use the translucent layers); `exposure`: the tone map's, for additive light."""
        if output not in OUTPUTS:
            raise ValueError(f"unknown renderer output '{output}'; expected one of {', '.join(OUTPUTS)}")
        self.spec = self.spec_of(width, height, dim, output, blends, ghosts, exposure)
        self.shared = False  # renderers of other states draw here too: each picture is composited whole
        self.on_cpu = runtime.running_arch() == "cpu"
        if output == "rgba" and not self.on_cpu:
            raise ValueError("the packed 'rgba' output is a host array: CPU backend only")
        self.width, self.height, self.dim, self.output = width, height, dim, output
        self.keep_image = output == "image"
        self.has_opaque, self.has_alpha, self.has_additive = (
            "opaque" in blends,
            "alpha" in blends,
            "additive" in blends,
        )
        self.exposure = float(exposure)
        self.image = self.layer(3)  # linear RGB in [0, 1]
        self.accum = self.layer(3)  # opaque: coverage-weighted colour sum
        self.weight = self.layer()  # opaque: coverage sum
        if self.has_alpha or ghosts:
            self.a_accum = self.layer(3)  # alpha-weighted colour sum
            self.a_weight = self.layer()  # alpha sum
            self.a_log = self.layer()  # sum of log(1 - alpha): log transmittance
        if self.has_additive:
            self.light = self.layer(3)  # additive light (unbounded)
        self.depth = self.layer(dtype=ti.i32)  # depth bits of the nearest opaque surface (3D)
        if output == "rgba":
            self.out = np.zeros((width, height), np.uint32)
        elif self.on_cpu:
            self.out = np.zeros((height, width, 3), np.uint8)
        else:
            self.out = runtime.ndarray(ti.u8, (height, width, 3))
        if dim == 2:
            self.tiles_x, self.tiles_y = -(-width // TILE), -(-height // TILE)
            self.tile_stamp = ti.field(ti.i32, shape=(self.tiles_x, self.tiles_y))
            self.tile_stamp.fill(-2)
            self.stamp = ti.field(ti.i32, shape=())  # the frame number
            self.dirty = ti.field(ti.i32, shape=self.tiles_x * self.tiles_y)
            self.n_dirty = ti.field(ti.i32, shape=())
            self.overlay = ti.Vector.field(4, ti.i32, shape=MAX_OVERLAYS)  # tile ranges tx0, tx1, ty0, ty1
            self.n_overlay = ti.field(ti.i32, shape=())

    @staticmethod
    def spec_of(width: int, height: int, dim: int, output: str, blends: set, ghosts: bool, exposure: float) -> tuple:
        """What a canvas made with these arguments is: two renderers may share a canvas where theirs are equal."""
        return (width, height, dim, output, frozenset(blends), bool(ghosts), float(exposure))

    def layer(self, channels: int = 1, dtype=ti.f32):
        """A W x H image field (indexed [x, y], stored row by row)."""
        shape = (self.width, self.height)
        if channels == 1:
            return ti.field(dtype, shape=shape, order=ROW_MAJOR)
        return ti.Vector.field(channels, dtype, shape=shape, order=ROW_MAJOR)

    def set_overlays(self, rects: list) -> None:
        """2D: the rectangles (x0, x1, row0, row1: pixels, rows counted from the top) that compositing redraws every
        frame (a chart, a panel, the legend, the clock: their content changes whether or not particles move)."""
        table = np.zeros((MAX_OVERLAYS, 4), np.int32)
        for k, (x0, x1, r0, r1) in enumerate(rects[:MAX_OVERLAYS]):
            y0, y1 = self.height - 1 - r1, self.height - 1 - r0  # rows from the top -> y up
            table[k] = (max(x0, 0) // TILE, x1 // TILE, max(y0, 0) // TILE, y1 // TILE)
        transfer.upload([(self.overlay, table), (self.n_overlay, min(len(rects), MAX_OVERLAYS))])  # one copy kernel

    @ti.func
    def box(self, a, b, r, c):
        """Pixel bounds of the capsule around a-b (and control point c, which bounds a curve with the ends): every
        pixel whose centre lies within r + 0.5 of it (where the coverage clamp(r + 0.5 - d, 0, 1) is not zero), as
        pixel px's centre is px + 0.5."""
        lo = ti.min(ti.min(a, b), c)
        hi = ti.max(ti.max(a, b), c)
        x0 = ti.max(ti.cast(ti.ceil(lo[0] - r - 1), ti.i32), 0)
        x1 = ti.min(ti.cast(ti.floor(hi[0] + r), ti.i32), self.width - 1)
        y0 = ti.max(ti.cast(ti.ceil(lo[1] - r - 1), ti.i32), 0)
        y1 = ti.min(ti.cast(ti.floor(hi[1] + r), ti.i32), self.height - 1)
        return x0, x1, y0, y1

    @ti.func
    def stamp_tiles(self, x0, x1, y0, y1):
        """2D: mark the tiles of pixel box [x0, x1] x [y0, y1] as drawn in this frame."""
        self.stamp_tiles_as(x0, x1, y0, y1, self.stamp[None])

    @ti.func
    def stamp_tiles_as(self, x0, x1, y0, y1, stamp):
        """2D: mark the tiles of pixel box [x0, x1] x [y0, y1] as drawn in frame number `stamp`."""
        if ti.static(self.dim == 2):
            for tx in range(x0 // TILE, x1 // TILE + 1):
                for ty in range(y0 // TILE, y1 // TILE + 1):
                    self.tile_stamp[tx, ty] = stamp

    @ti.func
    def over_translucent(self, x, y, c):
        """Colour c with pixel (x, y)'s translucent layer composited over it (weighted-average colour, total alpha
        1 - prod(1 - a)); the layer is zeroed for the next frame."""
        aw = self.a_weight[x, y]
        if aw > 0.0:
            a = 1.0 - ti.exp(self.a_log[x, y])
            c = c * (1.0 - a) + self.a_accum[x, y] / aw * a
            self.a_accum[x, y] = ti.Vector([0.0, 0.0, 0.0])
            self.a_weight[x, y] = 0.0
            self.a_log[x, y] = 0.0
        return c

    @ti.kernel
    def tone_map(self):
        """Add the additive light to the image, 1 - exp(-exposure L) per channel (dense light saturates gracefully)."""
        for x, y in self.image:
            self.image[x, y] = ti.min(self.image[x, y] + 1.0 - ti.exp(-self.exposure * self.light[x, y]), 1.0)

    @ti.kernel
    def pack(self, out: ti.types.ndarray()):
        """The float image into the 8-bit output."""
        for x, y in self.image:
            self.put_out(out, x, y, self.image[x, y])

    @ti.func
    def put_out(self, out: ti.template(), x, y, c):
        """Write colour c (floats in [0, 1]) at pixel (x, y) (y up) of the 8-bit output (see put_pixel)."""
        put_pixel(out, self.height, x, y, c)

    def picture(self) -> np.ndarray:
        """The 8-bit output as an (H, W, 3) uint8 array, top row first (packing the float image first where the last
        pass left it there: 3D, and the "image" output)."""
        if self.output == "rgba":  # packed already; unpack on the host
            rgba = self.out.view(np.uint8).reshape(self.width, self.height, 4)
            return np.ascontiguousarray(rgba[:, ::-1, :3].transpose(1, 0, 2))
        if self.dim == 3 or self.keep_image:
            self.pack(self.out)
        return self.out if self.on_cpu else self.out.to_numpy()
