"""service.api.frames: version 2 carries the robot's surface mesh (``sim.mesh``) once, so
the body grows with the frames by 12 bytes a voxel, as before, plus a fixed mesh."""

from __future__ import annotations

import numpy as np
import pytest

from softevo.service.api.frames import HEADER, decode_frames, encode_frames
from softevo.sim.mesh import lattice_mesh


def motion(n_frames: int) -> dict[str, np.ndarray]:
    voxels = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1]])
    rng = np.random.default_rng(n_frames)
    return {
        "t": np.arange(n_frames) * 0.01,
        "voxels": voxels,
        "material": np.array([1, 2, 2, 1]),
        "positions": (voxels + 0.5) * 0.01 + rng.normal(0, 1e-3, (n_frames, 4, 3)),
    }


def test_frames_round_trip_with_the_mesh():
    data = motion(5)
    decoded = decode_frames(encode_frames(data))
    assert decoded["voxels"].tolist() == data["voxels"].tolist()
    assert decoded["material"].tolist() == [1, 2, 2, 1]
    assert decoded["positions"] == pytest.approx(data["positions"], rel=1e-6)
    _, mesh_vert, mesh_face = lattice_mesh(data["voxels"])
    assert decoded["mesh_vert"].tolist() == mesh_vert.tolist()
    assert decoded["mesh_face"].tolist() == mesh_face.tolist()
    assert len(mesh_face) == 2 * 18  # 4 voxels, 3 bonds: 24 - 6 exposed faces


def test_the_mesh_is_a_fixed_cost_and_frames_cost_12_bytes_a_voxel():
    one, ten = len(encode_frames(motion(1))), len(encode_frames(motion(10)))
    assert ten - one == 9 * (4 + 4 * 12)  # t and positions of 9 more frames
    _, mesh_vert, mesh_face = lattice_mesh(motion(1)["voxels"])
    assert one == HEADER.size + 4 * (1 + 16 + 12) + 4 * (mesh_vert.size + mesh_face.size)


def test_truncated_or_old_files_are_refused():
    data = encode_frames(motion(3))
    with pytest.raises(ValueError, match="expected"):
        decode_frames(data[:-4])
    old = bytearray(data)
    old[4:8] = (1).to_bytes(4, "little")
    with pytest.raises(ValueError, match="version 1"):
        decode_frames(bytes(old))
