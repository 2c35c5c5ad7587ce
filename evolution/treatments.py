"""Treatments (environment schedule, stiffness, sizes, seeds) and the paper's presets.

A treatment's options are declared once, in ``evolution.options`` (name, part, type, default,
bounds or choices, unit, help); ``Treatment`` holds them in four typed parts (evaluation,
schedule, search, seeds) and reads each as an attribute.

A treatment's environment is a world of the registry (``sim.worlds``: ``land``, ``water``,
...) or a transition between two, ``land-water`` (``evolution.environments.transition``). A
transition switches at ``switch_at`` (default: half the generations): generations
``0 .. switch_at - 1`` are evaluated in the first environment, ``switch_at ..`` in the
second, and at ``switch_at`` the whole surviving population is re-evaluated in the new one.
With ``switch_over = G > 0`` the move is gradual: generations ``switch_at .. switch_at + G - 1``
are evaluated in compound worlds (``evolution.environments``; the new world's share of each
evaluation's cycles rising linearly, the population re-evaluated at each), pure second world
from ``switch_at + G``; ``docs/gradual.md`` explains the choice.
Repetition ``r`` of a treatment runs with seed ``seed + r``. In a preset every treatment has
seeds of its own (treatment k from ``seed + first_seed + k * SEED_STRIDE``), so that no two
treatments start from the same population, and the ``study`` scale starts past the
``pilot``'s seeds, so that a study never repeats a pilot run (docs/analysis.md).

The algorithm and the physics: ``algorithm`` is ``pareto`` (the paper's plain 3-objective
Pareto optimisation, mutation only: evosoro's ``ParetoOptimization``, see
``evolution.algorithm``) or ``afpo`` (Age-Fitness Pareto, a named variant: the remedy the paper
names for its algorithm's loss of diversity), or any algorithm registered since
(``evolution.algorithm.register``), such as ``map-elites`` (MAP-Elites over the grid of
``measures``, ``cells`` and ``measure_bounds``: ``grid()``, ``evolution.archive.grid_of``; the
other algorithms take these options' defaults only); ``model`` is the physics model of every
evaluation's scene (``sim.models.names()``: ``voxelyze-2``, or ``voxcad-land-water``, the
paper's own engine, whose ``distance`` is the 3-D displacement in both worlds). The
encoding's paper choices (``evolution.genotype``): ``control_mapping`` ``evosoro-logistic`` (the
scripts' frequency f = 10 / (mean(1/s') + 1.5) Hz of the frequency output read through the
logistic, s' = (1 + s) / 2, so within (0, 4) Hz, and phase offsets in cycles;
``evosoro-bounded`` clips the bipolar reading at 4 Hz, ``evosoro`` leaves it unbounded) and the
body rule ``evosoro`` (bodies with fewer than 30% of the workspace full or 10% active are drawn
or mutated again). Plain treatments default to AFPO,
``voxelyze-2``, the linear 1-5 Hz mapping and any non-empty body, so stored runs and the
quick start keep their meaning (stored settings without these fields read so too);
the paper presets use the paper's four (``PAPER_CHOICES``).

An evaluation lasts ``cycles`` actuation cycles (the paper's text, footnote 3; the fork's own
sample robots stop after InitCmTime + 50 / f: 50 cycles) after settling (the world's: 0.5 s
on land, 0 s in water, the fork files' InitCmTime; ``settle_seconds`` in the stored settings).
``max_seconds`` is a guard against runaway robots, not a protocol: with it an evaluation never
lasts more than that many seconds after settling. The presets set it at 50 cycles of
``GUARD_FREQUENCY_HZ`` (0.1 Hz: 500 s), which binds on about 1% of random robots (the
bounded mapping can go as low as it likes, 50 cycles of 0.01 Hz would last 83 minutes); the
report counts the evaluations it cut. Plain treatments have no cap.

Two encoding options, off by default (``evolution.genotype``): ``evolve_stiffness`` evolves a
Young's modulus per voxel within ``stiffness_range_mpa`` (default the paper's S1..S5,
0.001..10 MPa; the treatment's ``stiffness_mpa`` is then unused by the physics), and
``frequency_per_voxel`` gives each voxel its own actuation frequency. Settings stored before
these options existed read as both off.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from softevo.errors import UserError
from softevo.evolution import environments, options
from softevo.evolution.algorithm import EvolutionConfig
from softevo.evolution.algorithm import get as algorithm_of
from softevo.evolution.archive import Grid, grid_of
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EVOSORO_MAPPINGS, EncodingConfig
from softevo.evolution.options import PARTS, STIFFNESS_RANGE_MPA
from softevo.evolution.schedule import Schedule
from softevo.evolution.selection import Objective, objectives_named
from softevo.sim import models
from softevo.sim import worlds as sim_worlds


def model_names() -> tuple[str, ...]:
    """Every physics model a treatment may name (the simulator's registry, ``sim.models``)."""
    return models.names()


PAPER_WORLDS = environments.PAPER  # the paper's two worlds and its transitions
PAPER_TRANSITIONS = tuple(environments.TRANSITION.join(pair) for pair in (PAPER_WORLDS, PAPER_WORLDS[::-1]))
PAPER_CHOICES = options.paper_choices()  # what the paper presets run (docs/spec.md section 3)
PAPER_CYCLES = 50  # the fork's sample robots: InitCmTime + 50 / f (docs/algorithm.md)
GUARD_FREQUENCY_HZ = 0.1  # the presets' guard on seconds: their cycles at this frequency
PAPER_STIFFNESSES_MPA = (0.001, 0.01, 0.1, 1.0, 10.0)
DERIVED_SETTINGS = ("settle_seconds",)  # written by to_settings for the record, never read
RETIRED_SETTINGS = ("genomes_per_task",)  # stored by older versions (a dispatch setting), ignored


@dataclass(frozen=True, init=False)
class Treatment:
    """One treatment: its ``name`` and four parts, each a record of the options declared for
    it (``evolution.options``): ``evaluation_part``, ``schedule_part``, ``search_part`` and
    ``seeds_part``. Every option reads as an attribute (``treatment.population``), a
    runtime-declared one too. Made as ``Treatment(environment, stiffness_mpa, name=...,
    **options)``; an option left out has its declared default."""

    name: str
    evaluation_part: Any
    schedule_part: Any
    search_part: Any
    seeds_part: Any

    def __init__(self, environment: str | None = None, stiffness_mpa: float | None = None, name: str = "",
                 *, evaluation_part: Any = None, schedule_part: Any = None, search_part: Any = None,
                 seeds_part: Any = None, **values: Any) -> None:
        given: dict[str, Any] = {}
        for record in (evaluation_part, schedule_part, search_part, seeds_part):
            if record is not None:  # a copy's parts (dataclasses.replace), then what it changes
                given.update({f.name: getattr(record, f.name) for f in dataclasses.fields(record)})
        if environment is not None:
            given["environment"] = environment
        if stiffness_mpa is not None:
            given["stiffness_mpa"] = stiffness_mpa
        given.update(values)
        declared = {o.name: o for o in options.declared()}
        unknown = sorted(set(values) - set(declared))
        if unknown:
            raise UserError(f"unknown treatment field(s): {', '.join(unknown)}")
        for option in declared.values():
            value = given.get(option.name, option.default)
            if option.sequence and isinstance(value, list):
                value = tuple(value)
            given[option.name] = value
        for part in PARTS:
            record = options.part_type(part)(**{o.name: given[o.name] for o in options.declared(part)})
            object.__setattr__(self, f"{part}_part", record)
        object.__setattr__(self, "name", name)
        self.validate()
        if not self.name:
            object.__setattr__(self, "name", self.default_name())

    def __getattr__(self, name: str) -> Any:
        """An option's value, read from its part."""
        if not name.startswith("_"):
            for part in PARTS:
                record = self.__dict__.get(f"{part}_part")
                if record is not None and name in record.__dataclass_fields__:
                    return getattr(record, name)
        raise AttributeError(f"'Treatment' object has no attribute {name!r}")

    def __reduce__(self) -> tuple:
        return _treatment_of, (self.name, self.values())

    def __repr__(self) -> str:
        changed = ", ".join(f"{o.name}={getattr(self, o.name)!r}" for o in options.declared()
                            if o.required or getattr(self, o.name) != o.default)
        return f"Treatment(name={self.name!r}, {changed})"

    def values(self) -> dict[str, Any]:
        """Every option's value, by name (declaration order)."""
        return {o.name: getattr(self, o.name) for o in options.declared()}

    def replace(self, **changes: Any) -> Treatment:
        """A copy with ``changes`` (options, or ``name``); the name stays unless changed."""
        return Treatment(name=changes.pop("name", self.name), **{**self.values(), **changes})

    def validate(self) -> None:
        """Raise UserError (one clear line) for an impossible setting: each option's declared
        type, bounds and choices (``Option.validate``), then how options combine."""
        for option in options.declared():
            option.validate(getattr(self, option.name))
        low, high = self.stiffness_range_mpa
        if not low < high:
            raise UserError(f"stiffness range must be two numbers lo < hi within {STIFFNESS_RANGE_MPA[0]}.."
                            f"{STIFFNESS_RANGE_MPA[1]} MPa (got {low:g},{high:g})")
        if self.control_mapping in EVOSORO_MAPPINGS and self.frequency_per_voxel:
            raise UserError(f"control_mapping {self.control_mapping} gives one frequency per robot: "
                            "it cannot be combined with frequency_per_voxel")
        self._validate_switch()
        self._validate_grid()

    def _validate_grid(self) -> None:
        """A MAP-Elites grid (``measures``, ``cells``, ``measure_bounds``) for an algorithm with
        an archive (``evolution.archive.grid_of``); the others take the defaults only."""
        grid_options = ("measures", "cells", "measure_bounds")
        if not algorithm_of(self.algorithm).archive:
            changed = [name for name in grid_options if getattr(self, name) != options.option(name).default]
            if changed:
                raise UserError(f"{', '.join(changed)}: only an algorithm with an archive takes a grid "
                                f"(map-elites; got algorithm {self.algorithm})")
            return
        try:
            grid_of(self)
        except ValueError as exc:
            raise UserError(str(exc)) from None

    def grid(self) -> Grid | None:
        """The MAP-Elites grid of the treatment's runs (``evolution.archive.grid_of``), or None
        for an algorithm without an archive."""
        return grid_of(self) if algorithm_of(self.algorithm).archive else None

    def _validate_switch(self) -> None:
        over = self.switch_over
        if isinstance(over, bool) or not isinstance(over, int) or over < 0:
            raise UserError(f"switch_over must be an integer >= 0 (got {over!r})")
        if over and not environments.is_transition(self.environment):
            raise UserError(f"switch_over needs a transition environment (got {self.environment})")
        if over and self.switch_generation() + over >= self.generations:
            raise UserError(
                f"the switch-over ends at generation {self.switch_generation() + over}: "
                f"needs more than that many generations (got {self.generations})"
            )
        if self.switch_at is None:
            return
        if not environments.is_transition(self.environment):
            raise UserError(f"switch_at needs a transition environment (got {self.environment})")
        if not 1 <= self.switch_at < self.generations:
            raise UserError(f"switch_at must be within 1..{self.generations - 1} (got {self.switch_at})")

    def default_name(self) -> str:
        """E.g. ``land-water S=0.1MPa``; ``land E=evolved f=per-voxel`` with both options."""
        stiffness = "E=evolved" if self.evolve_stiffness else f"S={self.stiffness_mpa:g}MPa"
        frequency = " f=per-voxel" if self.frequency_per_voxel else ""
        gradual = f" over {self.switch_over}" if self.switch_over else ""
        return f"{self.environment} {stiffness}{frequency}{gradual}"

    @property
    def stiffness_pa(self) -> float:
        """Young's modulus in pascals."""
        return self.stiffness_mpa * 1e6

    @property
    def encoding(self) -> EncodingConfig:
        """The ``EncodingConfig`` the treatment's runs express their genomes with (the options
        that set the encoding: ``evolution.options.encoding_of``)."""
        return options.encoding_of(self.values())

    @property
    def evaluation(self) -> EvaluationSpec:
        """The ``EvaluationSpec`` of the treatment's evaluations in its first world (a
        transition's later worlds: ``evaluation.in_world(world)``)."""
        return EvaluationSpec(
            environment=self.environment_at(0),
            youngs_modulus=self.stiffness_pa,
            cycles=self.cycles,
            model=self.model,
            max_seconds=self.max_seconds,
            encoding=self.encoding,
        )

    def objective_list(self) -> tuple[Objective, ...]:
        """The registered objectives the treatment names (``evolution.selection``; the
        paper's when it names none); UserError for a name not registered in this process."""
        try:
            return objectives_named(self.objectives)
        except ValueError as exc:
            raise UserError(f"treatment {self.name}: {exc}") from None

    def evolution_config(self, seed: int) -> EvolutionConfig:
        """The ``EvolutionConfig`` of one run of the treatment with ``seed``. Descriptors are
        computed where the genomes are evaluated (``worker.evaluate``), not at ``tell``."""
        return EvolutionConfig(
            population_size=self.population,
            mode=self.algorithm,
            seed=seed,
            evaluation=self.evaluation,
            descriptors=False,
            objectives=self.objective_list(),
            grid=self.grid(),
        )

    def switch_generation(self) -> int | None:
        """First generation in the second environment (None without a transition)."""
        if not environments.is_transition(self.environment):
            return None
        return self.switch_at if self.switch_at is not None else max(1, self.generations // 2)

    def schedule(self) -> Schedule:
        """The ``evolution.schedule.Schedule``: [(environment, first generation), ...]."""
        switch = self.switch_generation()
        if switch is None:
            return Schedule.static(self.environment)
        first, second = environments.transition(self.environment)
        return Schedule([(first, 0), (second, switch)], spans=[0, self.switch_over])

    def arrival_generation(self) -> int | None:
        """First generation wholly in the second environment (``switch_generation`` plus the
        switch-over; None without a transition)."""
        switch = self.switch_generation()
        return None if switch is None else switch + self.switch_over

    def schedule_text(self) -> str:
        """The schedule as text, e.g. ``land:0,water:50``."""
        return self.schedule().format()

    def environment_at(self, generation: int) -> str:
        """The environment individuals are evaluated in at ``generation``."""
        return self.schedule().environment_at(generation)

    def seed_of(self, repetition: int) -> int:
        """Seed of repetition ``repetition`` (0-based)."""
        return self.seed + repetition

    def settle_seconds(self) -> dict[str, float]:
        """The settling time of an evaluation in each world the treatment visits (seconds;
        ``sim.worlds``: 0.5 on a floor, 0 elsewhere), recorded in the stored settings."""
        transition = environments.is_transition(self.environment)
        names = environments.transition(self.environment) if transition else (self.environment,)
        return {name: float(sim_worlds.get(name).settle_seconds) for name in names}

    def to_settings(self) -> dict[str, Any]:
        """Plain JSON settings (stored in ``treatments.settings``): the name and every option
        (an empty sequence, e.g. no objectives, left out), with the derived ``settle_seconds``
        of each world for the record (``from_settings`` ignores it)."""
        settings: dict[str, Any] = {"name": self.name}
        for option in options.declared():
            value = getattr(self, option.name)
            if not (option.sequence and option.many is not None and not value):
                settings[option.name] = option.to_json(value)
        settings["settle_seconds"] = self.settle_seconds()
        return settings

    @classmethod
    def from_settings(cls, settings: dict[str, Any]) -> Treatment:
        """Inverse of ``to_settings``; settings stored by older versions read too (an absent
        option is its default, ``genomes_per_task`` is ignored); unknown keys are a UserError."""
        declared = {o.name: o for o in options.declared()}
        ignored = {"name", *DERIVED_SETTINGS, *RETIRED_SETTINGS}
        unknown = sorted(set(settings) - set(declared) - ignored)
        if unknown:
            raise UserError(f"unknown treatment field(s): {', '.join(unknown)}")
        values = {key: declared[key].from_json(value) for key, value in settings.items() if key in declared}
        return cls(name=settings.get("name") or "", **values)


def _treatment_of(name: str, values: dict[str, Any]) -> Treatment:
    """The treatment of ``Treatment.__reduce__`` (pickling: a part's class is made at run time)."""
    return Treatment(name=name, **values)


# The quick start's treatment (README: ``softevo run --env land --stiffness 1 --population 8
# --generations 8 --workspace 5,5,5 --cycles 4``): ``softevo.evolve``'s defaults.
QUICK_START = dict(environment=environments.LAND.name, stiffness_mpa=1.0, population=8, generations=8,
                   workspace=(5, 5, 5), cycles=4)

@dataclass(frozen=True)
class Scale:
    """Sizes of a preset scale. The static S3 treatments run ``transition_generations``, as
    long as the transitions (their controls); the other static ones ``generations``."""

    population: int
    generations: int
    transition_generations: int
    workspace: tuple[int, int, int]
    cycles: int
    repetitions: int
    switch_over: int = 0  # the gradual preset's span (generations of compound worlds)
    first_seed: int = 0  # each treatment's first seed past its block's start
    max_seconds: float | None = None  # the guard on an evaluation's seconds (None: cycles/0.1 Hz)

    def guard_seconds(self) -> float:
        """The cap on an evaluation's seconds: ``max_seconds``, or ``cycles`` cycles at
        ``GUARD_FREQUENCY_HZ``."""
        return self.max_seconds if self.max_seconds is not None else self.cycles / GUARD_FREQUENCY_HZ


# tiny: the whole grid in minutes on 2 cores (CI: 2 cycles, capped at 1 s);
# pilot: 3 repetitions on the paper's protocol (50 cycles, the bounded mapping), the grid 10
# generations and the S3 runs 40 (the knee of their fitness curves; docs/results), for
# ``softevo power``; study: the pilot's sizes with the transitions switching at the knee, and
# the repetitions and grid generations that fit about 2 hours of a 2-core machine, on seeds
# past the pilot's (docs/results); small: longer runs of the same; paper: the paper's 5000 / 9000 generations
# and 15 repetitions (a cluster job).
PILOT = Scale(8, 10, 40, (5, 5, 5), PAPER_CYCLES, 3, switch_over=4)
STUDY_REPETITIONS = 6  # what fits about 2 hours of a 2-core machine (softevo plan; docs/results)
STUDY_SWITCH_GENERATIONS = 50  # 25 + 25: the switch at the pilot's knee, 24-26 (docs/results)
STUDY_GRID_GENERATIONS = 20  # the grid's other treatments: what about 1.25 hours allow beside the
# transitions on the logistic mapping (softevo plan: docs/results)
PRESET_SCALES: dict[str, Scale] = {
    "tiny": Scale(6, 6, 6, (5, 5, 5), 2, 1, switch_over=2, max_seconds=1.0),
    "pilot": PILOT,
    "study": dataclasses.replace(PILOT, generations=STUDY_GRID_GENERATIONS,
                                 transition_generations=STUDY_SWITCH_GENERATIONS,
                                 repetitions=STUDY_REPETITIONS, first_seed=PILOT.repetitions),
    "small": Scale(8, 40, 40, (6, 6, 6), PAPER_CYCLES, 2, switch_over=4),
    "paper": Scale(30, 5000, 9000, (7, 7, 7), PAPER_CYCLES, 15, switch_over=1000),
}
SCALES = tuple(PRESET_SCALES)
SEED_STRIDE = 1_000  # seeds per treatment of a preset


def preset_scale(scale: str) -> Scale:
    """The sizes of preset scale ``scale``; UserError for an unknown one."""
    if scale not in PRESET_SCALES:
        raise UserError(f"unknown scale {scale!r}; choose one of {', '.join(SCALES)}")
    return PRESET_SCALES[scale]


def paper_grid(
    scale: str = "tiny", repetitions: int | None = None, seed: int = 0, **choices: str
) -> list[Treatment]:
    """The paper's grid (docs/spec.md section 5): land and water at S1..S5, transitions at S3,
    with the paper's algorithm, model and encoding (``PAPER_CHOICES``; ``choices`` override
    any of them, e.g. ``algorithm="afpo"``).

    The S3 static treatments run as long as the transitions (at paper scale 9000
    generations), as in the paper, for a fair comparison: they are the transitions' controls.
    """
    sizes = preset_scale(scale)
    reps = sizes.repetitions if repetitions is None else repetitions
    common = {
        "population": sizes.population,
        "workspace": sizes.workspace,
        "cycles": sizes.cycles,
        "max_seconds": sizes.guard_seconds(),
        "repetitions": reps,
        "seed": seed,
        **_paper_choices(choices),
    }
    treatments = []
    for environment in PAPER_WORLDS:
        for index, stiffness in enumerate(PAPER_STIFFNESSES_MPA, start=1):
            long = stiffness == 0.1
            generations = sizes.transition_generations if long else sizes.generations
            treatments.append(
                Treatment(
                    environment,
                    stiffness,
                    name=f"{environment} S{index}",
                    generations=generations,
                    **common,
                )
            )
    for environment in PAPER_TRANSITIONS:
        treatments.append(
            Treatment(
                environment,
                0.1,
                name=f"{environment} S3",
                generations=sizes.transition_generations,
                **common,
            )
        )
    return own_seeds(treatments, seed, sizes.first_seed)


def own_seeds(treatments: list[Treatment], seed: int, first_seed: int = 0) -> list[Treatment]:
    """The treatments, treatment k with seeds from ``seed + first_seed + k * SEED_STRIDE``: no
    two share a seed, so their runs are independent samples (UserError if the repetitions
    overflow a block)."""
    if any(first_seed + t.repetitions > SEED_STRIDE for t in treatments):
        raise UserError(f"at most {SEED_STRIDE - first_seed} repetitions per treatment in a preset")
    start = seed + first_seed
    return [t.replace(seed=start + k * SEED_STRIDE) for k, t in enumerate(treatments)]


def gradual_grid(
    scale: str = "tiny", repetitions: int | None = None, seed: int = 0, **choices: str
) -> list[Treatment]:
    """The paper's two transitions at S3 (land-water, water-land), each abrupt and gradual
    (``switch_over`` of the scale: tiny 2, small 4, paper 1000 generations), switching at
    half the generations; same sizes, seeds and choices (``PAPER_CHOICES``, ``choices``
    override them) as ``paper_grid``'s transitions."""
    sizes = preset_scale(scale)
    common = {
        "population": sizes.population,
        "workspace": sizes.workspace,
        "cycles": sizes.cycles,
        "max_seconds": sizes.guard_seconds(),
        "repetitions": sizes.repetitions if repetitions is None else repetitions,
        "seed": seed,
        "generations": sizes.transition_generations,
        **_paper_choices(choices),
    }
    return [
        Treatment(environment, 0.1, name=f"{environment} S3 {kind}", switch_over=over, **common)
        for environment in PAPER_TRANSITIONS
        for kind, over in (("abrupt", 0), ("gradual", sizes.switch_over))
    ]


def _paper_choices(overrides: dict[str, str | None]) -> dict[str, str]:
    """``PAPER_CHOICES`` with the given (non-None) overrides; UserError for an unknown key."""
    unknown = sorted(set(overrides) - set(PAPER_CHOICES))
    if unknown:
        raise UserError(f"a preset cannot set {', '.join(unknown)}")
    return {**PAPER_CHOICES, **{k: v for k, v in overrides.items() if v is not None}}


PRESETS = {"paper": paper_grid, "gradual": gradual_grid}


def select_treatments(treatments: list[Treatment], names: Sequence[str]) -> list[Treatment]:
    """The treatments named in ``names``, in the preset's order and with their seeds in it
    (a subset's runs are the whole preset's runs of those treatments); UserError for a name
    the preset does not hold, or none at all."""
    wanted = [n.strip() for n in names if n.strip()]
    known = [t.name for t in treatments]
    unknown = [n for n in wanted if n not in known]
    if unknown or not wanted:
        raise UserError(f"no treatment {', '.join(map(repr, unknown)) or 'named'} in this preset; "
                        f"it has {', '.join(known)}")
    return [t for t in treatments if t.name in wanted]


def preset_grid(
    preset: str, scale: str = "tiny", repetitions: int | None = None, seed: int = 0, **choices: str | None
):
    """The treatments of preset ``preset`` (``PRESETS``); UserError for an unknown one.
    ``choices`` (``algorithm``, ``model``, ``control_mapping``, the body rule; None: the
    paper's) override ``PAPER_CHOICES``."""
    if preset not in PRESETS:
        raise UserError(f"unknown experiment preset {preset!r}; choose {' or '.join(PRESETS)}")
    return PRESETS[preset](scale, repetitions=repetitions, seed=seed, **choices)
