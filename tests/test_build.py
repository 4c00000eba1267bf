"""Bodies become exact lattices; springs join exactly the lattice neighbours within the spring radius."""

import math

import numpy as np
import pytest

from sandbox.config.build import build_particles
from sandbox.core.particles import bond_table

from .conftest import make_scene, scene_dict


def _body(**kw):
    body = {"material": "jelly", "shape": "box", "lo": [2.0, 2.0], "hi": [12.0, 7.0]}
    body.update(kw)
    return body


def test_square_box_counts_and_springs():
    built = build_particles(make_scene(scene_dict(bodies=[_body()])))
    assert built.count == 10 * 5
    # horizontal 9*5 + vertical 10*4 + two diagonals 2*9*4
    assert built.spring_count == 45 + 40 + 72
    assert np.allclose(sorted(set(np.round(built.rest_length, 9))), [1.0, math.sqrt(2)])
    assert built.max_bonds() == 8
    assert np.allclose(built.mass, 1.0) and np.allclose(built.radius, 0.5)


def test_nearest_neighbours_only():
    built = build_particles(make_scene(scene_dict(bodies=[_body(spring_radius=1.0)])))
    assert built.spring_count == 45 + 40


def test_hex_lattice_has_six_neighbours_inside():
    scene = make_scene(
        scene_dict(
            world={"dim": 2, "lo": [0, 0], "hi": [40, 40]},
            bodies=[_body(lattice="hex", lo=[5, 5], hi=[25, 25], spring_radius=1.0)],
        )
    )
    built = build_particles(scene)
    deg = np.bincount(np.concatenate([built.spring_i, built.spring_j]), minlength=built.count)
    assert deg.max() == 6 and np.allclose(built.rest_length, 1.0)
    # mass = density * area per site (sqrt(3)/2 for unit spacing)
    assert np.allclose(built.mass, math.sqrt(3) / 2)


def test_fcc_has_twelve_neighbours_and_disk_is_round():
    scene = make_scene(
        scene_dict(
            dim=3,
            bodies=[
                {
                    "material": "jelly",
                    "shape": "box",
                    "lattice": "fcc",
                    "lo": [2, 2, 2],
                    "hi": [14, 14, 14],
                    "spring_radius": 1.0,
                }
            ],
        )
    )
    built = build_particles(scene)
    deg = np.bincount(np.concatenate([built.spring_i, built.spring_j]), minlength=built.count)
    assert deg.max() == 12
    disk = make_scene(
        scene_dict(
            world={"dim": 2, "lo": [0, 0], "hi": [40, 40]},
            bodies=[{"material": "jelly", "shape": "disk", "center": [20, 20], "radius": 8}],
        )
    )
    built = build_particles(disk)
    r = np.linalg.norm(built.x - 20, axis=1)
    assert r.max() <= 8 + 1e-9
    assert abs(built.count - math.pi * 64) < 0.05 * math.pi * 64  # area / cell area


def test_bond_table_lists_every_spring_at_both_ends():
    built = build_particles(make_scene(scene_dict(bodies=[_body()])))
    table = bond_table(built.spring_i, built.spring_j, built.count, built.max_bonds())
    for s, (i, j) in enumerate(zip(built.spring_i, built.spring_j)):
        assert s in table[i] and s in table[j]
    assert (table >= 0).sum() == 2 * built.spring_count


def test_random_velocity_has_zero_momentum_and_requested_spread():
    scene = make_scene(
        scene_dict(
            world={"dim": 2, "lo": [0, 0], "hi": [100, 100]},
            bodies=[_body(lo=[0, 0], hi=[100, 100], springs=False, random_velocity=2.0)],
        )
    )
    built = build_particles(scene)
    assert np.allclose(built.v.mean(axis=0), 0, atol=1e-12)
    assert built.v.std() == pytest.approx(2.0, rel=0.03)


def test_png_mask_shapes_a_body_the_right_way_up():
    scene = make_scene(
        scene_dict(
            world={"dim": 2, "lo": [0, 0], "hi": [50, 50]},
            bodies=[
                {"material": "jelly", "shape": "mask", "mask": "assets/masks/heart.png", "lo": [10, 10], "hi": [42, 42]}
            ],
        )
    )
    built = build_particles(scene)
    area_fraction = 0.5449  # of the 64 x 64 mask's pixels that are opaque
    assert abs(built.count - area_fraction * 32 * 32) < 0.04 * area_fraction * 32 * 32
    y = built.x[:, 1]
    assert (y > 26).sum() > (y < 26).sum()  # the heart's two lobes are at the top, its point at the bottom
    assert built.x[:, 0].min() >= 10 and built.x[:, 0].max() <= 42
