"""The pixels mask emitters seed from (physics/emitters.py): a mask image's inside pixels, or for a `surface`
emitter the inside pixels with an outside 4-neighbour. Each pixel is equally likely, so seeding is uniform by area
(by length along the boundary, to within a pixel)."""

import numpy as np

from ..config.build import load_mask
from ..errors import SceneError


def mask_pixel_table(emitters: list, dim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """(pixels (P, 2) int32 of every mask emitter in turn, each emitter's first pixel (E,), its pixel count (E,),
    its pixel's size in scene units (E, dim)); None where no emitter is a mask. SceneError for a mask with no inside
    pixels."""
    chunks = []
    start = 0
    n = max(len(emitters), 1)
    starts, counts, sizes = np.zeros(n, np.int32), np.zeros(n, np.int32), np.zeros((n, dim))
    for k, e in enumerate(emitters):
        if e.shape != "mask":
            continue
        image = load_mask(e.mask)
        if e.surface:
            padded = np.pad(image, 1)
            outside_near = ~padded[:-2, 1:-1] | ~padded[2:, 1:-1] | ~padded[1:-1, :-2] | ~padded[1:-1, 2:]
            image = image & outside_near
        pixels = np.argwhere(image).astype(np.int32)
        if len(pixels) == 0:
            raise SceneError(str(e.mask), "", f"emitter {e.name!r}: the mask has no inside pixels")
        chunks.append(pixels)
        starts[k], counts[k] = start, len(pixels)
        sizes[k] = (np.asarray(e.hi) - np.asarray(e.lo)) / np.asarray(image.shape)
        start += len(pixels)
    if not chunks:
        return None
    return np.concatenate(chunks), starts, counts, sizes
