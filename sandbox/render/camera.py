"""Where the pictures are taken from: the 3D camera's pose (the pictures' and the caches'), and the 2D view as an
orthographic camera for a film tool.

World y is up in every picture. A 3D camera looks from `eye` at `target` with a vertical field of view; by default
it stands in front of and above the content box (render/layout.content_box), far enough back to frame it. A 2D
scene is seen from +z, the content box fitted into the picture as the pictures fit it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .layout import content_box, fit

WORLD_UP = np.array([0.0, 1.0, 0.0])


def default_eye(view_box, room: float = 1.0) -> np.ndarray:
    """The default eye (3,) for a view of the box (lo, hi): in front of it, raised and to the right, backed off by
    `room` (a picture whose top band takes rows from the view backs off further)."""
    lo, hi = (np.asarray(b, float) for b in view_box)
    size = float(np.linalg.norm(hi - lo))
    return (lo + hi) / 2 + np.array([0.35, 0.45, 1.0]) * size * 0.9 * room


def look_at(eye, target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, forward) unit vectors (3,) of a camera at `eye` looking at `target`, world y up."""
    forward = np.asarray(target, float) - np.asarray(eye, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, WORLD_UP)
    if np.linalg.norm(right) < 1e-6:  # looking straight up or down
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


@dataclass(frozen=True)
class Camera:
    """A camera in scene lengths: `eye` and `target` (3,), `fov` the vertical field of view in degrees, `aspect`
    the picture's width over its height; `ortho_height` > 0: orthographic, showing that many lengths top to bottom
    (a 2D scene's view)."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    fov: float
    aspect: float
    ortho_height: float = 0.0

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, forward) unit vectors (3,)."""
        return look_at(self.eye, self.target)

    def words(self) -> str:
        """The camera as one line of text (a PLY comment)."""
        eye, target = (" ".join(f"{v:.9g}" for v in p) for p in (self.eye, self.target))
        shape = f"ortho_height {self.ortho_height:.9g}" if self.ortho_height else f"fov {self.fov:.9g}"
        return f"camera eye {eye} target {target} {shape} aspect {self.aspect:.9g}"


def scene_camera(scene) -> Camera:
    """The camera of `scene`'s pictures, over the whole picture (no band of text): in 3D the render table's camera
    or the default one; in 2D the content box fitted into the picture, seen from +z."""
    cfg = scene.render
    aspect = cfg.width / cfg.height
    box = content_box(scene)
    if len(scene.world.lo) == 3:
        centre = (np.asarray(box[0]) + np.asarray(box[1])) / 2
        target = np.asarray(cfg.camera_target, float) if cfg.camera_target else centre
        eye = np.asarray(cfg.camera_position, float) if cfg.camera_position else default_eye(box)
        return Camera(tuple(map(float, eye)), tuple(map(float, target)), float(cfg.fov), aspect)
    scale, offset = fit(box, (0, cfg.width, 0, cfg.height), cfg.height, (scene.world.lo, scene.world.hi))
    centre = (np.array([cfg.width, cfg.height]) / 2 - offset) / scale
    height = cfg.height / scale
    distance = 0.5 * height / math.tan(math.radians(cfg.fov) / 2)  # where a perspective camera would frame it
    eye = (float(centre[0]), float(centre[1]), distance)
    return Camera(eye, (float(centre[0]), float(centre[1]), 0.0), float(cfg.fov), aspect, float(height))
