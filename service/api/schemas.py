"""Request and response bodies of the REST API (pydantic v2), apart from the SQL models.

Limits on submitted values keep every request within what the database and the simulator
accept (ids and seeds fit a 32-bit integer column, names a 200-character column), so a bad
request is a 422 with a clear message, never a 500.
"""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    GetCoreSchemaHandler,
    GetJsonSchemaHandler,
    StringConstraints,
    Tag,
    create_model,
)
from pydantic_core import core_schema

from softevo.evolution import environments, options
from softevo.evolution.options import MAX_INT32
from softevo.evolution.run_status import RunStatus
from softevo.evolution.treatments import PRESETS, SCALES
from softevo.service.api.schemas_traits import RegisteredTraits, trait_fields
from softevo.service.runs.executors import EXECUTOR_KINDS

Name = Annotated[
    str,
    StringConstraints(min_length=1, max_length=200, strip_whitespace=True, pattern=r"^[^\x00-\x1f\x7f]+$"),
]


class RegistryEnum(str):
    """A string that must be one of ``choices()``, read when a value is validated and when
    the JSON schema is made (its ``enum``): the REST schema follows the world registry,
    worlds registered after this module was imported included."""

    choices: staticmethod

    @classmethod
    def __get_pydantic_core_schema__(cls, source: Any, handler: GetCoreSchemaHandler) -> Any:
        def check(value: str) -> str:
            allowed = cls.choices()
            if value not in allowed:
                raise ValueError(f"must be one of {', '.join(allowed)} (got {value!r})")
            return value

        return core_schema.no_info_after_validator_function(check, core_schema.str_schema())

    @classmethod
    def __get_pydantic_json_schema__(cls, schema: Any, handler: GetJsonSchemaHandler) -> dict[str, Any]:
        return {"type": "string", "enum": list(cls.choices())}


class Environment(RegistryEnum):
    """A treatment's environment: a world or a transition (``evolution.environments.environments``)."""

    choices = staticmethod(environments.environments)


class WorldName(RegistryEnum):
    """One evolvable world of the registry (``sim.worlds``)."""

    choices = staticmethod(lambda: environments.names(evolve=True))

def choice_type(option: options.Option) -> type[RegistryEnum]:
    """A string among a declared option's choices, read when validated and when the schema
    is made (a model, algorithm or mapping registered after this module was imported is one)."""
    name = "".join(part.capitalize() for part in option.name.split("_"))
    return type(name, (RegistryEnum,), {"choices": staticmethod(option.choices), "__doc__": option.help})


Model = choice_type(options.option("model"))
Algorithm = choice_type(options.option("algorithm"))
RunStatusName = Literal[tuple(status.value for status in RunStatus)]  # type: ignore[valid-type]


class Strict(BaseModel):
    """Unknown fields are an error (a typo must not be silently ignored)."""

    model_config = ConfigDict(extra="forbid", strict=True)


class WorldOut(BaseModel):
    """One world of the registry (``sim.worlds.World``)."""

    name: str
    kind: str = Field(description="the physics kind it simulates as")
    gravity: float
    floor: bool
    drag: bool
    distance: str
    settle_seconds: float
    colour: str
    background: str
    label: str
    colormap: str
    evolve: bool


# -- requests ------------------------------------------------------------------------------


def option_field(option: options.Option) -> tuple[Any, Any]:
    """(annotation, ``Field``) of a declared treatment option in ``TreatmentIn``: its type,
    bounds (up to what a request may ask: ``Option.most_asked``), choices, default and help."""
    bounds = {"ge": option.least, "le": option.most_asked, "gt": option.above}
    bounds = {key: value for key, value in bounds.items() if value is not None}
    if option.type is float:
        bounds["allow_inf_nan"] = False
    if option.type is str:
        kind: Any = (choice_type(option) if option.choices is not None
                     else Annotated[str, StringConstraints(min_length=1, max_length=64)])
    elif option.type is bool:
        kind = bool
    else:
        kind = Annotated[option.type, Field(**bounds)] if option.sequence else option.type
    description = f"{option.help} ({option.unit})" if option.unit else option.help
    if option.sequence:
        sizes = {"min_length": option.length, "max_length": option.length or option.many}
        default = ... if option.required else list(option.default)
        return list[kind], Field(default, description=description, **sizes)
    if option.optional:
        kind = kind | None
    default = ... if option.required else option.default
    return kind, Field(default, description=description, **({} if option.type in (str, bool) else bounds))


