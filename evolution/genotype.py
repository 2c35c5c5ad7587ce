"""Robot genotype (two CPPNs) and its development into a phenotype.

Expression (paper section 2.3.2, docs/spec.md section 2), per voxel of the workspace:
- body CPPN output ``present`` >= 0: the voxel is full; then ``active`` >= 0: active (2),
  else passive (1); otherwise empty (0);
- control CPPN output ``phase`` * pi: the voxel's phase offset (radians, in (-pi, pi));
- control CPPN output ``frequency``: its mean over the present voxels, m in (-1, 1), maps
  linearly onto ``frequency_range`` (default 1 to 5 Hz): f = f_lo + (m + 1) / 2 (f_hi - f_lo).
  1-5 Hz spans the quasi-static gaits of stiff robots and the first body modes of the soft
  ones (a 7-voxel robot of 1 kPa resonates near 0.5-1 Hz, of 1 MPa near 10 Hz) while keeping
  a fixed number of cycles affordable (50 cycles last at most 50 s).
- only the largest face-connected component of full voxels is kept; the count of removed
  voxels is recorded (``Phenotype.removed_voxels``). Ties between equally large components go
  to the one met first in x-major order.

Options beyond the paper, off by default (``EncodingConfig``):
- ``evolve_stiffness``: a third body output ``stiffness`` s maps log-linearly onto
  ``stiffness_range`` (default 1e3..1e7 Pa, the paper's S1..S5): E = lo (hi/lo)^((s+1)/2)
  per voxel; the scene carries it as ``youngs_modulus_field`` (the treatment's scalar modulus
  is then unused: the field overrides it).
- ``frequency_per_voxel``: each voxel's control output ``frequency`` maps (as above) onto its
  own frequency, carried by the scene as ``frequency_field``; active voxels actuate at their
  own frequency, and an evaluation's cycles count at the mean over the active voxels (sim.scene).
  ``Phenotype.frequency`` stays the mapped mean output over present voxels (a descriptor).

The paper's own choices, named and off by default (what the paper presets use):
- ``control_mapping="evosoro-logistic"`` (what the paper presets run) and its variants: the
  control outputs as the paper-era evosoro scripts read them (examples/swimming_complex.py:67-71,
  101-104 and land_continuous.py:67-70,94-97 of skriegman/evosoro;
  tools/read_write_voxelyze.py:48,151; the fork's _voxcad_land_water/Voxelyze/VXS_Voxel.cpp:230).
  With s the ``frequency`` output (in (-1, 1): evosoro's bipolar sigmoid) at *every* voxel of
  the workspace, empty ones included: f = 4 * 2.5 / (mean(1 / s) + 1.5) Hz (the fork's
  TempPeriod is 1 / f): s = 1 everywhere gives the 4 Hz of ``MAX_FREQUENCY``, s = 0.5 gives
  2.86 Hz, s -> 0+ gives f -> 0, and negative outputs can give more than 4 Hz (s = -1
  everywhere: 20 Hz; a uniform s = -2/3 is a pole) or a negative f. The ``phase`` output s
  becomes PhaseOffset p = pi (1 + s) (``rescaled_positive_sigmoid`` onto (0, 2 pi)), which the
  fork reads in *cycles*: sin(2 pi (t / TempPeriod + p)), so the phase in radians is 2 pi p
  (stored modulo 2 pi). The four mappings differ in two choices the scripts leave open
  (``EVOSORO_MAPPINGS``), and the presets' reading of the output:
  - ``evosoro-logistic`` (the presets'): the frequency output read through the logistic,
    s' = (1 + s) / 2 in (0, 1), before the formula, so f lies in (0, 4) Hz and reaches 4 Hz
    only as every output tends to 1. An inference with its evidence in docs/algorithm.md: the
    formula maps (0, 1] exactly onto (0, 4] Hz with ``MAX_FREQUENCY`` at s = 1; the same
    network's other output, the phase, goes through the scripts' ``rescaled_positive_sigmoid``
    (the logistic, examples/swimming_complex.py:98-104); the paper's sample robots run at
    2.4-4.0 Hz. The four readings below apply the formula to the bipolar output itself;
  - bounded or not: ``-bounded`` clips the frequency at ``EVOSORO_MAX_FREQUENCY`` (4 Hz). An
    inference, not the scripts' text (their formula is unbounded under a bipolar sigmoid):
    the constant is named a maximum, and the paper's own sample robots run at 2.4-4.0 Hz
    (docs/algorithm.md);
  - a negative f: run at |f| (the fork's sine run backwards: sin(-2 pi |f| t + 2 pi p) =
    sin(2 pi |f| t + pi - 2 pi p), so the phenotype actuates at |f| with phase pi - 2 pi p),
    or, with ``-positive``, an invalid body (``is_viable``).
  ``evosoro`` is the unbounded |f| mapping of the earlier study. A frequency of 0 or not
  finite (an output exactly 0) has no period: the body is invalid under all four.
- ``body_rule="evosoro"``: the scripts' ``MyPhenotype.is_valid`` (swimming_complex.py:138-151,
  land_continuous.py:131-144, also basic.py and swimming_basic.py): a body is valid when at
  least 30% of the workspace's voxels are full and at least 10% of them are active (counted
  after keeping the largest component, as evosoro's ``make_material_tree`` does). Random
  genomes are drawn again until valid (softbot.py:447-454) and a mutation is tried again until
  the child is valid and differs from its parent (tools/mutation.py:120); a child that finds
  none keeps its parent's genome (tools/mutation.py:129-135); an invalid body is never
  simulated and gets the worst fitness (tools/evaluation.py:65-69).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from softevo.evolution.cppn import CPPN, INPUT_NAMES, express, minimal_cppn
from softevo.evolution.mutation import mutate_cppn
from softevo.sim import worlds
from softevo.sim.models import DEFAULT as DEFAULT_MODEL
from softevo.sim.models import defaults as model_defaults
from softevo.sim.scene import DEFAULT_CYCLES, Material, Scene
from softevo.sim.system import largest_component


class EvosoroMapping(NamedTuple):
    """How an evosoro mapping reads the scripts' frequency formula (module doc)."""

    logistic: bool  # the frequency output read through the logistic: s' = (1 + s) / 2 in (0, 1)
    bounded: bool  # clipped at EVOSORO_MAX_FREQUENCY (4 Hz)
    positive_only: bool  # a negative f makes the body invalid (else it runs at |f|)


