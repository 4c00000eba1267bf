"""Colour maps as Taichi funcs (and NumPy twins for tests and legends). Inputs t are in [0, 1]."""

import numpy as np
import taichi as ti

# Temperature: cold blue -> pale yellow -> hot red (ColorBrewer's RdYlBu, reversed): every colour appears once, so a
# particle's colour read against the colour bar gives its temperature.
TEMPERATURE_STOPS = np.array(
    [
        [0.0, 0.192, 0.212, 0.584],
        [0.2, 0.271, 0.459, 0.706],
        [0.35, 0.671, 0.851, 0.914],
        [0.5, 1.0, 1.0, 0.749],
        [0.65, 0.992, 0.682, 0.380],
        [0.8, 0.843, 0.188, 0.153],
        [1.0, 0.647, 0.0, 0.149],
    ],
    dtype=np.float32,
)
# Speed: dark blue -> teal -> yellow (viridis-like).
SPEED_STOPS = np.array(
    [[0.0, 0.12, 0.1, 0.35], [0.35, 0.13, 0.45, 0.56], [0.7, 0.35, 0.78, 0.4], [1.0, 0.99, 0.9, 0.15]], dtype=np.float32
)


def ramp_np(stops: np.ndarray, t: float) -> np.ndarray:
    """Piecewise-linear colour ramp (NumPy twin of the Taichi funcs)."""
    t = float(np.clip(t, 0.0, 1.0))
    return np.array([np.interp(t, stops[:, 0], stops[:, k]) for k in (1, 2, 3)], dtype=np.float32)


def ramp_np_many(stops: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """ramp_np at each of the positions `ts` ((n,) in [0, 1]): an (n, 3) float32 array, in three NumPy calls (the
    window draws its colour bar every frame)."""
    ts = np.clip(np.asarray(ts, dtype=float), 0.0, 1.0)
    return np.stack([np.interp(ts, stops[:, 0], stops[:, k]) for k in (1, 2, 3)], axis=1).astype(np.float32)


def _ramp_func(stops: np.ndarray):
    pos = [float(s[0]) for s in stops]
    cols = [ti.Vector([float(s[1]), float(s[2]), float(s[3])]) for s in stops]

    @ti.func
    def ramp(t):
        t = ti.math.clamp(t, 0.0, 1.0)
        c = cols[0]
        for k in ti.static(range(1, len(pos))):
            if t > pos[k - 1]:
                u = ti.min((t - pos[k - 1]) / (pos[k] - pos[k - 1]), 1.0)
                c = cols[k - 1] * (1.0 - u) + cols[k] * u
        return c

    return ramp


temperature_map = _ramp_func(TEMPERATURE_STOPS)
speed_map = _ramp_func(SPEED_STOPS)
