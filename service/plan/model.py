"""What an experiment grid costs before it runs: ``plan(treatments, cores=N | gpus=M) -> Plan``.

- Evaluations: each treatment's ``Evolution`` is driven with instant fake results (random
  distances) and the individuals ``ask`` hands out for simulation are counted per
  generation: the first population, each bred generation, and each generation that moves the
  population into another world (an abrupt switch, every compound generation of a gradual
  one and the arrival: the whole population re-evaluated). Small grids (``EXACT_BUDGET``)
  are driven whole, run by run with each run's seed; larger ones through a short probe of the
  same schedule whose counts per kind of generation are multiplied out. Reused evaluations
  (a living twin's) and empty bodies are not simulated and not counted.
- Seconds per evaluation: ``SAMPLE_GENOMES`` random viable genomes of the treatment's
  encoding (seeded), their scenes built by ``worker.tasks.scenes_of`` in each world the
  treatment visits (a gradual span at its middle share), at its stiffness, cycles, model and
  cap on seconds, costed by ``sim.cost.CostModel`` plus the worker's own work per evaluation
  (``WORKER_SECONDS_PER_EVALUATION``): a distribution, not only a mean. Random genomes stand
  for evolved ones (bodies that grow or shrink over a run change the cost).
- Wall time: ``service.plan.model.dispatch`` simulates dispatch on the workers, each generation
  split into jobs as ``service.runs.rq_executor.plan_batches`` splits it, job seconds drawn from
  the distribution plus ``JOB_SECONDS`` each, under ``DISPATCH`` (``"rounds"`` or
  ``"per-run"``), plus the coordinator's ``COORDINATOR_SECONDS`` per run-generation and its
  ``COORDINATOR_ASK_SECONDS`` per run before a run's first jobs are dispatched. Long
  stretches of like generations are simulated on at most ``MAX_SIMULATED`` generations (and
  ``EVENT_BUDGET`` jobs in all) whose seconds are scaled up to the stretch's length.
- GPUs: a round's genomes (all runs) are split evenly over the GPUs; a GPU steps its batch in
  lock-step, ``total voxels x the longest robot's steps / GPU_VOXEL_STEPS_PER_SECOND`` (an
  estimate, not measured); rounds wait for the slowest GPU.
- Storage: rows times the ``BYTES_PER_*`` measured on SQLite.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softevo.errors import UserError
from softevo.evolution import environments
from softevo.evolution.algorithm import Evolution
from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.evolution.outcome import Outcome
from softevo.evolution.runner import ask_generation
from softevo.evolution.treatments import Treatment
from softevo.service.plan.dispatch import Generation, simulate
from softevo.service.runs.executors import EXECUTOR_KINDS
from softevo.service.settings import GENOMES_PER_TASK
from softevo.worker.physics import MEASURED, CostModel, parse_scene, voxel_steps
from softevo.worker.tasks import EmptyBody, Task, scenes_of

DISPATCH = "per-run"  # the coordinator on the RQ executor (service.runs.coordinator.Coordinator.advance)
# what ``softevo experiment`` and ``run`` use (no server: the process pool); ``softevo serve`` with
# Redis uses "rq"
DEFAULT_EXECUTOR = "local"
UNBOUNDED_CORES = 10**9  # cores enough for every genome of every run at once (the floor wall)
USEFUL_MARGIN = 0.1  # useful_cores: the fewest cores whose wall is within 10% of the floor's
USEFUL_PRECISION = 0.1  # ... found to within 10% (a bisection on simulated dispatches)
SAMPLE_GENOMES = 48  # random genomes costed per treatment
EXACT_BUDGET = 4_000  # individual-generations driven whole (sum of population x generations)
PROBE_BREEDS = 3  # bred generations a probe drives before (and after) a switch
MAX_SIMULATED = 50  # generations of a stretch the dispatch simulation simulates
EVENT_BUDGET = 150_000  # jobs the dispatch simulation simulates in all
# Measured on the 2-core development machine, quiet, beside the simulation ``CostModel`` costs:
# - the coordinator's work per run-generation at population 30 (paper settings, 7^3), taken
#   in proportion to the population:
#   - "local" (``softevo run``: the process pool, SQLite): ask + tell + the transaction,
#     23 ms, with instant results (bench/coordinator_overhead.py);
#   - "rq" (``softevo serve`` with Redis workers, PostgreSQL): the coordinator process's CPU
#     per evaluation in bench/scale.py, 1.65 ms (604-607 evaluations per CPU-second at 100
#     workers): 50 ms;
# - a worker's own work per evaluation (developing the genome, descriptors, the result) and
#   a job's round trip: 3 ms and 8 ms, from bench/plan_check.py's 1-worker runs less their
#   coordinator's share and the cost model's simulation seconds.
COORDINATOR_SECONDS = {"local": 0.023, "rq": 0.05}
# - of which a part does not grow with the population (the transaction, the generation's
#   summary, the progress line): the tiny grid (population 6, 72 run-generations) with instant
#   results took 0.99 CPU s on the local executor, 14 ms a run-generation where the share of
#   population 30 alone gave 5 ms (issue 59: bench/coordinator_overhead.py's InstantExecutor
#   driving ``paper_grid("tiny")``). Not measured for "rq": taken as the local one's (the same
#   transaction and summary; Redis adds to it).
COORDINATOR_FIXED_SECONDS = {"local": 0.011, "rq": 0.011}
# - the coordinator's ask of a run's first population (random viable genomes, drawn until the
#   body rule holds) and its dispatch, before any of that run's jobs can start; at the start
#   a coordinator asks its runs one after the other: 50 ms ("rq": ask + RQ submit) and 41 ms
#   ("local": the ask alone), medians over the paper's 12 treatments at population 30.
COORDINATOR_ASK_SECONDS = {"local": 0.041, "rq": 0.05}
assert set(COORDINATOR_SECONDS) == set(COORDINATOR_ASK_SECONDS) == set(COORDINATOR_FIXED_SECONDS) == set(
    EXECUTOR_KINDS)
COORDINATOR_POPULATION = 30
COORDINATOR_TARGET = 0.8  # coordinators_needed keeps each coordinator busy at most this share
# - a worker's own work per evaluation: developing the genome and its descriptors, CPU
#   seconds on random 5^3 genomes (bench/plan_startup.py): 3.2 ms on the idle 2-core Intel Xeon
#   (Sapphire Rapids class), 2026-12-07 (10 ms on a loaded AMD EPYC before, where the tiny
#   preset had come out 1.9x a plan that counted 3 ms without descriptors);
WORKER_SECONDS_PER_EVALUATION = 0.0032
JOB_SECONDS = 0.008
# - the fixed start of one ``softevo run`` / ``experiment`` (the local executor): the command
#   and a new SQLite database (1.46 s), the kernel cache check (1.27 s) and a pool process
#   spawned and warmed, land and water kernels loaded (1.74 s; the processes start side by
#   side): CPU seconds, medians of 3 (bench/plan_startup.py): 0.92 + 1.01 + 1.03 s on the idle
#   2-core Intel Xeon (Sapphire Rapids class), 2026-12-07 (1.46 + 1.27 + 1.74 s on a loaded AMD
#   EPYC before). A cluster's workers are started and warm before a plan's experiment is sent:
#   nothing for "rq".
STARTUP_SECONDS = {"local": 3.0, "rq": 0.0}
# An H200's rate in the cuda engine: ESTIMATE, NOT MEASURED (a GPU design review's
# 1.5-2.2e9 voxel-steps/s, docs/gpu.md); replace it once bench/gpu_device_check.sh has run on
# one.
GPU_VOXEL_STEPS_PER_SECOND = 2.0e9
GPU_RATE_SOURCE = "estimate, not measured: a GPU design review's 1.5-2.2e9 per H200 (docs/gpu.md)"
# Bytes on SQLite (page-rounded, indexes included), measured with dbstat on a 12-generation
# run of population 10 (pareto, 5^3, land-water, paper encoding): an individual (genome and
# phenotype JSON) 2150, an evaluation 378, a generation summary 683, a population member 102,
# a run's stored algorithm state 3280 per population member. Genomes grow over long runs
# (more CPPN nodes): a paper-length run stores more per individual than this.
BYTES_PER_INDIVIDUAL = 2150
BYTES_PER_EVALUATION = 378
BYTES_PER_GENERATION = 683
BYTES_PER_MEMBER = 102
BYTES_PER_STATE_MEMBER = 3280
KINDS = ("first", "bred", "switch")


@dataclass(frozen=True)
class Counts:
    """Per run and kind of generation (``KINDS``): mean individuals simulated, pending
    (evaluations stored) and born (individuals stored)."""

    simulated: dict[str, float]
    stored: dict[str, float]
    born: dict[str, float]
    exact_total: float | None = None  # simulations of all runs, when driven whole


@dataclass(frozen=True)
class Costs:
    """Sampled evaluations in one world: seconds on one core, voxels and steps each."""

    seconds: np.ndarray
    voxels: np.ndarray
    steps: np.ndarray

    @property
    def voxel_steps(self) -> np.ndarray:
        return self.voxels * self.steps


@dataclass(frozen=True)
class Stretch:
    """Generations ``first .. first + count - 1`` of a run: one kind, one world."""

    first: int
    count: int
    kind: str
    world: str


@dataclass(frozen=True)
class TreatmentPlan:
    """One treatment's share of the plan (all its runs)."""

    name: str
    runs: int
    generations: int
    evaluations: int
    voxel_steps: float
    core_seconds: float  # its evaluations' seconds on one core
    database_bytes: int
    seconds_per_evaluation: dict[str, dict[str, float]]  # world -> mean, p10, p50, p90, max

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class Plan:
    """The cost of a grid; see the module doc. Seconds, hours, bytes; utilisation 0..1."""

    wall_seconds: float
    core_hours: float
    gpu_hours: float
    database_bytes: int
    utilisation: float
    evaluations: int
    voxel_steps: float
    cores: int | None
    gpus: int | None
    dispatch: str
    treatments: list[TreatmentPlan]
    cost: dict[str, Any]
    assumptions: list[str] = field(default_factory=list)
    coordinators: int = 1
    executor: str = DEFAULT_EXECUTOR  # whose coordinator cost the plan takes (COORDINATOR_SECONDS)
    coordinator_utilisation: float = 0.0  # the coordinators' busy share: near 1, they limit
    coordinator_seconds: float = 0.0  # the coordinators' work in all (every run-generation)
    # the wall time were coordinators never waited on (one per run): what the workers and
    # each run's own chain of generations allow; the plan's own wall where they do not limit
    unqueued_wall_seconds: float = 0.0
    startup_seconds: float = 0.0  # in wall_seconds: the command's fixed start (STARTUP_SECONDS)
    # device-seconds spent evaluating (jobs running): at most wall x devices, the rest waiting
    busy_seconds: float = 0.0
    # CPU plans: the wall time on unlimited cores (each run's generations one after another,
    # each waiting for its slowest evaluation and its coordinator), and the fewest cores whose
    # wall is within USEFUL_MARGIN of it: past them the wall hardly shrinks
    floor_wall_seconds: float = 0.0
    useful_cores: int | None = None
    longest_run: str = ""  # the treatment whose runs have the most generations (the floor's why)

    def coordinators_needed(self, target: float = COORDINATOR_TARGET) -> int:
        """Coordinator processes that would be busy at most ``target`` of the time at the pace
        the workers allow (fewer: the workers wait on them), at most one per run."""
        runs = sum(t.runs for t in self.treatments)
        wall = self.unqueued_wall_seconds or self.wall_seconds
        if wall <= 0:
            return 1
        return max(1, min(runs, math.ceil(self.coordinator_seconds / (target * wall))))

    @property
    def wall_hours(self) -> float:
        return self.wall_seconds / 3600

    def to_json(self) -> dict[str, Any]:
        """``wall_seconds, core_hours, gpu_hours, database_bytes, utilisation, evaluations,
        voxel_steps`` and the extras (``wall_hours``, ``runs``, ``treatments``, ...)."""
        out = dataclasses.asdict(self)
        out["treatments"] = [t.to_json() for t in self.treatments]
        out["wall_hours"] = self.wall_hours
        out["runs"] = sum(t.runs for t in self.treatments)
        out["evaluation_core_hours"] = sum(t.core_seconds for t in self.treatments) / 3600
        out["coordinators_needed"] = self.coordinators_needed()
        device = "core" if self.cores else "gpu"
        out[f"busy_{device}_hours"], out[f"idle_{device}_hours"] = self.busy_hours, self.idle_hours
        return out

    @property
    def booked_hours(self) -> float:
        """Core- or GPU-hours booked: the wall time on every device."""
        return self.core_hours if self.cores else self.gpu_hours

    @property
    def busy_hours(self) -> float:
        """Of ``booked_hours``, the devices' hours evaluating (jobs running)."""
        return min(self.busy_seconds / 3600, self.booked_hours)

    @property
    def idle_hours(self) -> float:
        """Of ``booked_hours``, the devices' hours waiting: ``booked = busy + idle``."""
        return self.booked_hours - self.busy_hours


