"""softevo's voxel physics engine (Voxelyze kind): voxels as 6-DOF bodies joined by beams.

Public API: ``simulate``, ``simulate_many`` (``sim.engines``: on the engine named, numba by
default), ``parse_scene``, ``Scene``, ``SceneError``, ``Result`` (``sim.result``),
``models`` (the physics-model registry: ``models.names()``, ``models.get(name)``,
``models.defaults(name)``), ``worlds`` (the world registry), ``engines`` (the engine
registry), ``largest_component`` (the face-connected part of a body that is simulated),
``scene_dt`` and ``scene_steps`` (the step and the number of steps of a scene's simulation:
the one source of both). See docs/spec.md section 1 and docs/contracts.md. No module here
imports numba until an engine runs (``sim.engines`` imports an engine on first use), so
reading scenes and bodies (``sim.scene``, ``sim.system``) stays light.
"""

from . import engines, models, worlds
from .engines import simulate, simulate_many
from .result import Result
from .scene import Scene, SceneError, parse_scene
from .system import largest_component, scene_dt, scene_steps

__all__ = ["Result", "Scene", "SceneError", "engines", "largest_component", "models", "parse_scene",
           "scene_dt", "scene_steps", "simulate", "simulate_many", "worlds"]

if __name__ != "softevo.sim":  # installed as softevo.sim (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.sim, not {__name__}")
