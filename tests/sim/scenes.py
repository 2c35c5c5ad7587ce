"""Scenes shared by the simulator's tests."""

from __future__ import annotations

import math

import numpy as np


def actuated_scene(body: np.ndarray, rng: np.random.Generator, env: str, cycles: int, every: int,
                   **material: float) -> dict:
    """A soft body (5 cm voxels, 1e5 Pa unless ``material`` says) actuated hard at 4 Hz with
    random phases, self-collisions on, recorded every ``every`` steps."""
    return {
        "voxel_size": 0.05,
        "material": {"youngs_modulus": 1e5, **material},
        "environment": {"kind": env},
        "body": body.tolist(),
        "phase": rng.uniform(-math.pi, math.pi, body.shape).tolist(),
        "actuation": {"frequency": 4.0, "amplitude": 0.5},
        "duration": {"cycles": cycles},
        "self_collisions": True,
        "record": {"every": every},
    }
