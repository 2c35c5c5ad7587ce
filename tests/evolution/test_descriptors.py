"""Descriptors on shapes whose values are computed by hand below.

The three flat shapes lie in the xy plane, one voxel thick (z = 0):

    L (2x2):      cross (3x3):     hollow frame (3x3):
    x=0: 1 1      x=0: 0 1 0       x=0: 1 1 1
    x=1: 1 0      x=1: 1 1 1       x=1: 1 0 1
                  x=2: 0 1 0       x=2: 1 1 1
    (rows x, columns y)
"""

import numpy as np
import pytest

from softevo.evolution.descriptors import (
    branching_index,
    describe,
    shape_entropy,
    symmetry_axes,
    symmetry_index,
)
from tests.evolution._descriptor_reference import surface_mesh


def flat(rows):
    return np.array(rows, dtype=np.int8)[:, :, None]


L_SHAPE = flat([[1, 1], [1, 0]])
CROSS = flat([[0, 1, 0], [1, 1, 1], [0, 1, 0]])
FRAME = flat([[1, 1, 1], [1, 0, 1], [1, 1, 1]])


def entropy_bits(*counts):
    p = np.array(counts) / sum(counts)
    return float(-(p * np.log2(p)).sum())


def test_full_cube():
    cube = np.ones((3, 3, 3), dtype=np.int8)
    assert symmetry_index(cube) == 1.0
    assert branching_index(cube) == pytest.approx(0.0, abs=1e-12)
    # 56 surface vertices: 8 corners (pi/2); 24 on edges and 24 on faces, all flat (0)
    assert shape_entropy(cube) == pytest.approx(entropy_bits(8, 48))
    mesh = surface_mesh(cube)
    assert mesh.is_watertight and mesh.volume == pytest.approx(27.0)


def test_branching_by_hand():
    # L: volume 3; hull = 2x2 square minus the half-voxel triangle at the empty corner = 3.5
    assert branching_index(L_SHAPE) == pytest.approx(1 - 3 / 3.5)
    # cross: volume 5; hull = octagon = 3x3 minus four corner triangles of 1/2 = 7
    assert branching_index(CROSS) == pytest.approx(1 - 5 / 7)
    # frame: volume 8; hull = the full 3x3 square = 9
    assert branching_index(FRAME) == pytest.approx(1 - 8 / 9)


def test_shape_entropy_by_hand():
    # Every vertex of the surface counts, flat ones included. A flat shape one voxel thick
    # has a vertex above and below each 2-D grid point of its outline: a convex 2-D corner
    # gives defect pi/2 (top pi/2 + two wall quads), a reflex one -pi/2 (top 3 pi/2 + two
    # walls), a point on a straight side or inside the shape 0.
    # L: 8 grid points = 5 convex, 1 reflex, 2 on straight sides -> 10, 2, 4
    assert shape_entropy(L_SHAPE) == pytest.approx(entropy_bits(10, 2, 4))
    # cross: 12 grid points = 8 convex, 4 reflex, none flat -> 16, 8
    assert shape_entropy(CROSS) == pytest.approx(entropy_bits(16, 8))
    # frame: 16 grid points = 4 convex outer corners, 4 reflex hole corners, 8 on the sides
    # -> 8, 8, 16 -> 1.5 bits
    assert shape_entropy(FRAME) == pytest.approx(1.5)
    # one voxel: 8 corners -> 0; a 2x1x1 bar: 8 corners and 4 straight-edge vertices
    assert shape_entropy(np.ones((1, 1, 1))) == 0.0
    assert shape_entropy(np.ones((2, 1, 1))) == pytest.approx(entropy_bits(8, 4))
    assert entropy_bits(8, 4) == pytest.approx(0.9183, abs=1e-4)


def test_shape_entropy_counts_the_flat_share_of_the_surface():
    # a 4x2x3 box: 5*3*4 - 3*1*2 = 54 surface vertices, 8 corners, 46 flat
    assert shape_entropy(np.ones((4, 2, 3))) == pytest.approx(entropy_bits(8, 46))
    # more flat surface around the same 8 corners: less entropy
    assert shape_entropy(np.ones((6, 6, 6))) < shape_entropy(np.ones((2, 2, 2)))
    rng = np.random.default_rng(0)
    ragged = (rng.random((6, 6, 6)) < 0.55).astype(np.int8)
    assert shape_entropy(ragged) > 1.5 > shape_entropy(CROSS)


