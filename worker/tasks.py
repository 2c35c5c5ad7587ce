"""Evaluation tasks and results, and the one path from a genome to a simulated robot.

- ``Task``: one genome to evaluate under an ``evolution.evaluation.EvaluationSpec`` (world,
  Young's modulus, cycles, physics model, cap on seconds, encoding), built by the
  coordinator from the algorithm's individuals (``Task.from_genome``) or from a stored
  individual and its treatment's settings (``Task.from_stored``). ``to_json`` / ``from_json``
  are the wire format every executor and RQ job exchanges:

      {"id": int,                      # the algorithm's id of the individual
       "run_id": int,                  # optional: job ids and logs only
       "generation": int,              # optional: job ids and logs only
       "genome": {...},                # Genotype.to_dict()
       "environment": str,             # a world (sim.worlds) or a compound world, land>water@0.250
       "youngs_modulus": float,        # Pa
       "cycles": int,
       "max_seconds": float,           # optional: the cap on an evaluation's seconds; absent: none
       "workspace": [x, y, z],
       "encoding": {...},              # optional EncodingConfig.to_dict(); wins over workspace
       "model": "voxcad-land-water"}   # optional sim.models name; absent: the default model

  (the keys after ``genome`` are ``EvaluationSpec.to_dict()``).

- ``generation_tasks(algorithm, asked, generation)``: the tasks of one generation's asked
  individuals.
- ``TaskResult``: what an evaluation returns: the task's id, its ``evolution.outcome.Outcome``
  and the phenotype's fields; ``to_json`` / ``from_json`` with the keys ``id, distance,
  stable, error, voxel_count, active_share, frequency, descriptors, phenotype, seconds,
  steps, simulated_seconds`` (the outcome's among them). ``failed(task, reason)`` is the
  result of any evaluation that could not finish (worst fitness, the reason kept); a
  finished one is scored by ``Outcome.of_simulation``. ``result_problem(data, id)`` says what is wrong with a
  result received from elsewhere (None: nothing).
- ``scene_of(task)``: (phenotype, scene) of a task in a pure world, the scene the evaluation
  simulates; ``scenes_of(task)``: (phenotype, scenes) for any world, one scene per part of a
  compound world (``evolution.environments``: a gradual transition's ``land>water@0.250`` runs
  75% of the cycles on land, then 25% in water). Both develop the genome and hand it to
  ``evolution.evaluation.evaluation_scenes``, the path the local run loop takes too;
  ``evolution.outcome.Outcome.combine`` adds the parts' distances.
- ``replay(task, every)``: the evaluation simulated again with frames recorded (the
  simulator is deterministic: the motion is the one that was evaluated).
- ``EmptyBody``: the error of a genome that develops no voxel (its message is the result's
  ``error``); ``default_record_every(scene)``: steps between frames for about ``DEFAULT_RECORD_FPS``
  frames per simulated second.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.outcome import Outcome

DEFAULT_RECORD_FPS = 60.0  # frames per simulated second of a replay without ``every``
MAX_FRAMES = 2000  # frames a replay keeps at most when ``max_frames`` is given


class EmptyBody(ValueError):
    """A genome that develops no voxel: nothing to simulate (the result's error is the
    message, "empty body")."""


@dataclass(frozen=True)
class Task:
    """One genome to evaluate with the ``EvaluationSpec`` it is evaluated under; see the
    module doc for its JSON."""

    id: int | None
    genome: dict[str, Any]
    evaluation: EvaluationSpec
    run_id: int | None = None
    generation: int | None = None

    @classmethod
    def from_genome(
        cls,
        genome,
        evaluation: EvaluationSpec,
        id: int | None = 0,
        run_id: int | None = None,
        generation: int | None = None,
    ) -> Task:
        """A task of ``genome`` (a ``Genotype`` or its ``to_dict()``) under ``evaluation``."""
        genome = genome if isinstance(genome, dict) else genome.to_dict()
        return cls(id=id, genome=genome, evaluation=evaluation, run_id=run_id, generation=generation)

    @classmethod
    def from_stored(
        cls,
        individual_id: int,
        genome: dict[str, Any],
        settings: Mapping[str, Any],
        environment: str,
        youngs_modulus: float,
    ) -> Task:
        """The task of a stored individual: its genome (``Genotype.to_dict()`` JSON), its
        treatment's settings (``EvaluationSpec.from_settings``: older settings read with
        their defaults) and the environment and Young's modulus (Pa) of the evaluation to
        reproduce."""
        spec = EvaluationSpec.from_settings(settings, environment, youngs_modulus)
        return cls.from_genome(genome, spec, id=int(individual_id))

    @property
    def environment(self) -> str:
        """The world the task is evaluated in (``evaluation.environment``)."""
        return self.evaluation.environment

    def to_json(self) -> dict[str, Any]:
        """The wire format (module doc); ``from_json(t.to_json()) == t``."""
        out: dict[str, Any] = {"id": self.id}
        if self.run_id is not None:
            out["run_id"] = self.run_id
        if self.generation is not None:
            out["generation"] = self.generation
        out["genome"] = self.genome
        out.update(self.evaluation.to_dict())
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Task:
        """A task from its JSON (unknown keys are ignored); KeyError if one is missing."""
        return cls(
            id=data["id"],
            genome=data["genome"],
            evaluation=EvaluationSpec.from_dict(data),
            run_id=data.get("run_id"),
            generation=data.get("generation"),
        )


def generation_tasks(algorithm, asked, generation: int, run_id: int | None = None) -> list[dict[str, Any]]:
    """The JSON tasks of the individuals ``asked`` of an ``evolution.Evolution`` at
    ``generation``, in the algorithm's current world (the schedule's, after a switch), as
    the coordinator and ``softevo.evolve`` hand them to ``worker.evaluate.evaluate_batch``."""
    spec = algorithm.config.evaluation.in_world(algorithm.environment)
    return [
        Task.from_genome(ind.genome, spec, id=ind.id, run_id=run_id, generation=generation).to_json()
        for ind in asked
    ]


@dataclass(frozen=True)
class TaskResult:
    """The result of one task: its ``id``, the ``outcome`` (``evolution.outcome.Outcome``:
    distance, stability, error, shape descriptors, steps and simulated seconds), what the
    phenotype is (``voxel_count``, ``active_share``, ``frequency``, the ``phenotype`` summary)
    and the wall ``seconds`` it took (the batch's simulator call shared over its robots).
    See the module doc for its JSON, the outcome's keys among the others."""

    id: int | None
    outcome: Outcome
    voxel_count: int = 0
    active_share: float = 0.0
    frequency: float | None = None
    phenotype: dict[str, Any] | None = field(default=None, repr=False)  # body arrays: not in repr
    seconds: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """The wire format, keys in ``RESULT_KEYS`` order."""
        fields = {"id": self.id, **self.outcome.to_json(), "voxel_count": self.voxel_count,
                  "active_share": self.active_share, "frequency": self.frequency,
                  "phenotype": self.phenotype, "seconds": self.seconds}
        return {key: fields[key] for key in RESULT_KEYS}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TaskResult:
        """The result of its JSON; absent phenotype fields read as their defaults."""
        return cls(data["id"], Outcome.from_json(data),
                   **{key: data[key] for key in ENVELOPE_KEYS if key in data})

    @classmethod
    def of(cls, task: Task | Mapping[str, Any], outcome: Outcome, phenotype=None, seconds: float = 0.0,
           describe: bool = True) -> TaskResult:
        """The result of ``task`` (a ``Task`` or its JSON) with ``outcome``, scored already
        (``Outcome.of_simulation``); with ``phenotype``, its fields and, unless
        ``describe=False``, its shape descriptors (off for the sleep engine's workers, which
        measure the system around the simulator, not the robots)."""
        task_id = task.id if isinstance(task, Task) else task["id"]
        if phenotype is None:
            return cls(task_id, outcome, seconds=seconds)
        descriptors = _descriptors(phenotype) if describe else None
        return cls(
            task_id,
            outcome.with_descriptors(descriptors),
            voxel_count=int(phenotype.voxel_count),
            active_share=float(phenotype.active_share),
            frequency=float(phenotype.frequency),
            phenotype=json_ready(phenotype.summary()),
            seconds=seconds,
        )


RESULT_KEYS = ("id", "distance", "stable", "error", "voxel_count", "active_share", "frequency",
               "descriptors", "phenotype", "seconds", "steps", "simulated_seconds")
ENVELOPE_KEYS = ("voxel_count", "active_share", "frequency", "phenotype", "seconds")


def result_problem(data: Any, task_id: Any) -> str | None:
    """What is wrong with ``data`` as the JSON result of the task ``task_id`` (None: it is
    one): a dict with that ``id``, a finite number ``distance``, a bool ``stable`` and a
    string or null ``error``. The receiving side checks every result it did not compute."""
    if not isinstance(data, dict):
        return f"a result must be a JSON object, got {type(data).__name__}"
    if data.get("id") != task_id:
        return f"result for task {data.get('id')!r} where task {task_id!r} was expected"
    distance = data.get("distance")
    if isinstance(distance, bool) or not isinstance(distance, int | float) or not math.isfinite(distance):
        return f"task {task_id}: distance must be a finite number, got {distance!r:.40}"
    if not isinstance(data.get("stable"), bool):
        return f"task {task_id}: stable must be true or false, got {data.get('stable')!r:.40}"
    if not (data.get("error") is None or isinstance(data.get("error"), str)):
        return f"task {task_id}: error must be a string or null"
    return None


def failed(task: Task | Mapping[str, Any], reason: str, phenotype=None) -> TaskResult:
    """The result of an evaluation that could not finish (a bad genome, a crash, a lost
    job): ``Outcome.failure(reason)``. ``task`` may be a ``Task`` or its JSON (KeyError
    without an ``id``)."""
    return TaskResult.of(task, Outcome.failure(reason), phenotype)


def _descriptors(phenotype) -> dict[str, float] | None:
    """Shape descriptors (symmetry, branching, shape_entropy, ...); never fails."""
    try:
        from softevo.evolution.descriptors import describe_phenotype

        return json_ready(describe_phenotype(phenotype))
    except Exception as exc:  # descriptors never fail an evaluation
        return {"error": f"{type(exc).__name__}: {exc}"}


def json_ready(value: Any) -> Any:
    """Numpy scalars and arrays to plain JSON types (RQ's JSON serialiser needs them)."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def scene_of(task: Task, **extra: Any):
    """(phenotype, scene) of ``task``: the genome developed in its encoding and placed in
    its environment; ``extra`` scene fields (e.g. ``record``) are added. ValueError
    (``EmptyBody``) for a genome without voxels, ValueError for a compound world (its
    evaluation is several scenes: ``scenes_of``)."""
    from softevo.evolution import environments

    if environments.is_compound(task.environment):
        raise ValueError(f"{task.environment} is a compound world of several scenes: use scenes_of")
    phenotype, (scene,) = scenes_of(task, **extra)
    return phenotype, scene


def scenes_of(task: Task, **extra: Any):
    """(phenotype, [scene, ...]): the genome developed in its encoding, and one scene per
    part of the task's world (``evolution.evaluation.evaluation_scenes``: a compound world's
    parts each run their share of the cycles and of the cap on seconds). A pure world gives
    the one scene of ``scene_of``. ``EmptyBody`` for a genome without voxels."""
    from softevo.evolution.genotype import Genotype, develop

    phenotype = develop(Genotype.from_dict(task.genome), task.evaluation.encoding)
    if phenotype.voxel_count == 0:
        raise EmptyBody("empty body")
    return phenotype, task.evaluation.scenes(phenotype, **extra)


def default_record_every(scene: Mapping[str, Any], fps: float = DEFAULT_RECORD_FPS) -> int:
    """Steps between frames for about ``fps`` frames per simulated second of ``scene``, at
    the engine's step (``sim.scene_dt``)."""
    from softevo.sim import parse_scene, scene_dt

    return max(1, int(round(1.0 / (fps * scene_dt(parse_scene(dict(scene)))))))


