"""The binary format of ``GET /individuals/{id}/frames``: recorded motion as little-endian
float32, and the robot's surface mesh as int32, behind a 24-byte header.

    offset  type              content
    0       4 bytes           magic b"SVXF"
    4       uint32 LE         format version (2)
    8       uint32 LE         F, number of frames
    12      uint32 LE         V, number of voxels
    16      uint32 LE         M, number of mesh vertices
    20      uint32 LE         T, number of mesh triangles
    24      float32[F]        t: simulated time of each frame, seconds
    ..      float32[V, 4]     per voxel: i, j, k (lattice indices), material (1 passive, 2 active)
    ..      float32[F, V, 3]  positions: voxel centres, metres, frame-major
    ..      int32[M, 8]       mesh vertices: 8 voxel + corner of each voxel sharing it (-1 pads)
    ..      int32[T, 4]       mesh triangles: 3 vertices (counter-clockwise from outside), voxel

The mesh (``sim.mesh``, the drag's surface mesh) is fixed: a frame's vertex positions follow
from its centres (``sim.mesh.deformed_mesh``; the dashboard computes the same in
``replay.js``), so the body grows with F as version 1's did, 12 V bytes a frame, and the mesh
adds at most 448 V bytes once (M <= 8 V, T <= 12 V).

All arrays are C order, little-endian (``numpy.dtype('<f4')``, ``'<i4'``). The response also
carries the shape in headers: ``X-Frames`` (F), ``X-Voxels`` (V), ``X-Time-Step`` (dt,
seconds). ``decode_frames`` reads it back.
"""

from __future__ import annotations

import struct

import numpy as np

from softevo.worker.physics import lattice_mesh

MAGIC = b"SVXF"
VERSION = 2
HEADER = struct.Struct("<4sIIIII")
FLOAT = np.dtype("<f4")
INT = np.dtype("<i4")


def encode_frames(motion: dict[str, np.ndarray]) -> bytes:
    """Bytes of ``worker.tasks.replay``'s output in the format above."""
    t = np.asarray(motion["t"], dtype=FLOAT)
    voxels = np.column_stack([motion["voxels"], motion["material"]]).astype(FLOAT)
    positions = np.asarray(motion["positions"], dtype=FLOAT)
    n_frames, n_voxels = len(t), len(voxels)
    if positions.shape != (n_frames, n_voxels, 3):
        raise ValueError(f"positions shape {positions.shape} != ({n_frames}, {n_voxels}, 3)")
    _, mesh_vert, mesh_face = lattice_mesh(motion["voxels"])
    header = HEADER.pack(MAGIC, VERSION, n_frames, n_voxels, len(mesh_vert), len(mesh_face))
    mesh = mesh_vert.astype(INT).tobytes() + mesh_face.astype(INT).tobytes()
    return header + t.tobytes() + voxels.tobytes() + positions.tobytes() + mesh


def decode_frames(data: bytes) -> dict[str, np.ndarray]:
    """Inverse of ``encode_frames``: t (F,), voxels (V, 3) int, material (V,) int,
    positions (F, V, 3), all from float32; mesh_vert (M, 8), mesh_face (T, 4) int."""
    magic, version, n_frames, n_voxels, n_vert, n_face = HEADER.unpack_from(data)
    if magic != MAGIC or version != VERSION:
        raise ValueError(f"not a softevo frames file (magic {magic!r}, version {version})")
    floats = n_frames + 4 * n_voxels + 3 * n_frames * n_voxels
    ints = 8 * n_vert + 4 * n_face
    if len(data) != HEADER.size + 4 * (floats + ints):
        raise ValueError(f"frames file of {len(data)} bytes, expected {HEADER.size + 4 * (floats + ints)}")
    values = np.frombuffer(data, dtype=FLOAT, offset=HEADER.size, count=floats)
    mesh = np.frombuffer(data, dtype=INT, offset=HEADER.size + 4 * floats).astype(np.int64)
    t = values[:n_frames]
    voxels = values[n_frames : n_frames + 4 * n_voxels].reshape(n_voxels, 4)
    positions = values[n_frames + 4 * n_voxels :].reshape(n_frames, n_voxels, 3)
    return {
        "t": t,
        "voxels": voxels[:, :3].astype(np.int64),
        "material": voxels[:, 3].astype(np.int64),
        "positions": positions,
        "mesh_vert": mesh[: 8 * n_vert].reshape(n_vert, 8),
        "mesh_face": mesh[8 * n_vert :].reshape(n_face, 4),
    }


def recorded_frames(task, every: int, max_frames: int) -> tuple[bytes, dict[str, str]]:
    """The body and headers of ``GET /individuals/{id}/frames`` for ``task``: its evaluation
    replayed (``worker.tasks.replay``) and encoded; run in the API's background process."""
    from softevo.worker.tasks import replay

    motion = replay(task, every, max_frames)
    headers = {
        "X-Frames": str(len(motion["t"])),
        "X-Voxels": str(len(motion["voxels"])),
        "X-Time-Step": repr(float(motion["dt"])),
    }
    return encode_frames(motion), headers
