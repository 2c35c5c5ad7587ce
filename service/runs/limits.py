"""What one request or command may cost: the size limits of ``service.settings.Settings``.

- ``check_workspace(workspace)``: a treatment's workspace holds at most ``max_voxels`` voxels
  (``SOFTEVO_MAX_VOXELS``, default 8000 = 20^3); the API answers 422, the CLI one line and
  exit 2.
- ``check_scene(scene)``: a scene's body holds at most ``max_voxels`` voxels and its
  simulation at most ``max_voxel_steps`` voxel-steps (``SOFTEVO_MAX_VOXEL_STEPS``, default
  2e9: a few minutes on one core), checked before anything is simulated or allocated.

- ``check_treatment(treatment)``: each option of a treatment within what a request may ask,
  as declared (``evolution.options``: an option's ``limit``, else its ``most``; e.g. population,
  generations, cycles, the cap on seconds, the workspace's side, ``sim.scene.MAX_SIDE``): the
  bounds of the REST schema (``service.api.schemas.TreatmentIn`` is made from the same
  declarations), applied by ``softevo run`` up front, so that the CLI takes what the API takes.

Every check raises ``softevo.errors.UserError`` whose message names the limit's variable (or,
for a fixed bound, the figure).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from softevo.errors import UserError
from softevo.evolution import options
from softevo.service.settings import Settings

if TYPE_CHECKING:
    from softevo.evolution.treatments import Treatment

PROBE_FREQUENCY_HZ = 1.0  # the lowest frequency of the linear mapping (EncodingConfig.frequency_range)
SLOWEST_FREQUENCY_HZ = 1e-9  # a probe for mappings without a lowest frequency: the cap decides


def check_treatment(treatment: Treatment) -> None:
    """UserError, with the figure, for a treatment beyond what a request may ask: each
    declared option's limit (``evolution.options.Option.beyond_limit``), then the workspace's
    voxels (``check_workspace``)."""
    for option in options.declared():
        problem = option.beyond_limit(getattr(treatment, option.name))
        if problem is not None:
            raise UserError(problem)
    check_workspace(treatment.workspace)


def _settings(settings: Settings | None) -> Settings:
    return settings if settings is not None else Settings.load()


def check_workspace(workspace: Sequence[int], settings: Settings | None = None) -> None:
    """UserError if the workspace ``(x, y, z)`` holds more voxels than allowed."""
    limit = _settings(settings).max_voxels
    voxels = math.prod(int(n) for n in workspace)
    if voxels > limit:
        shape = "x".join(str(int(n)) for n in workspace)
        raise UserError(
            f"workspace {shape} holds {voxels} voxels, more than the limit of {limit} (SOFTEVO_MAX_VOXELS)"
        )


@functools.lru_cache(maxsize=4096)
def evaluation_steps(treatment: Treatment) -> int:
    """Steps of one evaluation of ``treatment``, an upper bound: ``sim.scene_steps`` of a probe
    robot in each of its worlds (the slowest counts), with the treatment's model (its
    ``dt_fraction`` and ``min_steps_per_cycle``), cycles and settling, at its highest stiffness
    (the top of ``stiffness_range_mpa`` when evolved: a stiffer robot takes a shorter step) and
    the linear mapping's lowest frequency (``PROBE_FREQUENCY_HZ``: a slower robot runs longer;
    the evosoro mapping can go lower: with the treatment's ``max_seconds`` the probe runs at
    ``SLOWEST_FREQUENCY_HZ`` and the cap bounds it, without one such an evaluation stops at the
    scene's ``max_steps``, which caps the count too). The step does not depend on the body's
    size."""
    import numpy as np

    from softevo.evolution.genotype import Phenotype
    from softevo.worker.physics import parse_scene, scene_steps

    stiffness = treatment.stiffness_range_mpa[1] if treatment.evolve_stiffness else treatment.stiffness_mpa
    slowest = treatment.control_mapping != "linear" and treatment.max_seconds is not None
    frequency = SLOWEST_FREQUENCY_HZ if slowest else PROBE_FREQUENCY_HZ
    probe = Phenotype(np.full((1, 1, 1), 2, np.int8), np.zeros((1, 1, 1)), frequency)
    steps = 0
    for world in treatment.environment.split("-"):
        scene = parse_scene(probe.to_scene(world, stiffness * 1e6, treatment.cycles, model=treatment.model,
                                           max_seconds=treatment.max_seconds))
        try:
            world_steps = scene_steps(scene)
        except OverflowError:  # more than an int64: the engine refuses it at max_steps
            world_steps = scene.max_steps
        steps = max(steps, min(world_steps, scene.max_steps))
    return steps


def generation_cost(treatment: Treatment) -> float:
    """Voxel-steps of one generation of one run of ``treatment``, an upper bound: population x
    workspace voxels (the largest body) x ``evaluation_steps``."""
    return float(treatment.population) * math.prod(treatment.workspace) * evaluation_steps(treatment)


def experiment_cost(treatments: Iterable[Treatment]) -> float:
    """Voxel-steps of every run of ``treatments``: the sum of population x generations x
    repetitions x workspace voxels x steps per evaluation (cycles x steps per cycle, settling
    included)."""
    return sum(generation_cost(t) * t.generations * t.repetitions for t in treatments)


def check_experiment(
    treatments: Sequence[Treatment], unfinished: float = 0.0, settings: Settings | None = None
) -> float:
    """The voxel-steps of an experiment of ``treatments``; UserError if it asks more runs than
    ``max_runs_per_request``, more voxel-steps than ``max_request_voxel_steps``, or, with the
    ``unfinished`` voxel-steps the server still has to do, more than
    ``max_server_voxel_steps``."""
    settings = _settings(settings)
    runs = sum(t.repetitions for t in treatments)
    if runs > settings.max_runs_per_request:
        raise UserError(
            f"experiment has {runs} runs, more than the {settings.max_runs_per_request} a request may "
            "ask (SOFTEVO_MAX_RUNS_PER_REQUEST)"
        )
    cost = experiment_cost(treatments)
    if cost > settings.max_request_voxel_steps:
        raise UserError(
            f"experiment costs {cost:.3g} voxel-steps, more than the {settings.max_request_voxel_steps:.3g} "
            "a request may ask (SOFTEVO_MAX_REQUEST_VOXEL_STEPS)"
        )
    if unfinished + cost > settings.max_server_voxel_steps:
        raise UserError(
            f"experiment costs {cost:.3g} voxel-steps and the unfinished runs {unfinished:.3g} more, "
            f"more than the {settings.max_server_voxel_steps:.3g} the server takes on at once "
            "(SOFTEVO_MAX_SERVER_VOXEL_STEPS); wait for runs to finish or cancel some"
        )
    return cost


def scene_cost(scene: Mapping[str, Any]) -> tuple[int, int]:
    """(voxels, steps) the simulation of ``scene`` would take; ``sim.SceneError`` if the scene
    is malformed. Cheap: the body is counted before the robot's arrays are built."""
    import numpy as np

    from softevo.worker.physics import parse_scene, scene_steps

    parsed = parse_scene(dict(scene))
    voxels = int(np.count_nonzero(parsed.body))
    return voxels, -1 if voxels == 0 else scene_steps(parsed)


def check_scene(scene: Mapping[str, Any], settings: Settings | None = None) -> tuple[int, int]:
    """(voxels, steps) of ``scene``; UserError if it is larger or longer than allowed."""
    settings = _settings(settings)
    import numpy as np

    from softevo.worker.physics import parse_scene

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
