"""The physics-model registry: one ``Model`` record per model, the only place a model is defined.

A model is a named set of the engine's physics switches (``ModelOptions``) with the scene
defaults that go with it (``dt_fraction``, the actuation ``amplitude``) and a one-line
description. Two are built in: ``voxelyze-2`` (the default: the model validated against
Voxelyze 2.0, analytic solutions and conservation laws) and ``voxcad-land-water`` (the
paper's own engine, the VoxCAD land/water fork in evosoro: what ``softevo import-vxa`` writes
and the paper presets run). Everything that names models reads them here: the scene schema
(``"model"``, ``"model_options"``), the REST schema's enum, the CLI, the treatments, the VXA
importer.

API:

- ``names()``: every model's name, in registration order (the REST enum); ``DEFAULT``;
- ``get(name)``: the ``Model`` record (KeyError naming the choices);
- ``options(name)``: its ``ModelOptions``; ``defaults(name)``: the scene defaults of a model
  as plain values (``dt_fraction``, ``amplitude``, ``model_options`` as a dict), for code
  that writes scenes for it;
- ``OPTIONS``: the option fields, one ``Option`` each (name, and either its ``choices`` or
  its numeric range), in ``ModelOptions``' order; ``option(name)`` one of them;
  ``option_names()`` their names (the keys ``model_options`` accepts);
- ``register(model)`` / ``unregister(name)``: a model of one's own made of these switches,
  e.g. ``models.register(models.Model("soft-fork", models.options("voxcad-land-water")
  .replace(rotation_damping=1.0), 0.7, 0.14, "the fork without its angular damping"))``.

Each switch is documented in docs/fidelity.md (the fork's file and line, the measured effect).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

from .registry import Registry

# The arithmetic of a run: "float64" throughout (Voxelyze 2.0's, and the paper's engine's: its
# ``vfloat`` is double in the builds it ships, docs/fidelity.md), or "mixed": each link's
# geometry, deformation and loads in float32, positions, orientations, momenta, contacts and
# drag in float64 (halves the link loop's memory and doubles its SIMD width; docs/fidelity.md
# has its agreement with float64 and with the fork).
PRECISIONS = ("float64", "mixed")


@dataclass(frozen=True)
class ModelOptions:
    """The physics choices where the paper's engine (the VoxCAD land/water fork in evosoro)
    and Voxelyze 2.0 differ; each one a switch (docs/fidelity.md has the fork's file and line
    and the measured effect of each). The defaults are Voxelyze 2.0's; each ``Model`` holds
    its own."""

    rotation_damping: float = 1.0  # factor on the global angular damping (the fork: 10)
    collision_horizon: int = 1  # voxels within this many bond hops never collide (1: bonded)
    actuation_start: str = "settled"  # actuation begins after settling, or at the "start"
    actuation_clock: str = "settled"  # the sine's time: since settling, or "absolute"
    distance: str = "horizontal"  # on land: "horizontal" or "3d" (water is 3-D anyway)
    drag: str = "faces"  # water drag on each voxel's own faces, or on the deformed "mesh"
    min_steps_per_cycle: int = 2000  # the step resolves an actuation cycle at least this finely
    contact: str = "voxelyze-2"  # self-contact: "voxelyze-2" or the fork's 1.5-voxel "voxcad" spheres
    actuation_lag: int = 0  # steps by which the sizes lag the clock (the fork: 1)
    friction: str = "voxelyze-2"  # the floor's static/kinetic rule: "voxelyze-2" or "voxcad"
    precision: str = "float64"  # "float64", or "mixed": each link's beam in float32 (sim.kernels)

    def replace(self, **changes: Any) -> ModelOptions:
        """A copy with ``changes`` (each checked by ``Option.check``; ValueError otherwise)."""
        return replace(self, **{k: option(k).check(v) for k, v in changes.items()})

    def to_dict(self) -> dict[str, Any]:
        """The switches as plain values (every field is a number or a string: a shallow copy,
        about 10x faster than ``dataclasses.asdict``, called once per scene written)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class Option:
    """One field of ``ModelOptions``: either a choice among ``choices`` or a number in
    [``low``, ``high``] (``whole``: an integer)."""

    name: str
    choices: tuple[str, ...] = ()
    low: float = 0.0
    high: float = 1e6
    whole: bool = False

    def check(self, value: Any) -> Any:
        """``value`` as the field holds it; ValueError with a one-line reason otherwise (the
        scene parser prefixes ``model_options.<name>: ``)."""
        if self.choices:
            if value not in self.choices:
                raise ValueError(f"must be one of {', '.join(self.choices)} (got {value!r})")
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"must be a number (got {value!r})")
        x = float(value)
        if not self.low <= x <= self.high:  # NaN fails too
            raise ValueError(f"must be in [{self.low:g}, {self.high:g}] (got {value!r})")
        if self.whole:
            if x != int(x):
                raise ValueError(f"must be a whole number (got {value!r})")
            return int(x)
        return x


