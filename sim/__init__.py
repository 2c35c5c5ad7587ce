"""softevo's voxel physics engine (Voxelyze kind): voxels as 6-DOF bodies joined by beams.

Public API: ``simulate``, ``simulate_many``, ``parse_scene``, ``Scene``, ``SceneError``,
``Result``, ``MODELS`` and ``model_defaults`` (the physics models and the scene defaults of
each), ``largest_component`` (the face-connected part of a body that is simulated),
``scene_dt`` and ``scene_steps`` (the step and the number of steps of a scene's simulation:
the one source of both). See docs/spec.md section 1 and docs/contracts.md. The engine (and
numba) is imported on first use of ``simulate``, ``simulate_many`` or ``Result``, so that
reading scenes and bodies (``sim.scene``, ``sim.system``) stays light.
"""

from typing import Any

from .scene import MODELS, Scene, SceneError, model_defaults, parse_scene
from .system import largest_component, scene_dt, scene_steps

_ENGINE = ("Result", "simulate", "simulate_many")

__all__ = ["MODELS", "Result", "Scene", "SceneError", "largest_component", "model_defaults", "parse_scene",
           "scene_dt", "scene_steps", "simulate", "simulate_many"]


def __getattr__(name: str) -> Any:
    if name in _ENGINE:
        from . import engine

        return getattr(engine, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

if __name__ != "softevo.sim":  # installed as softevo.sim (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.sim, not {__name__}")