def plan(
    treatments: Sequence[Treatment],
    cores: int | None = None,
    gpus: int | None = None,
    cost: CostModel = MEASURED,
    dispatch: str | None = None,
    samples: int = SAMPLE_GENOMES,
    seed: int = 0,
    coordinator_seconds: float | None = None,
    gpu_rate: float = GPU_VOXEL_STEPS_PER_SECOND,
    coordinators: int = 1,
    executor: str = DEFAULT_EXECUTOR,
    ask_seconds: float | None = None,
) -> Plan:
    """The plan of ``treatments`` on ``cores`` CPU workers or ``gpus`` GPUs (exactly one),
    driven by ``coordinators`` coordinator processes (``service.runs.driver``: they split the
    runs) through ``executor``: ``"rq"`` (a cluster: ``softevo serve`` and Redis workers) or
    ``"local"`` (``softevo run``'s process pool), whose coordinator costs differ
    (``COORDINATOR_SECONDS``, ``COORDINATOR_ASK_SECONDS``; ``coordinator_seconds`` and
    ``ask_seconds`` override them) and whose dispatch differs (``dispatch``, default
    ``DISPATCH`` with ``rq``, ``"rounds"`` with ``local``); UserError for neither, both, or
    fewer than 1."""
    check_devices(cores, gpus)
    check_coordinators(coordinators)
    if executor not in EXECUTOR_KINDS:
        raise UserError(f"executor must be one of {', '.join(EXECUTOR_KINDS)} (got {executor!r})")
    if coordinator_seconds is None:
        coordinator_seconds = COORDINATOR_SECONDS[executor]
    if ask_seconds is None:
        ask_seconds = COORDINATOR_ASK_SECONDS[executor]
    if not treatments:
        raise UserError("nothing to plan: no treatment")
    if dispatch is None:  # the local executors advance every run together
        dispatch = "rounds" if executor == "local" else DISPATCH
    rng = np.random.default_rng(seed)
    counts = [count_evaluations(t) for t in treatments]
    costs = [sample_costs(t, cost, samples, seed) for t in treatments]
    lines = [_treatment_plan(t, c, k) for t, c, k in zip(treatments, counts, costs, strict=True)]
    fixed = min(coordinator_seconds, COORDINATOR_FIXED_SECONDS[executor])

    def tell_of(treatment: Treatment) -> float:
        return _coordinator(treatment, coordinator_seconds, fixed)

    def ask_of(treatment: Treatment) -> float:
        return _coordinator(treatment, ask_seconds)

    told = sum(tell_of(t) * t.repetitions * t.generations for t in treatments)

    def dispatch_with(k: int, rng: np.random.Generator, workers: int | None = None) -> tuple[float, float]:
        if gpus is not None:
            return _gpu_dispatch(treatments, counts, costs, workers or gpus, gpu_rate,
                                 lambda t: tell_of(t) / k, rng)
        return _cpu_dispatch(treatments, counts, costs, workers or cores, dispatch, tell_of, rng, k, ask_of)

    wall, busy = dispatch_with(coordinators, rng)
    workers = gpus if gpus is not None else cores
    unqueued = wall
    runs = sum(t.repetitions for t in treatments)
    if wall > 0 and told / (wall * coordinators) > COORDINATOR_TARGET and coordinators < runs:
        unqueued, _ = dispatch_with(runs, np.random.default_rng(seed))  # they limit: how much?
    useful, span = None, wall
    if cores is not None:  # every genome its own job on its own core: the runs' chains alone
        def wall_on(k: int) -> float:
            return dispatch_with(coordinators, np.random.default_rng(seed), k)[0]

        span = wall_on(UNBOUNDED_CORES)
        widest = 2 * sum(t.population * t.repetitions for t in treatments)  # every genome of a round
        useful = useful_cores(wall_on, span, widest, known={cores: wall})
    startup = STARTUP_SECONDS[executor]
    wall, unqueued = wall + startup, unqueued + startup
    return Plan(
        startup_seconds=startup,
        wall_seconds=wall,
        busy_seconds=busy,
        useful_cores=useful,
        floor_wall_seconds=min(span + startup, wall),
        longest_run=longest_run(treatments),
        core_hours=wall * cores / 3600 if cores else 0.0,
        gpu_hours=wall * gpus / 3600 if gpus else 0.0,
        database_bytes=sum(line.database_bytes for line in lines),
        utilisation=min(1.0, busy / (wall * workers)) if wall > 0 else 0.0,
        coordinators=coordinators,
        executor=executor,
        coordinator_utilisation=min(1.0, told / (wall * coordinators)) if wall > 0 else 0.0,
        coordinator_seconds=told,
        unqueued_wall_seconds=unqueued,
        evaluations=sum(line.evaluations for line in lines),
        voxel_steps=sum(line.voxel_steps for line in lines),
        cores=cores,
        gpus=gpus,
        dispatch="rounds" if gpus else dispatch,
        treatments=lines,
        cost={**cost.to_dict(), **_gpu_rate(gpu_rate, gpus)},
        assumptions=_assumptions(gpus is not None, coordinator_seconds, ask_seconds, executor),
    )