def treatment_model() -> type[BaseModel]:
    """``TreatmentIn`` as the declared treatment options make it now (``evolution.options``):
    a treatment's ``name`` and one field per option."""
    fields = {option.name: option_field(option) for option in options.declared()}
    return create_model(
        "TreatmentIn",
        __base__=Strict,
        __doc__="One treatment (docs/spec.md section 5); every field but environment and stiffness_mpa "
        "has a default. Repetition r runs with seed ``seed + r``. Its fields are the declared "
        "treatment options (evolution.options).",
        name=(Name | None, Field(None, description="default: e.g. 'land S=0.1MPa'")),
        **fields,
    )


TreatmentIn = treatment_model()


class ExperimentIn(Strict):
    """An experiment of explicit treatments."""

    name: Name
    treatments: list[TreatmentIn] = Field(min_length=1, max_length=200)


class PresetIn(Strict):
    """A preset experiment: the paper's grid at a scale (docs/spec.md section 5), with the paper's
    algorithm, model and encoding unless ``algorithm`` or ``model`` says otherwise."""

    preset: Literal[tuple(PRESETS)] = Field(  # type: ignore[valid-type]
        description="paper: the paper's grid; gradual: its two transitions, abrupt and gradual")
    scale: Literal[SCALES] = "tiny"  # type: ignore[valid-type]
    repetitions: int | None = Field(None, ge=1, le=1000)
    seed: int = Field(0, ge=0, le=MAX_INT32 - 1000)
    name: Name | None = None
    algorithm: Algorithm | None = Field(None, description="default the paper's: pareto")
    model: Model | None = Field(None, description="default the paper's: voxcad-land-water")


def _experiment_kind(value: Any) -> str:
    if isinstance(value, dict):
        return "preset" if "preset" in value else "treatments"
    return "preset" if isinstance(value, PresetIn) else "treatments"


EXPERIMENT_TAGS = ("treatments", "preset")  # where a request's errors are (see app.py)