EVOSORO_MAPPINGS: dict[str, EvosoroMapping] = {
    "evosoro-logistic": EvosoroMapping(logistic=True, bounded=False, positive_only=False),
    "evosoro": EvosoroMapping(logistic=False, bounded=False, positive_only=False),
    "evosoro-bounded": EvosoroMapping(logistic=False, bounded=True, positive_only=False),
    "evosoro-positive": EvosoroMapping(logistic=False, bounded=False, positive_only=True),
    "evosoro-bounded-positive": EvosoroMapping(logistic=False, bounded=True, positive_only=True),
}
CONTROL_MAPPINGS = ("linear", *EVOSORO_MAPPINGS)
BODY_RULES: dict[str, tuple[float, float]] = {  # (min full, min active) shares of the workspace
    "any": (0.0, 0.0),
    "evosoro": (0.3, 0.1),
}
EVOSORO_MAX_FREQUENCY = 4.0  # Hz, the scripts' MAX_FREQUENCY


@dataclass(frozen=True)
class EncodingConfig:
    """How genomes are expressed: workspace shape (voxels) and the output mappings."""

    workspace: tuple[int, int, int] = (7, 7, 7)
    frequency_range: tuple[float, float] = (1.0, 5.0)  # Hz
    evolve_stiffness: bool = False
    stiffness_range: tuple[float, float] = (1e3, 1e7)  # Pa
    frequency_per_voxel: bool = False
    initial_hidden_nodes: int = 4  # add_node mutations applied to a newcomer
    initial_links: int = 6  # add_link mutations applied to a newcomer
    control_mapping: str = "linear"  # or one of EVOSORO_MAPPINGS (the paper's; module doc)
    body_rule: str = "any"  # or "evosoro" (the paper's; module doc)

    def __post_init__(self) -> None:
        if self.control_mapping not in CONTROL_MAPPINGS:
            raise ValueError(f"control_mapping must be one of {CONTROL_MAPPINGS} "
                             f"(got {self.control_mapping!r})")
        if self.body_rule not in BODY_RULES:
            raise ValueError(f"body_rule must be one of {tuple(BODY_RULES)} (got {self.body_rule!r})")
        if self.control_mapping in EVOSORO_MAPPINGS and self.frequency_per_voxel:
            raise ValueError(f"control_mapping {self.control_mapping!r} gives one frequency per robot: "
                             "it cannot be combined with frequency_per_voxel")

    @property
    def rejects_invalid(self) -> bool:
        """Whether newcomers and children are drawn again until ``is_viable`` (the paper's
        choices); the defaults keep any non-empty newcomer and any changed child."""
        return self.body_rule != "any" or self.control_mapping != "linear"

    @property
    def body_outputs(self) -> tuple[str, ...]:
        return ("present", "active") + (("stiffness",) if self.evolve_stiffness else ())

    @property
    def control_outputs(self) -> tuple[str, ...]:
        return ("frequency", "phase")

    def to_dict(self) -> dict[str, Any]:
        return {
            "workspace": list(self.workspace),
            "frequency_range": list(self.frequency_range),
            "evolve_stiffness": self.evolve_stiffness,
            "stiffness_range": list(self.stiffness_range),
            "frequency_per_voxel": self.frequency_per_voxel,
            "initial_hidden_nodes": self.initial_hidden_nodes,
            "initial_links": self.initial_links,
            "control_mapping": self.control_mapping,
            "body_rule": self.body_rule,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EncodingConfig:
        data = dict(data)
        for key in ("workspace", "frequency_range", "stiffness_range"):
            if key in data:
                data[key] = tuple(data[key])
        return cls(**data)


@dataclass(frozen=True)
class Genotype:
    """A robot's genome: the body CPPN and the control CPPN."""

    body: CPPN
    control: CPPN

    def to_dict(self) -> dict[str, Any]:
        return {"body": self.body.to_dict(), "control": self.control.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Genotype:
        return cls(CPPN.from_dict(data["body"]), CPPN.from_dict(data["control"]))

    def to_json(self) -> str:
        return json.dumps(self.to_dict())

    @classmethod
    def from_json(cls, text: str) -> Genotype:
        return cls.from_dict(json.loads(text))


@dataclass(frozen=True, eq=False)
class Phenotype:
    """A developed robot.

    body: (nx, ny, nz) int8, 0 empty, 1 passive, 2 active (largest component only).
    phase: (nx, ny, nz) float64 radians, 0 where empty.
    frequency: Hz, one for the robot.
    removed_voxels: full voxels dropped because they were outside the largest component.
    stiffness: (nx, ny, nz) float64 Pa or None; frequency_field: (nx, ny, nz) Hz or None
    (0 where empty). Both enter the scene (``to_scene``) and the hash when present.
    """

    body: np.ndarray
    phase: np.ndarray
    frequency: float
    removed_voxels: int = 0
    stiffness: np.ndarray | None = None
    frequency_field: np.ndarray | None = None

    @property
    def voxel_count(self) -> int:
        return int(np.count_nonzero(self.body))

    @property
    def active_share(self) -> float:
        """Active voxels / present voxels; 0 for an empty body."""
        count = self.voxel_count
        return float(np.count_nonzero(self.body == 2)) / count if count else 0.0

    def phenotype_hash(self) -> str:
        """sha1 of the body bytes, phase rounded to 1e-6 rad, frequency rounded to 1e-9 Hz.

        Phases of empty voxels are zero, so only what the simulator sees enters the hash.
        """
        digest = hashlib.sha1()
        digest.update(np.asarray(self.body.shape, dtype=np.int64).tobytes())
        digest.update(np.ascontiguousarray(self.body, dtype=np.int8).tobytes())
        digest.update(np.round(self.phase, 6).astype(np.float64).tobytes())
        digest.update(repr(round(float(self.frequency), 9)).encode())
        if self.stiffness is not None:
            digest.update(np.round(np.log10(self.stiffness + 1e-300), 6).tobytes())
        if self.frequency_field is not None:
            digest.update(b"frequency_field")
            digest.update(np.round(self.frequency_field, 9).astype(np.float64).tobytes())
        return digest.hexdigest()

    def summary(self) -> dict[str, Any]:
        """Plain-JSON facts about the phenotype (for records and exports)."""
        return {
            "hash": self.phenotype_hash(),
            "voxel_count": self.voxel_count,
            "active_share": self.active_share,
            "frequency": self.frequency,
            "removed_voxels": self.removed_voxels,
        }

    def to_scene(
        self,
        environment: str,
        youngs_modulus: float,
        cycles: int = DEFAULT_CYCLES,
        *,
        voxel_size: float = Scene.voxel_size,
        density: float = Material.density,
        poisson_ratio: float = Material.poisson_ratio,
        amplitude: float | None = None,
        settle_seconds: float | None = None,
        model: str = DEFAULT_MODEL,
        max_seconds: float | None = None,
        arrays: bool = False,
        **extra: Any,
    ) -> dict[str, Any]:
        """A simulator scene (docs/spec.md section 1 schema), plain JSON types; with
        ``arrays`` its body, phase and fields are this phenotype's own NumPy arrays instead
        of nested lists (what ``sim.parse_scene`` reads without converting lists: not JSON,
        and to be read, not changed).

        The evaluation lasts ``cycles`` cycles, capped at ``max_seconds`` seconds when given
        (``duration_of``).

        ``model`` is the physics model (``sim.models.names()``); the scene names it unless it is
        the default (a scene without ``model`` is the default model's). ``amplitude``
        defaults to the model's (0.39 / 0.14 strain). ``settle_seconds`` defaults to the
        world's (``sim.worlds``: 0.5 on a floor, 0 elsewhere), which is also the paper's engine's
        InitCmTime in the fork's own sample robots (``_voxcad_land_water/sample_vxa/*.vxa``:
        0.5 s on land, 0 s in water; its distance counts from there). ``extra`` fields are
        copied into the scene as given (e.g. ``record``). An evolved stiffness field enters as
        ``youngs_modulus_field`` (Pa; it overrides ``youngs_modulus``), a per-voxel frequency
        field as ``frequency_field`` (Hz; it overrides the robot frequency, and ``cycles`` count
        at the mean frequency of the active voxels).
        """
        defaults = model_defaults(model)
        if amplitude is None:
            amplitude = defaults["amplitude"]
        world = worlds.get(environment)
        if settle_seconds is None:
            settle_seconds = world.settle_seconds
        scene = {
            "voxel_size": voxel_size,
            "material": {
                "youngs_modulus": float(youngs_modulus),
                "density": density,
                "poisson_ratio": poisson_ratio,
            },
            "environment": world.scene_environment(),
            "body": self.body if arrays else self.body.astype(int).tolist(),
            "phase": self.phase if arrays else self.phase.tolist(),
            "actuation": {"frequency": float(self.frequency), "amplitude": amplitude},
            "duration": duration_of(int(cycles), max_seconds),
            "settle_seconds": float(settle_seconds),
        }
        for name, values in (("youngs_modulus_field", self.stiffness),
                             ("frequency_field", self.frequency_field)):
            if values is not None:
                values = np.asarray(values, np.float64)
                scene[name] = values if arrays else values.tolist()
        if model != DEFAULT_MODEL:
            scene["model"] = model
        scene.update(extra)
        return scene


def duration_of(cycles: float, max_seconds: float | None = None, share: float = 1.0) -> dict[str, Any]:
    """The scene duration of ``share`` of an evaluation of ``cycles`` cycles capped at
    ``max_seconds`` seconds (None: no cap): ``{"cycles": n}`` or ``{"cycles": n,
    "max_seconds": s}`` (``sim.scene``), both scaled by ``share``. A whole evaluation
    (share 1) keeps an integer count of cycles."""
    duration: dict[str, Any] = {"cycles": int(cycles) if share == 1.0 else float(cycles) * share}
    if max_seconds is not None:
        duration["max_seconds"] = float(max_seconds) * share
    return duration


def _map_linear(value: np.ndarray | float, bounds: tuple[float, float]) -> np.ndarray | float:
    low, high = bounds
    return low + (np.asarray(value) + 1.0) / 2.0 * (high - low)


def logistic_reading(output: np.ndarray) -> np.ndarray:
    """A bipolar output s in (-1, 1) read as the logistic 1 / (1 + e^-x) of the same
    activation: (1 + s) / 2 in (0, 1) (tanh(x / 2) = 2 logistic(x) - 1)."""
    return (1.0 + np.asarray(output, dtype=np.float64)) / 2.0


def evosoro_frequency(output: np.ndarray) -> float:
    """The paper scripts' signed frequency (Hz) of a robot from its ``frequency`` output s
    at every workspace voxel: 4 * 2.5 / (mean(1 / s) + 1.5) (module doc); 0 when an output
    is exactly 0 (no period), +-inf when the denominator is 0. For s in (0, 1] it lies in
    (0, 4] Hz, 4 Hz at s = 1 everywhere."""
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = float(np.mean(1.0 / np.asarray(output, dtype=np.float64))) + 1.5
        return float(EVOSORO_MAX_FREQUENCY * 2.5 / np.float64(denominator))


def evosoro_phase_cycles(output: np.ndarray) -> np.ndarray:
    """The scripts' PhaseOffset of each voxel from its ``phase`` output s: pi (1 + s), which
    the fork reads in cycles (module doc)."""
    return np.pi * (1.0 + np.asarray(output, dtype=np.float64))


def _evosoro_control(
    control_out: dict[str, np.ndarray], kept: np.ndarray, mapping: str
) -> tuple[np.ndarray, float]:
    """(phase in radians, frequency in Hz) of the evosoro ``mapping`` (``EVOSORO_MAPPINGS``):
    ``-logistic`` reads the frequency output through the logistic first (always in (0, 4) Hz);
    a negative frequency runs at |f| with phase pi - 2 pi p, or is returned as it is (an
    invalid body) under a ``-positive`` mapping; a ``-bounded`` one clips at 4 Hz (module doc)."""
    logistic, bounded, positive_only = EVOSORO_MAPPINGS[mapping]
    output = control_out["frequency"]
    signed = evosoro_frequency(logistic_reading(output) if logistic else output)
    angle = 2.0 * np.pi * evosoro_phase_cycles(control_out["phase"])
    if signed < 0 and not positive_only:
        angle = np.pi - angle
    phase = np.where(kept, np.mod(angle, 2.0 * np.pi), 0.0)
    frequency = signed if positive_only else abs(signed)
    if bounded and frequency > EVOSORO_MAX_FREQUENCY:
        frequency = EVOSORO_MAX_FREQUENCY
    return phase, frequency


def develop(genotype: Genotype, config: EncodingConfig = EncodingConfig()) -> Phenotype:
    """Express both CPPNs over ``config.workspace`` and apply the expression pattern."""
    body_out = express(genotype.body, config.workspace)
    control_out = express(genotype.control, config.workspace)
    full = body_out["present"] >= 0.0
    kept = largest_component(full)
    body = np.where(kept, np.where(body_out["active"] >= 0.0, 2, 1), 0).astype(np.int8)
    if config.control_mapping in EVOSORO_MAPPINGS:
        phase, frequency = _evosoro_control(control_out, kept, config.control_mapping)
    else:
        phase = np.where(kept, control_out["phase"] * np.pi, 0.0)
        mean_output = float(control_out["frequency"][kept].mean()) if kept.any() else 0.0
        frequency = float(_map_linear(mean_output, config.frequency_range))
    stiffness = None
    if config.evolve_stiffness:
        low, high = config.stiffness_range
        exponent = (body_out["stiffness"] + 1.0) / 2.0
        stiffness = np.where(kept, low * (high / low) ** exponent, 0.0)
    field_hz = None
    if config.frequency_per_voxel:
        field_hz = np.where(kept, _map_linear(control_out["frequency"], config.frequency_range), 0)
    return Phenotype(
        body=body,
        phase=phase,
        frequency=frequency,
        removed_voxels=int(np.count_nonzero(full) - np.count_nonzero(kept)),
        stiffness=stiffness,
        frequency_field=field_hz,
    )


def random_cppn(
    rng: np.random.Generator, output_names: tuple[str, ...], config: EncodingConfig
) -> CPPN:
    """A newcomer: inputs fully linked to outputs (weights U(-1, 1)), then a few structural
    mutations (``initial_hidden_nodes`` node additions, ``initial_links`` link additions)."""
    from softevo.evolution.mutation import add_link, add_node

    cppn = minimal_cppn(output_names, rng.uniform(-1, 1, (len(INPUT_NAMES), len(output_names))))
    for _ in range(config.initial_hidden_nodes):
        cppn = add_node(cppn, rng) or cppn
    for _ in range(config.initial_links):
        cppn = add_link(cppn, rng) or cppn
    return cppn


def random_genotype(
    rng: np.random.Generator, config: EncodingConfig = EncodingConfig()
) -> Genotype:
    """A random genotype (not checked for a non-empty body: see ``random_viable_genotype``)."""
    return Genotype(
        random_cppn(rng, config.body_outputs, config),
        random_cppn(rng, config.control_outputs, config),
    )


def is_viable(phenotype: Phenotype, config: EncodingConfig = EncodingConfig()) -> bool:
    """Whether a body may be simulated: at least one voxel, the ``body_rule``'s shares of
    full and active voxels of the workspace (evosoro: a body with fewer than 30% / 10% is
    invalid, examples/swimming_complex.py:146-150) and a finite positive frequency."""
    min_full, min_active = BODY_RULES[config.body_rule]
    cells = float(np.prod(config.workspace))
    active = int(np.count_nonzero(phenotype.body == 2))
    return (
        phenotype.voxel_count > 0
        and phenotype.voxel_count >= min_full * cells
        and active >= min_active * cells
        and bool(np.isfinite(phenotype.frequency) and phenotype.frequency > 0)
    )


MAX_NEWCOMER_TRIES = 1000
"""Bounded draws for a viable newcomer (evosoro draws until one is valid, softbot.py:447-454)."""


def random_viable_genotype(
    rng: np.random.Generator, config: EncodingConfig = EncodingConfig(),
    max_tries: int = MAX_NEWCOMER_TRIES,
) -> Genotype:
    """A random genotype whose phenotype ``is_viable`` (the last try if none is)."""
    return random_viable(rng, config, max_tries)[0]


def random_viable(
    rng: np.random.Generator, config: EncodingConfig = EncodingConfig(),
    max_tries: int = MAX_NEWCOMER_TRIES,
) -> tuple[Genotype, Phenotype]:
    """``random_viable_genotype`` with the phenotype it was judged by (developed in
    ``config``), so that the caller need not develop it again."""
    for _ in range(max_tries):
        genotype = random_genotype(rng, config)
        phenotype = develop(genotype, config)
        if is_viable(phenotype, config):
            return genotype, phenotype
    return genotype, phenotype


MAX_MUTATION_TRIES = 100
"""Bounded retries for a child that differs from its parent in phenotype (evosoro-like)."""


def mutate_genotype(
    parent: Genotype,
    rng: np.random.Generator,
    config: EncodingConfig = EncodingConfig(),
    max_tries: int = MAX_MUTATION_TRIES,
) -> tuple[Genotype, list[str], bool]:
    """A mutated child: (child, applied operators, phenotype changed).

    Each try starts from the parent, picks the body or the control CPPN with equal chance
    and applies 1 + try // 10 mutations to it (so late tries take larger steps). The first
    child whose phenotype hash differs from the parent's is returned; after ``max_tries``
    the last child is returned with ``changed=False``.

    With ``config.rejects_invalid`` (the paper's choices) a child must also be viable
    (``is_viable``; evosoro, tools/mutation.py:120); after ``max_tries`` the parent's genome
    itself is returned with ``changed=False``, as evosoro keeps the unmutated clone
    (tools/mutation.py:129-135).
    """
    child, ops, changed, _ = mutate_developed(parent, develop(parent, config), rng, config, max_tries)
    return child, ops, changed


def mutate_developed(
    parent: Genotype,
    parent_phenotype: Phenotype,
    rng: np.random.Generator,
    config: EncodingConfig = EncodingConfig(),
    max_tries: int = MAX_MUTATION_TRIES,
) -> tuple[Genotype, list[str], bool, Phenotype]:
    """``mutate_genotype`` of a parent already developed in ``config``
    (``parent_phenotype``), returning the child's phenotype as well: (child, applied
    operators, phenotype changed, the child's phenotype in ``config``). The same random
    draws and the same child as ``mutate_genotype``."""
    parent_hash = parent_phenotype.phenotype_hash()
    for attempt in range(max_tries):
        which = "body" if rng.random() < 0.5 else "control"
        cppn = getattr(parent, which)
        ops = []
        for _ in range(1 + attempt // 10):
            cppn, op = mutate_cppn(cppn, rng)
            ops.append(f"{which}.{op}")
        child = Genotype(cppn, parent.control) if which == "body" else Genotype(parent.body, cppn)
        phenotype = develop(child, config)
        if phenotype.phenotype_hash() != parent_hash and (
            not config.rejects_invalid or is_viable(phenotype, config)
        ):
            return child, ops, True, phenotype
    if config.rejects_invalid or max_tries < 1:
        return parent, [], False, parent_phenotype
    return child, ops, False, phenotype
