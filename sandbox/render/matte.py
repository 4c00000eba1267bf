"""Pictures with alpha, for a video an editor lays over other footage: the same picture drawn over a black and over
a white background gives each pixel's colour and coverage (difference matting).

A pixel drawn over background B is alpha x F + (1 - alpha) x B for the particle's (or text's) colour F; over black
(B = 0) and white (B = 1) that is two equations for alpha and F: alpha = 1 - (white - black), F = black / alpha. The
domain's backdrop is derived from the background colour, so it comes out transparent where it is the background and
partly opaque where the picture shades it (outside the box, the walls' faint frame); heat plates, particles, text and
charts are opaque.
"""

from __future__ import annotations

import numpy as np

BLACK, WHITE = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)


def matte(over_black: np.ndarray, over_white: np.ndarray) -> np.ndarray:
    """(H, W, 4) uint8 RGBA, straight (not premultiplied) alpha, from the (H, W, 3) uint8 pictures drawn over black
    and over white."""
    black = over_black.astype(np.float32) / 255.0
    white = over_white.astype(np.float32) / 255.0
    alpha = np.clip(1.0 - (white - black).mean(axis=2, keepdims=True), 0.0, 1.0)
    color = np.where(alpha > 0.0, black / np.maximum(alpha, 1e-6), 0.0)
    rgba = np.concatenate([np.clip(color, 0.0, 1.0), alpha], axis=2)
    return np.round(255.0 * rgba).astype(np.uint8)
