"""softevo's voxel physics engine (Voxelyze kind): voxels as 6-DOF bodies joined by beams.

Public API: ``simulate``, ``simulate_many``, ``parse_scene``, ``Scene``, ``SceneError``,
``Result``. See SPEC.md section 1 and docs/contracts.md.
"""

from .engine import Result, simulate, simulate_many
from .scene import Scene, SceneError, parse_scene

__all__ = ["Result", "Scene", "SceneError", "parse_scene", "simulate", "simulate_many"]