def slice_shares(rows):
    """The six shares of one 2-D slice (rows x, columns y): a flat body's shares along z."""
    return symmetry_axes(np.array(rows, dtype=np.int8)[:, :, None])[2]


# Six shares per slice: (r_v, r_h, r_pd, r_sd, t_v, t_h), intersection over union.
def test_slice_shares_by_hand():
    # L slice [[1,1],[1,0]]: columns reversed [[1,1],[0,1]] overlaps 2 of 4 -> 1/2; rows
    # reversed likewise 1/2; transpose is itself -> 1; anti-transpose [[0,1],[1,1]] -> 2/4;
    # top row [1,1] vs bottom [1,0] -> 1/2; left column vs right column -> 1/2.
    shares = slice_shares([[1, 1], [1, 0]])
    assert shares == pytest.approx([0.5, 0.5, 1.0, 0.5, 0.5, 0.5])
    # column [1,0,1] (3x1): reflections of rows/columns -> 1; padded to 3x3 its transpose is
    # the row [1,0,1]: overlap (0,0) of union 3 -> 1/3, anti-transpose -> 1/3; odd halves
    # rows 0-1 [1,0] vs rows 1-2 [0,1] -> 0; one column compares with itself -> 1.
    shares = slice_shares([[1], [0], [1]])
    assert shares == pytest.approx([1, 1, 1 / 3, 1 / 3, 0, 1])


def test_symmetry_index_by_hand():
    # L. Along z: one slice, shares above -> (0.5+0.5+1+0.5+0.5+0.5)/6 = 3.5/6.
    # Along x: slices (y, z) of shape 2x1: x=0 [1,1] -> (1, 1, 1/3, 1/3, 1, 1) -> 14/3 / 6;
    #   x=1 [1,0] -> (1, 0, 1, 0, 0, 1) -> 3/6. Along y: the same by the L's diagonal symmetry.
    s_z = 3.5 / 6
    s_x = ((14 / 3) / 6 + 3 / 6) / 2
    assert symmetry_index(L_SHAPE) == pytest.approx((s_z + 2 * s_x) / 3)
    # cross. z: 4 reflections 1; halves rows 0-1 vs 1-2 overlap 2 of 6 -> 1/3 (both ways).
    #   x: [0,1,0] -> (1, 1, 0, 0, 0, 1) = 3/6; [1,1,1] -> (1, 1, 1/5, 1/5, 1, 1) = 4.4/6.
    s_z = (4 + 2 / 3) / 6
    s_x = (3 / 6 + 4.4 / 6 + 3 / 6) / 3
    assert symmetry_index(CROSS) == pytest.approx((s_z + 2 * s_x) / 3)
    # frame. z: 4 reflections 1; halves overlap 4 of 6 -> 2/3 (both ways).
    #   x: [1,1,1] -> 4.4/6 (twice); [1,0,1] -> (1, 1, 1/3, 1/3, 0, 1) = (11/3)/6.
    s_z = (4 + 4 / 3) / 6
    s_x = (2 * 4.4 / 6 + (11 / 3) / 6) / 3
    assert symmetry_index(FRAME) == pytest.approx((s_z + 2 * s_x) / 3)


def test_symmetry_is_invariant_to_position_in_the_workspace():
    big = np.zeros((7, 7, 7), dtype=np.int8)
    big[2:5, 1:4, 3:4] = FRAME
    assert symmetry_index(big) == pytest.approx(symmetry_index(FRAME))


def test_describe_uses_the_largest_component():
    body = np.zeros((5, 5, 1), dtype=np.int8)
    body[:3, :3] = FRAME * 2
    body[4, 4] = 1  # a stray voxel, not face-connected
    result = describe(body, frequency=2.5)
    assert result["voxel_count"] == 8 and result["active_share"] == 1.0
    assert result["branching"] == pytest.approx(1 / 9)
    assert result["frequency"] == 2.5
    assert describe(np.zeros((2, 2, 2)))["voxel_count"] == 0
