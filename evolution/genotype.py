"""Robot genotype (two CPPNs) and its development into a phenotype.

Expression (paper section 2.3.2, SPEC.md section 2), per voxel of the workspace:
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
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from softevo.evolution.cppn import CPPN, INPUT_NAMES, express, minimal_cppn
from softevo.evolution.mutation import mutate_cppn
from softevo.sim.scene import DEFAULT_CYCLES, Actuation, Material, Scene
from softevo.sim.system import largest_component


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
        amplitude: float = Actuation.amplitude,
        settle_seconds: float | None = None,
        **extra: Any,
    ) -> dict[str, Any]:
        """A simulator scene (SPEC.md section 1 schema), plain JSON types.

        ``settle_seconds`` defaults to 0.5 on land and 0 elsewhere. ``extra`` fields are copied
        into the scene as given (e.g. ``record``). An evolved stiffness field enters as
        ``youngs_modulus_field`` (Pa; it overrides ``youngs_modulus``), a per-voxel frequency
        field as ``frequency_field`` (Hz; it overrides the robot frequency, and ``cycles`` count
        at the mean frequency of the active voxels).
        """
        if settle_seconds is None:
            settle_seconds = 0.5 if environment == "land" else 0.0
        scene = {
            "voxel_size": voxel_size,
            "material": {
                "youngs_modulus": float(youngs_modulus),
                "density": density,
                "poisson_ratio": poisson_ratio,
            },
            "environment": {"kind": environment},
            "body": self.body.astype(int).tolist(),
            "phase": self.phase.tolist(),
            "actuation": {"frequency": float(self.frequency), "amplitude": amplitude},
            "duration": {"cycles": int(cycles)},
            "settle_seconds": float(settle_seconds),
        }
        if self.stiffness is not None:
            scene["youngs_modulus_field"] = np.asarray(self.stiffness, np.float64).tolist()
        if self.frequency_field is not None:
            scene["frequency_field"] = np.asarray(self.frequency_field, np.float64).tolist()
        scene.update(extra)
        return scene


def _map_linear(value: np.ndarray | float, bounds: tuple[float, float]) -> np.ndarray | float:
    low, high = bounds
    return low + (np.asarray(value) + 1.0) / 2.0 * (high - low)


def develop(genotype: Genotype, config: EncodingConfig = EncodingConfig()) -> Phenotype:
    """Express both CPPNs over ``config.workspace`` and apply the expression pattern."""
    body_out = express(genotype.body, config.workspace)
    control_out = express(genotype.control, config.workspace)
    full = body_out["present"] >= 0.0
    kept = largest_component(full)
    body = np.where(kept, np.where(body_out["active"] >= 0.0, 2, 1), 0).astype(np.int8)
    phase = np.where(kept, control_out["phase"] * np.pi, 0.0)
    mean_output = float(control_out["frequency"][kept].mean()) if kept.any() else 0.0
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
        frequency=float(_map_linear(mean_output, config.frequency_range)),
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


def random_viable_genotype(
    rng: np.random.Generator, config: EncodingConfig = EncodingConfig(), max_tries: int = 100
) -> Genotype:
    """A random genotype whose body has at least one voxel (the last try if all are empty)."""
    for _ in range(max_tries):
        genotype = random_genotype(rng, config)
        if develop(genotype, config).voxel_count > 0:
            return genotype
    return genotype


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
    """
    parent_hash = develop(parent, config).phenotype_hash()
    for attempt in range(max_tries):
        which = "body" if rng.random() < 0.5 else "control"
        cppn = getattr(parent, which)
        ops = []
        for _ in range(1 + attempt // 10):
            cppn, op = mutate_cppn(cppn, rng)
            ops.append(f"{which}.{op}")
        child = Genotype(cppn, parent.control) if which == "body" else Genotype(parent.body, cppn)
        if develop(child, config).phenotype_hash() != parent_hash:
            return child, ops, True
    return child, ops, False