OPTIONS: tuple[Option, ...] = (
    Option("rotation_damping", low=0.0, high=1e3),
    Option("collision_horizon", low=1, whole=True),
    Option("actuation_start", ("settled", "start")),
    Option("actuation_clock", ("settled", "absolute")),
    Option("distance", ("horizontal", "3d")),
    Option("drag", ("faces", "mesh")),
    Option("min_steps_per_cycle", low=0, whole=True),
    Option("contact", ("voxelyze-2", "voxcad")),
    Option("actuation_lag", low=0, whole=True),
    Option("friction", ("voxelyze-2", "voxcad")),
    Option("precision", PRECISIONS),
)
_OPTIONS = {o.name: o for o in OPTIONS}
assert tuple(_OPTIONS) == tuple(f.name for f in fields(ModelOptions)), "one Option per field"


def option(name: str) -> Option:
    """The option field called ``name``; KeyError naming the fields."""
    try:
        return _OPTIONS[name]
    except KeyError:
        raise KeyError(f"unknown model option {name!r}; choose one of {', '.join(_OPTIONS)}") from None


def option_names() -> tuple[str, ...]:
    """The keys a scene's ``model_options`` may hold, in ``ModelOptions``' order."""
    return tuple(_OPTIONS)


@dataclass(frozen=True)
class Model:
    """One physics model: its switches, the scene defaults that go with them
    (``dt_fraction``: the step as a fraction of the stability limit; ``amplitude``: the
    actuation's linear strain) and a one-line ``description``."""

    name: str
    options: ModelOptions
    dt_fraction: float
    amplitude: float
    description: str

    def defaults(self) -> dict[str, Any]:
        """The scene defaults of this model as plain values."""
        return {"dt_fraction": self.dt_fraction, "amplitude": self.amplitude,
                "model_options": self.options.to_dict()}


VOXELYZE_2 = Model(
    "voxelyze-2", ModelOptions(), dt_fraction=0.5, amplitude=0.39,
    description="Voxelyze 2.0's physics, validated against it, analytic solutions and "
                "conservation laws")
VOXCAD_LAND_WATER = Model(
    "voxcad-land-water",
    ModelOptions(rotation_damping=10.0, collision_horizon=3, actuation_start="settled",
                 actuation_clock="absolute", distance="3d", drag="mesh", min_steps_per_cycle=0,
                 contact="voxcad", actuation_lag=1, friction="voxcad"),
    # the fork reads its files' TempAmp 39, TempBase 25, CTE 0.01 as 0.14 strain
    dt_fraction=0.7, amplitude=0.14,
    description="the paper's engine: the VoxCAD land/water fork in evosoro (import-vxa, the "
                "paper presets)")
DEFAULT = VOXELYZE_2.name
_BUILT_IN = (VOXELYZE_2, VOXCAD_LAND_WATER)
_REGISTRY: Registry[Model] = Registry("model", _BUILT_IN)
register, unregister, get, names = _REGISTRY.register, _REGISTRY.unregister, _REGISTRY.get, _REGISTRY.names


def options(name: str) -> ModelOptions:
    """The switches of the model called ``name``."""
    return get(name).options


def defaults(name: str) -> dict[str, Any]:
    """The scene defaults of the model called ``name`` (``Model.defaults``)."""
    return get(name).defaults()
