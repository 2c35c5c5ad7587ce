"""What one request or command may cost: the size limits of ``service.settings.Settings``.

- ``check_workspace(workspace)``: a treatment's workspace holds at most ``max_voxels`` voxels
  (``SOFTEVO_MAX_VOXELS``, default 8000 = 20^3); the API answers 422, the CLI one line and
  exit 2.
- ``check_scene(scene)``: a scene's body holds at most ``max_voxels`` voxels and its
  simulation at most ``max_voxel_steps`` voxel-steps (``SOFTEVO_MAX_VOXEL_STEPS``, default
  2e9: a few minutes on one core), checked before anything is simulated or allocated.

Every check raises ``softevo.errors.UserError`` whose message names the limit's variable.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from softevo.errors import UserError
from softevo.service.settings import Settings


def _settings(settings: Settings | None) -> Settings:
    return settings if settings is not None else Settings()


def check_workspace(workspace: Sequence[int], settings: Settings | None = None) -> None:
    """UserError if the workspace ``(x, y, z)`` holds more voxels than allowed."""
    limit = _settings(settings).max_voxels
    voxels = math.prod(int(n) for n in workspace)
    if voxels > limit:
        shape = "x".join(str(int(n)) for n in workspace)
        raise UserError(
            f"workspace {shape} holds {voxels} voxels, more than the limit of {limit} (SOFTEVO_MAX_VOXELS)"
        )


def scene_cost(scene: Mapping[str, Any]) -> tuple[int, int]:
    """(voxels, steps) the simulation of ``scene`` would take; ``sim.SceneError`` if the scene
    is malformed. Cheap: the body is counted before the robot's arrays are built."""
    import numpy as np

    from softevo.sim import parse_scene
    from softevo.sim.system import I_STEPS, build_robot

    parsed = parse_scene(dict(scene))
    voxels = int(np.count_nonzero(parsed.body))
    return voxels, -1 if voxels == 0 else int(build_robot(parsed).iparams[I_STEPS])


def check_scene(scene: Mapping[str, Any], settings: Settings | None = None) -> tuple[int, int]:
    """(voxels, steps) of ``scene``; UserError if it is larger or longer than allowed."""
    settings = _settings(settings)
    import numpy as np

    from softevo.sim import parse_scene

    body = np.asarray(parse_scene(dict(scene)).body)
    voxels = int(np.count_nonzero(body))
    if voxels > settings.max_voxels:
        raise UserError(
            f"scene body holds {voxels} voxels, more than the limit of {settings.max_voxels} "
            "(SOFTEVO_MAX_VOXELS)"
        )
    try:
        voxels, steps = scene_cost(scene)
    except OverflowError:  # more steps than an int64 holds (duration.cycles: 1e300)
        raise UserError(
            f"scene's duration needs more steps than can be counted, far more than the limit of "
            f"{settings.max_voxel_steps:.3g} voxel-steps (SOFTEVO_MAX_VOXEL_STEPS)"
        ) from None
    if voxels * max(steps, 0) > settings.max_voxel_steps:
        raise UserError(
            f"scene needs {voxels} voxels x {steps:,} steps = {voxels * steps:.3g} voxel-steps, "
            f"more than the limit of {settings.max_voxel_steps:.3g} (SOFTEVO_MAX_VOXEL_STEPS)"
        )
    return voxels, steps
