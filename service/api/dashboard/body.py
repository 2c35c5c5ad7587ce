"""``GET /dashboard/api/individuals/{id}/body``: what the replay needs besides the frames.

The frames (``GET /individuals/{id}/frames``) give voxel positions only; the replay also
colours each voxel by material and by its actuation, ``sin(2 pi f (t - settle) + phase)``.
This endpoint expresses the stored genome into the same scene the frames were simulated
from (same task, same ``genome -> scene`` path as the workers) and returns its lattice,
materials, phases and actuation, without simulating anything.
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, HTTPException, Query

from softevo.service.api.deps import ServicesDep
from softevo.service.api.params import IndividualId
from softevo.service.api.schemas import WorldName
from softevo.service.api.stored import stored_task_or_404
from softevo.worker.tasks import EmptyBody, scenes_of

router = APIRouter()



def scene_body(scene: dict[str, Any]) -> dict[str, Any]:
    """Lattice and actuation of a simulator scene, as plain JSON for the replay.

    ``voxels``: one ``[i, j, k, material, phase]`` per voxel (material 1 passive, 2 active;
    phase in radians), in lattice order. Lengths in metres, frequency in Hz, times in s.
    """
    body = np.asarray(scene["body"], dtype=int)
    phase = np.asarray(scene.get("phase", np.zeros(body.shape)), dtype=float)
    actuation = scene["actuation"]
    return {
        "workspace": list(body.shape),
        "voxel_size": float(scene["voxel_size"]),
        "environment": scene["environment"]["kind"],
        "frequency": float(actuation["frequency"]),
        "amplitude": float(actuation["amplitude"]),
        "waveform": actuation.get("waveform", "sine"),
        "settle_seconds": float(scene.get("settle_seconds", 0.0)),
        "voxels": [
            [int(i), int(j), int(k), int(body[i, j, k]), round(float(phase[i, j, k]), 6)]
            for i, j, k in np.argwhere(body > 0)
        ],
    }


@router.get("/api/individuals/{individual_id}/body")
def body(
    individual_id: IndividualId,
    services: ServicesDep,
    environment: Annotated[WorldName | None, Query()] = None,
) -> dict[str, Any]:
    """The individual's body and actuation in ``environment`` (default: that of its latest
    evaluation, as for the frames). 404 for an unknown or never evaluated individual."""

    task = stored_task_or_404(services, individual_id, environment)
    try:
        _, (scene, *_) = scenes_of(task)  # a compound world: its first part's scene
    except EmptyBody as exc:  # as the frames endpoint reports it
        raise HTTPException(404, f"individual {individual_id} has no body: {exc}") from exc
    return scene_body(scene)