def replay(
    task: Task | Mapping[str, Any],
    every: int | None = None,
    max_frames: int | None = None,
    threads: int | None = 1,
) -> dict[str, np.ndarray]:
    """Simulate ``task`` again recording voxel positions every ``every`` steps (default
    ``default_record_every``); with ``max_frames``, keep at most that many frames (and at
    most ``MAX_FRAMES``) evenly spread, the first and last kept; at most twice as many are
    recorded (``every`` raised as needed), so memory stays bounded however long the evaluation.

    Returns:
        t: (F,) float64 seconds of simulated time.
        voxels: (V, 3) int64 lattice indices (i, j, k) of the simulated voxels.
        material: (V,) int64, 1 passive, 2 active.
        positions: (F, V, 3) float64 voxel centres, metres.
        dt: () float64 time step, seconds; stable: () bool.
        distance: () float64 distance, voxel lengths (the evaluated one when stable).
        voxel_size: () float64 voxel edge, metres.
    Raises ``EmptyBody`` for a genome with an empty body.
    """
    from softevo import sim

    task = task if isinstance(task, Task) else Task.from_json(task)
    phenotype, scenes = scenes_of(task)
    every = int(every if every is not None else default_record_every(scenes[0]))
    if max_frames is not None:  # record at most twice the frames kept: bounded memory
        steps = sum(sim.scene_steps(sim.parse_scene(dict(scene))) for scene in scenes)
        every = max(every, math.ceil(steps / (2 * min(int(max_frames), MAX_FRAMES))))
    for scene in scenes:
        scene["record"] = {"every": every}
    results = sim.simulate_many(scenes, threads=threads)
    voxels = np.asarray(results[0].voxels, dtype=np.int64).reshape(-1, 3)
    t, positions = _joined_frames(results, len(voxels))
    outcome = Outcome.combine([Outcome.of_result(result) for result in results])
    index = np.arange(len(t))
    if max_frames is not None and len(t):
        keep = min(len(t), max(1, min(int(max_frames), MAX_FRAMES)))
        index = np.unique(np.linspace(0, len(t) - 1, keep).round().astype(int))
    material = np.asarray(phenotype.body, dtype=np.int64)[tuple(voxels.T)]
    return {
        "t": t[index],
        "voxels": voxels,
        "material": material,
        "positions": positions[index],
        "dt": np.float64(min(result.dt for result in results)),
        "stable": np.bool_(outcome.stable),
        "distance": np.float64(outcome.distance if outcome.stable else 0.0),
        "voxel_size": np.float64(scenes[0]["voxel_size"]),
    }


def _joined_frames(results: list[Any], n_voxels: int) -> tuple[np.ndarray, np.ndarray]:
    """(t, positions) of the parts' frames one after the other: each later part starts at
    the time the previous one ended (its first frame dropped), moved horizontally to where
    the body's centre was."""
    times, moves = [], []
    offset_t, offset_xy = 0.0, np.zeros(2)
    for result in results:
        t = np.asarray(result.frames["t"], dtype=float) if result.frames else np.zeros(0)
        positions = (
            np.asarray(result.frames["positions"], dtype=float).reshape(len(t), n_voxels, 3)
            if result.frames
            else np.zeros((0, n_voxels, 3))
        )
        if times and len(t):  # its first frame is the previous part's last moment: dropped
            start_xy = positions[0, :, :2].mean(axis=0)
            t, positions = t[1:], positions[1:].copy()
            positions[:, :, :2] += offset_xy - start_xy
        if len(t):
            offset_xy = positions[-1, :, :2].mean(axis=0)
        times.append(t + offset_t)
        moves.append(positions)
        offset_t += float(result.simulated_seconds)
    return np.concatenate(times), np.concatenate(moves)
