"""The binary format of ``GET /individuals/{id}/frames``: recorded motion as little-endian
float32, behind a 16-byte header.

    offset  type              content
    0       4 bytes           magic b"SVXF"
    4       uint32 LE         format version (1)
    8       uint32 LE         F, number of frames
    12      uint32 LE         V, number of voxels
    16      float32[F]        t: simulated time of each frame, seconds
    ..      float32[V, 4]     per voxel: i, j, k (lattice indices), material (1 passive, 2 active)
    ..      float32[F, V, 3]  positions: voxel centres, metres, frame-major

All arrays are C order, little-endian (``numpy.dtype('<f4')``). The response also carries
the shape in headers: ``X-Frames`` (F), ``X-Voxels`` (V), ``X-Time-Step`` (dt, seconds).
``decode_frames`` reads it back.
"""

from __future__ import annotations

import struct

import numpy as np

MAGIC = b"SVXF"
VERSION = 1
HEADER = struct.Struct("<4sIII")
FLOAT = np.dtype("<f4")


def encode_frames(motion: dict[str, np.ndarray]) -> bytes:
    """Bytes of ``worker.tasks.replay``'s output in the format above."""
    t = np.asarray(motion["t"], dtype=FLOAT)
    voxels = np.column_stack([motion["voxels"], motion["material"]]).astype(FLOAT)
    positions = np.asarray(motion["positions"], dtype=FLOAT)
    n_frames, n_voxels = len(t), len(voxels)
    if positions.shape != (n_frames, n_voxels, 3):
        raise ValueError(f"positions shape {positions.shape} != ({n_frames}, {n_voxels}, 3)")
    header = HEADER.pack(MAGIC, VERSION, n_frames, n_voxels)
    return header + t.tobytes() + voxels.tobytes() + positions.tobytes()


def decode_frames(data: bytes) -> dict[str, np.ndarray]:
    """Inverse of ``encode_frames``: t (F,), voxels (V, 3) int, material (V,) int,
    positions (F, V, 3), all from float32."""
    magic, version, n_frames, n_voxels = HEADER.unpack_from(data)
    if magic != MAGIC or version != VERSION:
        raise ValueError(f"not a softevo frames file (magic {magic!r}, version {version})")
    values = np.frombuffer(data, dtype=FLOAT, offset=HEADER.size)
    expected = n_frames + 4 * n_voxels + 3 * n_frames * n_voxels
    if values.size != expected:
        raise ValueError(f"frames file holds {values.size} floats, expected {expected}")
    t = values[:n_frames]
    voxels = values[n_frames : n_frames + 4 * n_voxels].reshape(n_voxels, 4)
    positions = values[n_frames + 4 * n_voxels :].reshape(n_frames, n_voxels, 3)
    return {
        "t": t,
        "voxels": voxels[:, :3].astype(np.int64),
        "material": voxels[:, 3].astype(np.int64),
        "positions": positions,
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