def request_problems(errors: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """pydantic's ``errors()`` of a request, as a person reads them: each ``loc`` without the
    union's tag (which kind of experiment body: no field of it), each ``msg`` without
    pydantic's "Value error, " prefix, and the problems with values given before the fields
    left out (a body with no ``name`` and a wrong treatment leads with the treatment)."""
    problems = []
    for error in errors:
        loc = [str(part) for part in error.get("loc", ())]
        at = 1 if loc[:1] == ["body"] else 0
        if len(loc) > at and loc[at] in EXPERIMENT_TAGS:
            del loc[at]
        msg = str(error.get("msg", "")).removeprefix("Value error, ")
        if error.get("type") == "json_invalid":  # not ``body.20: JSON decode error`` (issue 59.4)
            loc, msg = [], malformed_json_text(error, loc)
        problems.append({"loc": loc, "msg": msg, "type": str(error.get("type", ""))})
    return sorted(problems, key=lambda problem: problem["type"] == "missing")


def malformed_json_text(error: dict[str, Any], loc: list[str]) -> str:
    """What a body that is not JSON gets: the parser's reason and the character it stopped at
    (the number in ``loc``, counted from 0)."""
    reason = str((error.get("ctx") or {}).get("error") or "").strip()
    where = next((part for part in reversed(loc) if part.isdigit()), None)
    at = f" at character {int(where) + 1}" if where is not None else ""
    return f"the body is not valid JSON{at}" + (f" ({reason[:1].lower() + reason[1:]})" if reason else "")


def problem_line(problems: list[dict[str, Any]]) -> str:
    """The first of ``problems`` (``request_problems``) in one line, with how many more."""
    first = problems[0] if problems else {"loc": [], "msg": "invalid request"}
    message = f"{'.'.join(first['loc'])}: {first['msg']}" if first["loc"] else first["msg"]
    if len(problems) > 1:
        message += f" (and {len(problems) - 1} more problem(s))"
    return message
ExperimentRequest = Annotated[
    Annotated[ExperimentIn, Tag("treatments")] | Annotated[PresetIn, Tag("preset")],
    Discriminator(_experiment_kind),
]



class Devices(Strict):
    """What a plan runs on: ``cores`` CPU workers or ``gpus`` GPUs (exactly one)."""

    cores: int | None = Field(None, ge=1, le=100_000, description="CPU workers, one core each")
    gpus: int | None = Field(None, ge=1, le=10_000, description="GPUs (their rate: an estimate)")
    coordinators: int = Field(1, ge=1, le=1_000, description="coordinator processes sharing the runs")
    executor: Literal[EXECUTOR_KINDS] | None = Field(  # type: ignore[valid-type]
        None, description="rq: a cluster (softevo serve, Redis workers); local: softevo run's process pool; "
        "left out: this server's own (rq with SOFTEVO_REDIS_URL, else local)"
    )


class PlanExperimentIn(ExperimentIn, Devices):
    """An experiment of explicit treatments to plan, and the devices."""

    name: Name = "plan"


class PlanPresetIn(PresetIn, Devices):
    """A preset experiment to plan, and the devices."""


PlanRequest = Annotated[
    Annotated[PlanExperimentIn, Tag("treatments")] | Annotated[PlanPresetIn, Tag("preset")],
    Discriminator(_experiment_kind),
]


# -- responses -----------------------------------------------------------------------------


class ErrorOut(BaseModel):
    """Every error: one clear message."""

    detail: str


class ValidationErrorOut(BaseModel):
    """A request that does not match the schema: a message and each problem found."""

    detail: str
    errors: list[dict[str, Any]]


class HealthOut(BaseModel):
    status: Literal["ok", "degraded"]
    workers: int = Field(description="RQ workers on the queue, or local evaluation processes")
    queued: int = Field(description="evaluation jobs waiting in the queue")
    executor: Literal["rq", "local", "none"]
    database: Literal["ok", "unreachable"]
    coordinator: bool = Field(description="whether this process drives runs (its coordinator loop is alive)")
    reasons: list[str] = Field(default_factory=list, description="why the status is degraded, in words")


class ExperimentCreated(BaseModel):
    id: int
    runs: list[int]


class WorldBest(BaseModel):
    """A run's best distance in one world (``/runs``: what its list can give cheaply)."""

    environment: str
    distance: float = Field(description="voxel lengths")


class RunSummary(BaseModel):
    id: int
    experiment_id: int
    treatment: str
    repetition: int
    seed: int
    status: RunStatusName
    generation: int = Field(description="last generation stored, counted from 0 (-1: none yet)")
    generations: int = Field(description="generations planned (generation + 1 of them stored)")
    environment: str | None = Field(description="world of the last generation stored (None: none yet)")
    best_distance: float | None = Field(
        description="best distance of the last generation stored, voxel lengths (None: none yet)"
    )
    best_per_world: list[WorldBest] = Field(
        description="per world the run was evaluated in, in the order the run met them: the best "
        "distance of any generation in it (GET /runs/{id} gives the whole best evaluation)"
    )
    best_by_world: dict[str, float] = Field(
        description="deprecated, kept for older clients: best_per_world as {world: distance}"
    )


class Progress(BaseModel):
    generations_done: int
    generations_total: int
    fraction: float


class ExperimentOut(BaseModel):
    id: int
    name: str
    preset: str | None
    scale: str | None
    created_at: datetime | None
    status: RunStatusName = Field(
        description="running if any run is, else pending if any is, else failed, cancelled or "
        "finished (the first that applies)"
    )
    progress: Progress
    runs_total: int = Field(description="runs of the experiment (status and progress count them all)")
    runs: list[RunSummary] = Field(
        description="a page of the runs in id order: runs_limit of them from the runs_offset-th")


class Objectives(BaseModel):
    """Every objective of the evaluation's run by name: the paper's three, and any other the
    treatment names (``TreatmentIn.objectives``) as an extra field."""

    model_config = ConfigDict(extra="allow")

    distance: float = Field(description="voxel lengths (maximised)")
    active_share: float = Field(description="active voxels / voxels (minimised)")
    voxel_count: int = Field(description="voxels (minimised)")


class BestOut(Objectives):
    individual_id: int
    generation: int = Field(description="generation of the evaluation")
    environment: str


class TreatmentOut(BaseModel):
    name: str
    settings: dict[str, Any] = Field(description="evolution.treatments.Treatment as JSON")


class RunOut(BaseModel):
    id: int
    experiment_id: int
    status: RunStatusName
    generation: int = Field(description="last generation stored, counted from 0 (-1: none yet)")
    generations: int = Field(description="generations planned (generation + 1 of them stored)")
    repetition: int
    seed: int
    treatment: TreatmentOut
    best: BestOut | None = Field(
        description="the best evaluation (greatest distance) in the run's last world so far: "
        "distances of different worlds are not comparable (None: none yet)"
    )
    best_per_world: list[BestOut] = Field(
        description="the best evaluation in each world the run was evaluated in, the worlds in "
        "the order the run met them (the last is ``best``); the same as GET /runs/{id}/best"
    )
    error: str | None
    created_at: datetime | None
    updated_at: datetime | None


class GenerationOut(BaseModel):
    generation: int
    environment: str
    evaluations: int
    best_distance: float
    mean_distance: float
    front_size: int
    evaluation_seconds: float
    stats: dict[str, Any]
    created_at: datetime | None


EvaluationTraits = trait_fields("EvaluationTraits")


class EvaluationOut(EvaluationTraits):
    """One evaluation: a field per trait with a column of its own (``EvaluationTraits``,
    generated from ``evolution.traits``), and every trait by name in ``traits``."""

    generation: int
    environment: str
    stiffness: float = Field(description="Young's modulus, Pa")
    age: int
    descriptors: dict[str, Any] | None
    objectives: dict[str, float] | None = Field(
        description="every objective of the evaluation's run, by name (None: not recorded)")
    traits: dict[str, float | None] = Field(
        description="every trait of the registry (softevo.evolution.traits), by name")
    stable: bool
    error: str | None
    seconds: float | None


class FrontMember(BaseModel):
    id: int
    local_id: int
    parent_id: int | None
    generation_born: int
    age: int
    front_rank: int
    objectives: Objectives
    evaluation: EvaluationOut


class FrontOut(BaseModel):
    run_id: int
    generation: int
    individuals: list[FrontMember]


class IndividualOut(BaseModel):
    id: int
    run_id: int
    local_id: int
    parent_id: int | None
    generation_born: int
    genome: dict[str, Any]
    phenotype: dict[str, Any] | None
    objectives: Objectives | None = Field(description="from the latest evaluation")
    descriptors: dict[str, Any] | None = Field(description="from the latest evaluation")
    evaluations: list[EvaluationOut]


LineageTraits = trait_fields("LineageTraits", RegisteredTraits, nullable=True)


class LineageEntry(LineageTraits):
    """An ancestor with its birth evaluation: a field per trait with a column of its own,
    and every other registered trait as an extra key (``schemas_traits``)."""

    depth: int = Field(description="0: the individual, 1: its parent, ...")
    id: int
    parent_id: int | None
    run_id: int
    generation_born: int
    generation: int | None = Field(description="generation of the evaluation shown (its birth)")
    environment: str | None
    stiffness: float | None
    age: int | None
    stable: bool | None
    error: str | None
