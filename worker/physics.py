"""The simulator as the service sees it. Everything ``service/`` needs of ``sim/`` passes
here (STYLE.md: the service reaches physics only through the worker), so that the engine can
change behind one door:

- ``simulate(scene)``, ``parse_scene``, ``scene_steps`` and ``SceneError``: one scene run
  (``softevo simulate``) or sized before anything is run (``service.runs.limits``);
- ``energy_audit(scene)``: where a run's energy comes from and goes (``softevo simulate
  --energy``; ``sim.energy``, which loads numba, imported on first use);
- ``EngineUnavailable``: the error of an engine that cannot run here;
- ``PRECISIONS``: the arithmetic a scene may ask for (``model_options.precision``);
- ``lattice_mesh``: the surface mesh of a body, for the replay frames of the REST API;
- the cost model of ``softevo plan``: ``CostModel``, ``MEASURED``, ``voxel_steps``,
  ``measure``.
"""

from __future__ import annotations

from softevo.sim import SceneError, parse_scene, scene_steps, simulate
from softevo.sim.cost import MEASURED, CostModel, measure, voxel_steps
from softevo.sim.engines import EngineUnavailable
from softevo.sim.mesh import lattice_mesh
from softevo.sim.models import PRECISIONS


def energy_audit(scene: dict, engine: str = "numba", final_positions=None) -> dict:
    """The energy audit of one scene (``sim.energy.audit``) as plain JSON values: the
    ``energy`` object of ``softevo simulate --json --energy``. ``final_positions``: the
    engine's own run's, compared with the audited run's (``engine_agreement``, metres)."""
    from softevo.sim import energy

    return energy.audit(scene, engine=engine, final_positions=final_positions).summary()


__all__ = [
    "MEASURED",
    "PRECISIONS",
    "CostModel",
    "EngineUnavailable",
    "SceneError",
    "energy_audit",
    "lattice_mesh",
    "measure",
    "parse_scene",
    "scene_steps",
    "simulate",
    "voxel_steps",
]
