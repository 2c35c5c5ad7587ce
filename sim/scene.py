"""The scene: a validated, typed form of the JSON scene document (docs/spec.md section 1).

``parse_scene(dict) -> Scene`` fills defaults and rejects bad input with a ``SceneError``
whose message starts with the offending field, e.g.
``material.youngs_modulus: must be > 0 (got -1.0)``. Everything downstream (system building,
kernels) may assume a valid Scene.

Per-voxel fields (optional, top level, each a nested list shaped like ``body`` and ``phase``,
indexed ``[x][y][z]``):

- ``youngs_modulus_field``: Young's modulus of each voxel, Pa;
- ``density_field``: density of each voxel, kg/m^3;
- ``frequency_field``: actuation frequency of each voxel, Hz (only active voxels use it).

Values at empty voxels are ignored (any number, even 0 or negative, JSON has no NaN); at every
present voxel a value must be finite and > 0, else a ``SceneError`` naming the field and the
voxel, e.g. ``youngs_modulus_field: must be > 0 at [1, 0, 2] (got -3.0)``. An absent field means
the scalar everywhere: ``material.youngs_modulus``, ``material.density``,
``actuation.frequency``. With a ``frequency_field``, ``duration.cycles`` counts cycles of the
robot's mean frequency over its active voxels (those of ``body`` as given: seconds = cycles /
mean f); with no active voxel the scalar ``actuation.frequency`` counts them. How the engine
combines two materials at a link: ``sim.kernels``' docstring.

The duration is ``{"cycles": n}``, ``{"seconds": s}`` or ``{"cycles": n, "max_seconds": s}``:
n cycles, but never more than s seconds (settling not counted), as the paper's text (cycles)
and its scripts (a fixed time) meet; a robot of very low frequency then runs s seconds, not
n / f.

The physics model (optional, top level): ``"model"`` is ``"voxelyze-2"`` (the default: the
model validated against Voxelyze 2.0, analytic solutions and conservation laws) or
``"voxcad-land-water"`` (the paper's own engine, the VoxCAD land/water fork in evosoro: what
``softevo import-vxa`` writes and the paper presets run). ``"model_options"`` overrides any
of the model's switches (``sim.models``: the model registry, ``ModelOptions``; each one
documented in docs/fidelity.md), e.g.
``{"model": "voxcad-land-water", "model_options": {"rotation_damping": 1}}``. The model also
sets the defaults of ``dt_fraction`` (0.5 / 0.7) and ``actuation.amplitude`` (0.39 / 0.14:
the fork reads its files' TempAmp 39, TempBase 25, CTE 0.01 as 0.14 strain).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import models, worlds
from .models import ModelOptions

WAVEFORMS = ("sine", "square", "impulse")
ENVIRONMENTS = worlds.KINDS  # the physics kinds (sim.worlds): every other world simulates as one
DEFAULT_MAX_STEPS = 20_000_000
MAX_SIDE = 64  # workspace side limit: a guard against absurd inputs, far above any robot here


class SceneError(ValueError):
    """A malformed scene. The message names the field first."""


DEFAULT_CYCLES = 50  # actuation cycles of an evaluation when a scene gives no duration


@dataclass(frozen=True)
class Material:
    youngs_modulus: float = 1e6  # Pa
    density: float = 1200.0  # kg / m^3
    poisson_ratio: float = 0.4
    friction_static: float = 1.0
    friction_kinetic: float = 0.5
    damping_bond: float = 1.0  # damping ratios (dimensionless)
    damping_global: float = 0.01
    damping_collision: float = 0.8


@dataclass(frozen=True)
class Environment:
    kind: str = worlds.LAND.name
    gravity: float = 9.81  # m / s^2, pointing -z
    fluid_density: float = 1000.0  # kg / m^3 (water only)
    drag_coefficient: float = 1.5  # (water only)


@dataclass(frozen=True)
class Actuation:
    frequency: float = 3.0  # Hz
    amplitude: float = 0.39  # linear strain of an active voxel's rest size
    waveform: str = "sine"


@dataclass(frozen=True)
class Scene:
    """A validated scene. Arrays are indexed body[x][y][z] (x-major)."""

    body: np.ndarray  # (X, Y, Z) int8: 0 empty, 1 passive, 2 active
    phase: np.ndarray  # (X, Y, Z) float64, radians
    # per-voxel fields, (X, Y, Z) float64 or None (None: the scalar everywhere); values at
    # empty voxels are 0
    youngs_modulus_field: np.ndarray | None = None  # Pa
    density_field: np.ndarray | None = None  # kg / m^3
    frequency_field: np.ndarray | None = None  # Hz, used by active voxels
    voxel_size: float = 0.05  # metres
    material: Material = field(default_factory=Material)
    environment: Environment = field(default_factory=Environment)
    actuation: Actuation = field(default_factory=Actuation)
    fixed: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))  # (n, 3)
    force_voxels: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    force_values: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # newtons
    initial_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m / s
    initial_angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # rad / s
    initial_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # metres, added to start positions
    duration_seconds: float = 0.0  # simulated after settling
    settle_seconds: float = 0.0
    # Step = min(dt_fraction x the link stability step, actuation period / 2000). 0.5 is the
    # largest fraction that kept a walker's and a swimmer's distance (8, 10 and 12 cycles)
    # within 1% of a dt_fraction-0.1 reference at every stiffness from 1 kPa to 10 MPa, with
    # every smaller fraction too (bench/dt_accuracy.py); 0.7 drifts 2% on a stiff walker. The
    # engine itself stays stable up to about 1.0 with bond damping 1 (3.0 without).
    dt_fraction: float = 0.5
    self_collisions: bool = True
    record_every: int = 0  # 0: no frames
    max_steps: int = DEFAULT_MAX_STEPS
    model: str = models.DEFAULT
    options: ModelOptions = field(default_factory=ModelOptions)

    @property
    def total_seconds(self) -> float:
        return self.settle_seconds + self.duration_seconds


_TOP_FIELDS = {
    "voxel_size", "material", "environment", "body", "phase", "actuation", "fixed", "forces",
    "initial_velocity", "initial_angular_velocity", "initial_offset", "duration", "settle_seconds",
    "dt_fraction", "self_collisions", "record", "notes", "max_steps",
    "youngs_modulus_field", "density_field", "frequency_field", "model", "model_options",
}
FIELDS = ("youngs_modulus_field", "density_field", "frequency_field")


def _number(value: Any, name: str, *, low: float | None = None, high: float | None = None,
            low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{name}: must be a number (got {value!r})")
    x = float(value)
    if not math.isfinite(x):
        raise SceneError(f"{name}: must be finite (got {value!r})")
    if low is not None and (x <= low if low_open else x < low):
        raise SceneError(f"{name}: must be {'>' if low_open else '>='} {low:g} (got {x:g})")
    if high is not None and x > high:
        raise SceneError(f"{name}: must be <= {high:g} (got {x:g})")
    return x


def _vector3(value: Any, name: str) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise SceneError(f"{name}: must be a list of 3 numbers (got {value!r})")
    return tuple(_number(v, f"{name}[{i}]") for i, v in enumerate(value))  # type: ignore


def _section(data: Any, name: str, allowed: set[str]) -> dict:
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise SceneError(f"{name}: must be an object (got {type(data).__name__})")
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise SceneError(f"{name}.{unknown[0]}: unknown field (allowed: {', '.join(sorted(allowed))})")
    return data


def _grid(value: Any, name: str, dtype) -> np.ndarray:
    try:
        arr = np.array(value, dtype=dtype)
    except (ValueError, TypeError) as exc:
        raise SceneError(f"{name}: must be a nested list of shape [X][Y][Z] of numbers ({exc})") from None
    if arr.ndim != 3:
        raise SceneError(f"{name}: must be 3-D, body[x][y][z] (got {arr.ndim}-D)")
    if min(arr.shape) < 1 or max(arr.shape) > MAX_SIDE:
        raise SceneError(f"{name}: each side must be 1..{MAX_SIDE} (got shape {list(arr.shape)})")
    return arr


def _voxel_field(value: Any, name: str, body: np.ndarray) -> np.ndarray | None:
    """A per-voxel field shaped like body: finite and > 0 at present voxels, 0 elsewhere."""
    if value is None:
        return None
    arr = _grid(value, name, np.float64)
    if arr.shape != body.shape:
        raise SceneError(f"{name}: shape {list(arr.shape)} differs from body {list(body.shape)}")
    present = body > 0
    for bad, rule in ((present & ~np.isfinite(arr), "be finite"), (present & ~(arr > 0), "be > 0")):
        if bad.any():
            where = [int(c) for c in np.argwhere(bad)[0]]
            raise SceneError(f"{name}: must {rule} at {where} (got {float(arr[tuple(where)])!r})")
    return np.where(present, arr, 0.0)


def mean_active_frequency(body: np.ndarray, field: np.ndarray, default: float) -> float:
    """The robot's mean actuation frequency over its active voxels (``default`` if none);
    exactly the common value when they all share one."""
    values = field[body == 2]
    if len(values) == 0:
        return default
    if np.all(values == values[0]):
        return float(values[0])
    return float(values.mean())


def _parse_material(data: Any) -> Material:
    d = _section(data, "material", set(Material.__dataclass_fields__))
    m = Material()
    kw = {k: getattr(m, k) for k in Material.__dataclass_fields__}
    for key, value in d.items():
        kw[key] = _number(value, f"material.{key}")
    _number(kw["youngs_modulus"], "material.youngs_modulus", low=0, low_open=True, high=1e12)
    _number(kw["density"], "material.density", low=0, low_open=True)
    _number(kw["poisson_ratio"], "material.poisson_ratio", low=-0.99, high=0.499)
    for key in ("friction_static", "friction_kinetic", "damping_bond", "damping_global",
                "damping_collision"):
        _number(kw[key], f"material.{key}", low=0)
    return Material(**kw)


def _parse_environment(data: Any) -> Environment:
    d = _section(data, "environment", set(Environment.__dataclass_fields__))
    kind = d.get("kind", worlds.LAND.name)
    if kind not in ENVIRONMENTS:
        raise SceneError(f"environment.kind: must be one of {', '.join(ENVIRONMENTS)} (got {kind!r})")
    gravity = _number(d["gravity"], "environment.gravity") if "gravity" in d else (
        worlds.get(kind).gravity)
    rho = _number(d.get("fluid_density", 1000.0), "environment.fluid_density", low=0)
    cd = _number(d.get("drag_coefficient", 1.5), "environment.drag_coefficient", low=0)
    return Environment(kind=kind, gravity=gravity, fluid_density=rho, drag_coefficient=cd)


def _parse_model(data: dict) -> tuple[str, ModelOptions]:
    model = data.get("model", models.DEFAULT)
    if model not in models.names():
        raise SceneError(f"model: must be one of {', '.join(models.names())} (got {model!r})")
    d = _section(data.get("model_options"), "model_options", set(models.option_names()))
    try:
        return model, models.options(model).replace(**d)
    except ValueError:
        pass
    for key, value in d.items():  # the first bad field, named
        try:
            models.option(key).check(value)
        except ValueError as exc:
            raise SceneError(f"model_options.{key}: {exc}") from None
    raise AssertionError("a bad field was found")


def _parse_actuation(data: Any, default_amplitude: float) -> Actuation:
    d = _section(data, "actuation", set(Actuation.__dataclass_fields__))
    freq = _number(d.get("frequency", 3.0), "actuation.frequency", low=0)
    amp = _number(d.get("amplitude", default_amplitude), "actuation.amplitude", low=0, high=0.9)
    wave = d.get("waveform", "sine")
    if wave not in WAVEFORMS:
        raise SceneError(f"actuation.waveform: must be one of {', '.join(WAVEFORMS)} (got {wave!r})")
    return Actuation(frequency=freq, amplitude=amp, waveform=wave)


def _voxel_index(value: Any, name: str, body: np.ndarray) -> tuple[int, int, int]:
    if (not isinstance(value, (list, tuple)) or len(value) != 3
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise SceneError(f"{name}: must be [x, y, z] integers (got {value!r})")
    if not all(0 <= v < s for v, s in zip(value, body.shape, strict=True)):
        raise SceneError(f"{name}: {list(value)} is outside the body of shape {list(body.shape)}")
    if body[tuple(value)] == 0:
        raise SceneError(f"{name}: {list(value)} is an empty voxel")
    return tuple(value)  # type: ignore


def parse_scene(data: Any) -> Scene:
    """Validate a scene document (a dict from JSON) and return a Scene with defaults filled."""
    if isinstance(data, Scene):
        return data
    if isinstance(data, str | os.PathLike):
        raise SceneError(f"scene: must be a dict, the JSON object itself (got the {type(data).__name__} "
                         f"{str(data)[:60]!r}; a file: json.load it first, or softevo simulate FILE)")
    if not isinstance(data, dict):
        raise SceneError(f"scene: must be a JSON object (got {type(data).__name__})")
    unknown = sorted(set(data) - _TOP_FIELDS)
    if unknown:
        raise SceneError(f"{unknown[0]}: unknown field")
    if "body" not in data:
        raise SceneError("body: missing (a nested list body[x][y][z] of 0, 1, 2)")
    body = _grid(data["body"], "body", np.float64)
    if not np.all(np.isin(body, (0, 1, 2))):
        raise SceneError("body: values must be 0 (empty), 1 (passive) or 2 (active)")
    body = body.astype(np.int8)
    if not body.any():
        raise SceneError("body: has no voxels (every value is 0)")
    if "phase" in data and data["phase"] is not None:
        phase = _grid(data["phase"], "phase", np.float64)
        if phase.shape != body.shape:
            raise SceneError(f"phase: shape {list(phase.shape)} differs from body {list(body.shape)}")
        if not np.all(np.isfinite(phase)):
            raise SceneError("phase: must be finite numbers")
    else:
        phase = np.zeros(body.shape)

    fields = {name: _voxel_field(data.get(name), name, body) for name in FIELDS}

    voxel_size = _number(
        data.get("voxel_size", Scene.voxel_size), "voxel_size", low=0, low_open=True, high=10
    )
    model, options = _parse_model(data)
    material = _parse_material(data.get("material"))
    environment = _parse_environment(data.get("environment"))
    actuation = _parse_actuation(data.get("actuation"), models.get(model).amplitude)

    fixed_list = data.get("fixed") or []
    if not isinstance(fixed_list, list):
        raise SceneError("fixed: must be a list of [x, y, z]")
    fixed = np.array([_voxel_index(v, f"fixed[{i}]", body) for i, v in enumerate(fixed_list)],
                     dtype=np.int64).reshape(-1, 3)

    forces_list = data.get("forces") or []
    if not isinstance(forces_list, list):
        raise SceneError("forces: must be a list of {voxel, force}")
    fv, ff = [], []
    for i, item in enumerate(forces_list):
        item = _section(item, f"forces[{i}]", {"voxel", "force"})
        if "voxel" not in item or "force" not in item:
            raise SceneError(f"forces[{i}]: needs both 'voxel' and 'force'")
        fv.append(_voxel_index(item["voxel"], f"forces[{i}].voxel", body))
        ff.append(_vector3(item["force"], f"forces[{i}].force"))

    duration = _section(data.get("duration", {"cycles": DEFAULT_CYCLES}), "duration",
                        {"cycles", "seconds", "max_seconds"})
    if "max_seconds" in duration and "cycles" not in duration:
        raise SceneError("duration.max_seconds: caps duration.cycles; give cycles with it")
    if len(duration.keys() - {"max_seconds"}) != 1:
        raise SceneError("duration: give exactly one of {'cycles': n} or {'seconds': s}")
    if "cycles" in duration:
        cycles = _number(duration["cycles"], "duration.cycles", low=0)
        frequency = actuation.frequency
        if fields["frequency_field"] is not None:
            frequency = mean_active_frequency(body, fields["frequency_field"], frequency)
        if frequency <= 0 and cycles > 0:
            raise SceneError("duration.cycles: needs actuation.frequency > 0 (or give seconds)")
        seconds = cycles / frequency if cycles > 0 else 0.0
        if "max_seconds" in duration:
            seconds = min(seconds, _number(duration["max_seconds"], "duration.max_seconds", low=0,
                                           low_open=True))
    else:
        seconds = _number(duration["seconds"], "duration.seconds", low=0)

    record = _section(data.get("record"), "record", {"every"})
    record_every = 0
    if "every" in record:
        every = _number(record["every"], "record.every", low=1)
        record_every = int(every)

    max_steps = int(_number(data.get("max_steps", DEFAULT_MAX_STEPS), "max_steps", low=1))
    self_collisions = data.get("self_collisions", True)
    if not isinstance(self_collisions, bool):
        raise SceneError(f"self_collisions: must be true or false (got {self_collisions!r})")
    notes = data.get("notes", "")
    if not isinstance(notes, str):
        raise SceneError("notes: must be a string")

    return Scene(
        body=body,
        phase=phase,
        **fields,
        voxel_size=voxel_size,
        material=material,
        environment=environment,
        actuation=actuation,
        fixed=fixed,
        force_voxels=np.array(fv, dtype=np.int64).reshape(-1, 3),
        force_values=np.array(ff, dtype=np.float64).reshape(-1, 3),
        initial_velocity=_vector3(data.get("initial_velocity", [0, 0, 0]), "initial_velocity"),
        initial_angular_velocity=_vector3(data.get("initial_angular_velocity", [0, 0, 0]),
                                          "initial_angular_velocity"),
        initial_offset=_vector3(data.get("initial_offset", [0, 0, 0]), "initial_offset"),
        duration_seconds=seconds,
        settle_seconds=_number(data.get("settle_seconds", 0.0), "settle_seconds", low=0),
        dt_fraction=_number(data.get("dt_fraction", models.get(model).dt_fraction),
                            "dt_fraction", low=0, low_open=True, high=10),
        self_collisions=self_collisions,
        record_every=record_every,
        max_steps=max_steps,
        model=model,
        options=options,
    )