def useful_cores(wall_on, floor: float, most: int, known: dict[int, float] | None = None) -> int:
    """The fewest cores whose wall (``wall_on(cores)``, seconds) is within ``USEFUL_MARGIN``
    of ``floor`` (the wall on unlimited cores), searched between 1 and ``most`` (cores enough
    for every job of a round) to ``USEFUL_PRECISION``; ``known``: walls already simulated."""
    walls = dict(known or {})

    def enough(k: int) -> bool:
        if k not in walls:
            walls[k] = wall_on(k)
        return walls[k] <= floor * (1 + USEFUL_MARGIN)

    low, high = 1, max(1, most)  # low: too few unless it is 1; high: enough (or as many as help)
    if enough(low) or not enough(high):
        return low if walls[low] <= floor * (1 + USEFUL_MARGIN) else high
    while high > low * (1 + USEFUL_PRECISION) and high - low > 1:
        middle = int(round(math.sqrt(low * high)))
        low, high = (low, middle) if enough(middle) else (middle, high)
    return high


def longest_run(treatments: Sequence[Treatment]) -> str:
    """The name of the treatment whose runs have the most generations (of those, the one whose
    generations simulate longest: steps per evaluation)."""
    return max(treatments, key=lambda t: (t.generations, t.evaluation.cycles)).name


