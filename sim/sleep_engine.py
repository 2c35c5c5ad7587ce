"""The sleep engine: no physics, only the time an evaluation would take.

``simulate_many(scenes, device)`` sleeps for the batch's cost by ``sim.cost.MEASURED`` (its
robots one after another, as one core runs them), then returns a ``Result`` per scene whose
distance is a fixed function of the body (a hash: the same robot always goes as far), so an
evolution on it runs its course. It is for measuring the system around the simulator, not
the robots: ``bench/scale.py`` runs hundreds of such workers on 2 cores, since a sleeping
worker uses no CPU.

``device`` is the speed-up, ``"x<factor>"`` (``"x100"``: a hundredth of the modelled time;
default ``"x1"``), so a bench can make evaluations short without changing their spread.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from .cost import MEASURED, voxel_steps
from .engines import EngineUnavailable
from .result import Result
from .scene import Scene, parse_scene
from .system import largest_component, scene_dt

MAX_DISTANCE = 5.0  # voxel lengths: the sleep engine's distances lie in [0, MAX_DISTANCE)


def speed_up(device: str | None) -> float:
    """The factor of ``device`` ("x<factor>", None: 1); ``EngineUnavailable`` otherwise."""
    if device is None or device == "":
        return 1.0
    try:
        factor = float(device[1:]) if device.startswith("x") else float("nan")
    except ValueError:
        factor = float("nan")
    if not factor > 0 or factor == float("inf"):
        raise EngineUnavailable(
            f"device: the sleep engine takes a speed-up x<factor> > 0, e.g. x100 (got {device!r})")
    return factor


def body_distance(body: np.ndarray) -> float:
    """A distance in [0, MAX_DISTANCE) that is a fixed function of the body's voxels."""
    digest = hashlib.blake2b(np.ascontiguousarray(body, dtype=np.int8).tobytes(), digest_size=8).digest()
    return MAX_DISTANCE * int.from_bytes(digest, "little") / 2.0**64


def simulate_many(scenes: list[dict | Scene], device: str | None = None) -> list:
    """Results of ``scenes`` after sleeping their modelled cost divided by ``device``'s factor."""
    factor = speed_up(device)
    parsed = [s if isinstance(s, Scene) else parse_scene(s) for s in scenes]
    results, seconds = [], 0.0
    for scene in parsed:
        voxels, steps = voxel_steps(scene)
        seconds += MEASURED.seconds(voxels, steps, scene.model, scene.environment.kind)
        body = largest_component(scene.body)
        idx = np.argwhere(body > 0)
        pos = (idx + 0.5) * scene.voxel_size
        com = pos.mean(axis=0) if len(pos) else np.zeros(3)
        distance = body_distance(body)
        move = np.array([distance * scene.voxel_size, 0.0, 0.0])
        dt = scene_dt(scene) if steps else 0.0
        results.append(Result(True, None, dt, steps, scene.total_seconds, idx, pos + move, com,
                              com + move, move, distance, {"t": np.zeros(1), "com": com[None]}))
    time.sleep(seconds / factor)
    return results
