"""The self-contact policy (``sim.physics``: MAX_CONTACTS candidates per voxel, no silent
drop), the same on both engines: a body that collapses onto itself stops with a reason."""

from __future__ import annotations

import numpy as np
import pytest

from softevo import sim
from softevo.sim.system import MAX_CONTACTS


def collapsing(model: str) -> dict:
    """A 5^3 body of active voxels that all shrink to a tenth of their size at once (phase
    -pi/2 at amplitude 0.9), in the void: its 98 surface voxels fall within each other's
    contact reach."""
    body = np.full((5, 5, 5), 2)
    return {"body": body.tolist(), "model": model, "environment": {"kind": "void"},
            "actuation": {"amplitude": 0.9, "frequency": 3.0},
            "phase": np.full(body.shape, -np.pi / 2).tolist(), "duration": {"seconds": 0.02}}


@pytest.mark.parametrize("model", sim.models.names())
def test_a_collapsed_body_stops_with_the_reason_on_the_numba_engine(model):
    r = sim.simulate(collapsing(model))
    assert not r.stable and r.distance == 0.0
    assert r.reason.startswith(f"self-contact: a voxel had more than {MAX_CONTACTS} contact "
                               f"candidates at step {r.steps}")
    assert 0 < r.steps < 200
    upright = sim.simulate({**collapsing(model), "phase": None, "actuation": {"amplitude": 0.1}})
    assert upright.stable and upright.reason is None