def _gpu_rate(rate: float, gpus: int | None) -> dict[str, Any]:
    return {"gpu_rate": rate, "gpu_rate_source": GPU_RATE_SOURCE} if gpus else {}


def check_coordinators(coordinators: int) -> None:
    """UserError unless ``coordinators`` is an integer >= 1."""
    if isinstance(coordinators, bool) or not isinstance(coordinators, int) or coordinators < 1:
        raise UserError(f"coordinators must be an integer >= 1 (got {coordinators!r})")


def check_devices(cores: int | None, gpus: int | None) -> None:
    """UserError unless exactly one of ``cores`` and ``gpus`` is given, and it is >= 1."""
    if (cores is None) == (gpus is None):
        raise UserError("give either --cores N or --gpus M (one of them)")
    for name, value in (("cores", cores), ("gpus", gpus)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise UserError(f"{name} must be an integer >= 1 (got {value!r})")


def _assumptions(gpu: bool, coordinator_seconds: float, ask_seconds: float, executor: str) -> list[str]:
    notes = [
        "evaluations counted on the algorithm driven with instant fake results (twins and empty "
        "bodies are not simulated)",
        f"seconds per evaluation from {SAMPLE_GENOMES} random viable genomes per treatment; evolved "
        "bodies may cost more or less",
        f"coordinator ({executor} executor) {coordinator_seconds * 1000:.0f} ms per run-generation at "
        f"population {COORDINATOR_POPULATION}, one generation at a time, and "
        f"{ask_seconds * 1000:.0f} ms to ask a run's first population; "
        f"{WORKER_SECONDS_PER_EVALUATION * 1000:.1f} ms "
        f"of a worker's own per evaluation, {JOB_SECONDS * 1000:.0f} ms per job (measured here)",
        "database bytes measured on SQLite for short runs; genomes grow over long runs",
    ]
    if STARTUP_SECONDS[executor]:
        notes.append(f"{STARTUP_SECONDS[executor]:g} s to start the command, its database and its pool's "
                     "processes (measured here, kernels in numba's cache; a first run compiles them, "
                     "about 100 s more)")
    if gpu:
        notes.append(f"GPU rate {GPU_VOXEL_STEPS_PER_SECOND:.1e} voxel-steps/s: {GPU_RATE_SOURCE}; "
                     "a batch steps in lock-step until its longest robot is done")
    return notes


# -- evaluations ----------------------------------------------------------------------------


def kind_of(treatment: Treatment, generation: int) -> str:
    """``first``, ``switch`` (the population moves to another world) or ``bred``."""
    if generation == 0:
        return "first"
    return "switch" if treatment.schedule().switches_at(generation) else "bred"


def drive(treatment: Treatment, seed: int) -> list[tuple[str, int, int, int]]:
    """Each generation of one run of ``treatment`` with instant fake results: (kind,
    simulated, stored evaluations, born), asked as the coordinator and the local run loop ask
    (``evolution.runner.ask_generation``)."""
    algorithm = Evolution(treatment.evolution_config(seed))
    schedule, fake = treatment.schedule(), np.random.default_rng(seed)
    out = []
    for generation in range(treatment.generations):
        asked = ask_generation(algorithm, schedule, generation)
        pending = list(algorithm.pending)
        born = sum(1 for ind in pending if ind.generation_born == generation)
        out.append((kind_of(treatment, generation), len(asked), len(pending), born))
        algorithm.tell({ind.id: Outcome(float(fake.random())) for ind in asked})
    return out


def probe_of(treatment: Treatment) -> Treatment:
    """A short treatment with the same kinds of generation as ``treatment``."""
    if treatment.switch_generation() is None:
        return dataclasses.replace(treatment, generations=1 + PROBE_BREEDS, repetitions=1)
    over = min(treatment.switch_over, 2)
    switch = 1 + PROBE_BREEDS
    return dataclasses.replace(treatment, switch_at=switch, switch_over=over, repetitions=1,
                               generations=switch + over + 1 + PROBE_BREEDS)


def count_evaluations(treatment: Treatment) -> Counts:
    """Mean simulated / stored / born per run and kind of generation; the exact total when
    the treatment is small enough to drive whole (``EXACT_BUDGET``)."""
    exact = treatment.population * treatment.generations * treatment.repetitions <= EXACT_BUDGET
    if exact:
        rows = [row for r in range(treatment.repetitions) for row in drive(treatment, treatment.seed_of(r))]
    else:
        rows = drive(probe_of(treatment), treatment.seed)
    means = [{kind: float(np.mean([row[i] for row in rows if row[0] == kind] or [0])) for kind in KINDS}
             for i in (1, 2, 3)]
    total = float(sum(row[1] for row in rows)) if exact else None
    return Counts(*means, exact_total=total)


def stretches(treatment: Treatment) -> list[Stretch]:
    """The run's generations as stretches of one kind and world (a gradual span's world is
    its middle share)."""
    schedule, generations = treatment.schedule(), treatment.generations
    switch, over = treatment.switch_generation(), treatment.switch_over
    first = schedule.environment_at(0)
    if switch is None:
        parts = [(0, 1, "first", first), (1, generations - 1, "bred", first)]
    else:
        second = schedule.environment_at(switch + over)
        middle = environments.compound(first, second, 0.5) if over else second
        parts = [(0, 1, "first", first), (1, switch - 1, "bred", first), (switch, over, "switch", middle),
                 (switch + over, 1, "switch", second), (switch + over + 1, generations - switch - over - 1,
                                                         "bred", second)]
    return [Stretch(*part) for part in parts if part[1] > 0]


# -- seconds per evaluation -------------------------------------------------------------------


def sample_costs(treatment: Treatment, cost: CostModel, samples: int, seed: int) -> dict[str, Costs]:
    """Costs of ``samples`` random viable genomes in each world of ``treatment``'s stretches."""
    genomes = sample_genomes(treatment.encoding, samples, seed)
    visited = {stretch.world for stretch in stretches(treatment)}
    return {world: _costs(treatment, genomes, world, cost) for world in visited}


@functools.lru_cache(maxsize=16)
def sample_genomes(encoding: EncodingConfig, samples: int, seed: int) -> tuple:
    """``samples`` random viable genomes of ``encoding`` (seeded; shared by the treatments of
    one encoding)."""
    rng = np.random.default_rng(seed)
    return tuple(random_viable_genotype(rng, encoding) for _ in range(samples))


def _costs(treatment: Treatment, genomes: list, world: str, cost: CostModel) -> Costs:
    seconds, voxels, steps = [], [], []
    for genome in genomes:
        task = Task.from_genome(genome, treatment.evaluation.in_world(world))
        try:
            _, scenes = scenes_of(task)
        except EmptyBody:  # never simulated
            continue
        parsed = [parse_scene(scene) for scene in scenes]
        counted = [voxel_steps(scene) for scene in parsed]
        seconds.append(sum(cost.scene_seconds(scene) for scene in parsed) + WORKER_SECONDS_PER_EVALUATION)
        voxels.append(max(v for v, _ in counted))
        steps.append(sum(s for _, s in counted))
    if not seconds:
        seconds, voxels, steps = [0.0], [0], [0]
    return Costs(np.array(seconds), np.array(voxels, dtype=float), np.array(steps, dtype=float))


def scenes_for_measure(treatments: Sequence[Treatment], budget: float = 4e7, seed: int = 0) -> dict:
    """Scenes by (model, world) for ``sim.cost.measure``: sampled robots of the grid, at most
    about ``budget`` voxel-steps per key (a few seconds each on one core)."""
    out: dict[tuple[str, str], list[dict]] = {}
    work: dict[tuple[str, str], float] = {}
    for treatment in treatments:
        encoding = treatment.encoding
        rng = np.random.default_rng([seed, treatment.seed])
        for world in {w for s in stretches(treatment) for w, _ in environments.parts(s.world)}:
            key = (treatment.model, world)
            genome = random_viable_genotype(rng, encoding)
            task = Task.from_genome(genome, treatment.evaluation.in_world(world))
            try:
                _, (scene,) = scenes_of(task)
            except EmptyBody:
                continue
            voxels, steps = voxel_steps(parse_scene(dict(scene)))
            if out.get(key) and work[key] + voxels * steps > budget:
                continue
            out.setdefault(key, []).append(scene)
            work[key] = work.get(key, 0.0) + voxels * steps
    return out


# -- per treatment ------------------------------------------------------------------------------


def _treatment_plan(treatment: Treatment, counts: Counts, costs: dict[str, Costs]) -> TreatmentPlan:
    runs = treatment.repetitions
    simulated = stored = born = seconds = work = 0.0
    for stretch in stretches(treatment):
        n = counts.simulated[stretch.kind] * stretch.count
        simulated += n
        stored += counts.stored[stretch.kind] * stretch.count
        born += counts.born[stretch.kind] * stretch.count
        seconds += n * float(costs[stretch.world].seconds.mean())
        work += n * float(costs[stretch.world].voxel_steps.mean())
    evaluations = counts.exact_total if counts.exact_total is not None else simulated * runs
    scale = evaluations / simulated if simulated else 0.0  # runs (or the exact count's ratio)
    per_generation = BYTES_PER_GENERATION + treatment.population * BYTES_PER_MEMBER
    per_run_bytes = (born * BYTES_PER_INDIVIDUAL + stored * BYTES_PER_EVALUATION
                     + treatment.generations * per_generation + treatment.population * BYTES_PER_STATE_MEMBER)
    return TreatmentPlan(
        name=treatment.name,
        runs=runs,
        generations=treatment.generations,
        evaluations=int(round(evaluations)),
        voxel_steps=work * scale,
        core_seconds=seconds * scale,
        database_bytes=int(per_run_bytes * runs),
        seconds_per_evaluation={world: _summary(c.seconds) for world, c in sorted(costs.items())},
    )


def _summary(values: np.ndarray) -> dict[str, float]:
    p10, p50, p90 = np.percentile(values, [10, 50, 90])
    return {"mean": float(values.mean()), "p10": float(p10), "p50": float(p50), "p90": float(p90),
            "max": float(values.max())}


# -- dispatch -----------------------------------------------------------------------------------


def phases(treatments: Sequence[Treatment]) -> list[tuple[int, int]]:
    """(first generation, length) of the grid's phases: between any two stretch boundaries of
    any treatment, so that within a phase every run stays in one stretch."""
    edges = {0}
    for treatment in treatments:
        for stretch in stretches(treatment):
            edges.update((stretch.first, stretch.first + stretch.count))
    edges = sorted(edges)
    return [(a, b - a) for a, b in zip(edges, edges[1:], strict=False)]


def _stretch_at(treatment: Treatment, generation: int) -> Stretch | None:
    for stretch in stretches(treatment):
        if stretch.first <= generation < stretch.first + stretch.count:
            return stretch
    return None


def _timeline(treatments, counts, jobs_of) -> tuple[list[tuple[int, float]], list]:
    """The simulated rounds: (phase first generation, weight) and, per run, the stretch of each
    phase; ``jobs_of(treatment, n)`` is the number of jobs of a generation of ``n``."""
    grid = phases(treatments)
    runs = [(t, c) for t, c in zip(treatments, counts, strict=True) for _ in range(t.repetitions)]
    per_round = [sum(jobs_of(t, round(c.simulated[s.kind])) for t, c in runs
                     if (s := _stretch_at(t, first)) is not None) for first, _ in grid]
    cap = max(1, min(MAX_SIMULATED, EVENT_BUDGET // max(1, sum(per_round))))
    rounds = [(first, length / min(length, cap)) for first, length in grid for _ in range(min(length, cap))]
    return rounds, runs


def _cpu_dispatch(treatments, counts, costs, cores, dispatch, tell_of, rng, coordinators, ask_of) -> tuple:
    """(wall, busy worker-seconds) of the runs' generations on ``cores`` workers; ``tell_of``
    and ``ask_of``: a treatment's coordinator seconds per run-generation and first ask."""
    def size_of(t: Treatment, n: int) -> int:  # plan_batches / executors.chunks
        return max(1, min(GENOMES_PER_TASK, math.ceil(n / cores)))

    rounds, runs = _timeline(treatments, counts, lambda t, n: math.ceil(n / size_of(t, n)) if n else 0)
    by_treatment = {id(t): k for t, k in zip(treatments, costs, strict=True)}
    simulated_runs = []
    for treatment, count in runs:
        generations = []
        for first, weight in rounds:
            stretch = _stretch_at(treatment, first)
            if stretch is None:
                continue
            n = int(round(count.simulated[stretch.kind]))
            draws = rng.choice(by_treatment[id(treatment)][stretch.world].seconds, size=n)
            size = size_of(treatment, n) if n else 1
            jobs = np.add.reduceat(draws, np.arange(0, n, size)) + JOB_SECONDS if n else np.zeros(0)
            told = weight * tell_of(treatment)
            asked = ask_of(treatment) if stretch.kind == "first" else 0.0
            generations.append(Generation(jobs * weight, told, asked))
        simulated_runs.append(generations)
    return simulate(simulated_runs, cores, dispatch, coordinators)


def _coordinator(treatment: Treatment, seconds: float, fixed: float = 0.0) -> float:
    """Coordinator seconds at ``treatment``'s population of ``seconds`` measured at
    ``COORDINATOR_POPULATION``, ``fixed`` of them whatever the population."""
    return fixed + (seconds - fixed) * treatment.population / COORDINATOR_POPULATION


def _gpu_dispatch(treatments, counts, costs, gpus, rate, tell_of, rng) -> tuple[float, float]:
    """Rounds of every run's genomes split evenly over the GPUs, each batch in lock-step."""
    rounds, runs = _timeline(treatments, counts, lambda t, n: n)
    by_treatment = {id(t): k for t, k in zip(treatments, costs, strict=True)}
    wall = busy = 0.0
    for first, weight in rounds:
        voxels, steps, told = [], [], 0.0
        for treatment, count in runs:
            stretch = _stretch_at(treatment, first)
            if stretch is None:
                continue
            sample = by_treatment[id(treatment)][stretch.world]
            picks = rng.integers(0, len(sample.seconds), size=int(round(count.simulated[stretch.kind])))
            voxels.append(sample.voxels[picks])
            steps.append(sample.steps[picks])
            told += tell_of(treatment)
        batches = _gpu_batches(np.concatenate(voxels), np.concatenate(steps), gpus, rate)
        wall += weight * (max(batches, default=0.0) + told)
        busy += weight * sum(batches)
    return wall, busy


def _gpu_batches(voxels: np.ndarray, steps: np.ndarray, gpus: int, rate: float) -> list[float]:
    """Seconds of each GPU's batch: its genomes' voxels x its longest robot's steps / rate."""
    order = np.argsort(steps)  # like steps together: less idle in lock-step
    return [float(voxels[part].sum() * steps[part].max() / rate)
            for part in np.array_split(order, gpus) if len(part)]
