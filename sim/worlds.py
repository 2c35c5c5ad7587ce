"""The world registry: one ``World`` record per world, the only place a world is defined.

A world is what a robot is evaluated in: its gravity, whether it has a floor, whether a
fluid drags on the voxels, how its distance is measured, how long a robot settles before
it is actuated, and how it is drawn (colour, background, report label). Everything that
names worlds reads them here: the scene schema (``environment.kind``), the engine's
physics codes, the CLI's ``--env`` choices, the REST schema's enums, the dashboard's
colours (``GET /api/worlds``), the report's labels and the VXA export.

The physics has three kinds, each a built-in world: ``land`` (a floor, gravity), ``water``
(neutral buoyancy, drag) and ``void`` (nothing). Any other world simulates as the kind with
its floor and drag, with its own gravity (``World.scene_environment``), so its scenes run
on any engine and any worker without the registration. Adding a world::

    from softevo.sim import worlds
    worlds.register(worlds.World("moon", gravity=1.62, floor=True, drag=False, colour="#8a8f98"))

and ``worlds.unregister("moon")`` removes it again. ``evolve=True`` worlds (the default)
are offered for evolution (the CLI, the REST schema, transitions between two of them).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from .registry import Registry

HORIZONTAL, THREE_D = "horizontal", "3-D"


@dataclass(frozen=True)
class World:
    """One world. ``gravity`` in m/s^2 (pointing -z); ``floor``: a ground plane at z = 0;
    ``drag``: fluid drag on the voxels (water's); ``distance``: ``"horizontal"`` (on a
    floor) or ``"3-D"``; ``settle_seconds``: the settling time before actuation in the
    Voxelyze 2.0 model (the paper's model always settles 0.5 s); ``colour`` (``#rrggbb``)
    its lines and points, ``background`` the replay's sky, ``colormap`` (a matplotlib name)
    the report figures' shades of it; ``label`` how a report says a result is in it
    (``"on land"``); ``evolve``: offered as an evolution environment."""

    name: str
    gravity: float
    floor: bool
    drag: bool
    distance: str = ""
    settle_seconds: float | None = None
    colour: str = "#667085"
    background: str = "#eef2f6"
    label: str = ""
    colormap: str = "Greys"
    evolve: bool = True

    def __post_init__(self) -> None:
        if not self.name or any(c in self.name for c in " :,>@-"):
            raise ValueError(f"a world's name must be a word without ' :,>@-' (got {self.name!r})")
        if self.floor and self.drag:
            raise ValueError(f"world {self.name}: the engine has no floor under a fluid")
        if not self.distance:
            object.__setattr__(self, "distance", HORIZONTAL if self.floor else THREE_D)
        if self.distance not in (HORIZONTAL, THREE_D):
            raise ValueError(f"world {self.name}: distance must be {HORIZONTAL} or {THREE_D}")
        if self.settle_seconds is None:
            object.__setattr__(self, "settle_seconds", 0.5 if self.floor else 0.0)
        if not self.label:
            object.__setattr__(self, "label", f"{'on' if self.floor else 'in'} {self.name}")

    @property
    def kind(self) -> str:
        """The physics kind (a built-in world's name) this world simulates as."""
        for world in _KINDS:
            if (world.floor, world.drag) == (self.floor, self.drag):
                return world.name
        raise AssertionError("every floor/drag pair has a kind")

    def scene_environment(self) -> dict[str, Any]:
        """The scene's ``environment`` section: the kind, and the gravity where it is not
        the kind's own."""
        environment: dict[str, Any] = {"kind": self.kind}
        if self.gravity != get(self.kind).gravity:
            environment["gravity"] = self.gravity
        return environment

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "kind": self.kind}


_KINDS = (
    World("land", gravity=9.81, floor=True, drag=False, colour="#b7791f", background="#eef2f6",
          colormap="Oranges"),
    World("water", gravity=0.0, floor=False, drag=True, colour="#1f6feb", background="#d6e9f6",
          colormap="Blues"),
    World("void", gravity=0.0, floor=False, drag=False, colour="#667085", background="#f4f4f5",
          evolve=False),
)
LAND, WATER, VOID = _KINDS
KINDS = tuple(world.name for world in _KINDS)  # the scene schema's environment.kind
_REGISTRY: Registry[World] = Registry("world", _KINDS)
register, unregister, get = _REGISTRY.register, _REGISTRY.unregister, _REGISTRY.get
all_worlds, added = _REGISTRY.records, _REGISTRY.added


def names(evolve: bool = False) -> tuple[str, ...]:
    """Every world's name in registration order (``evolve=True``: those offered for evolution)."""
    return tuple(world.name for world in _REGISTRY.records() if world.evolve or not evolve)


def register_missing(records: tuple[World, ...]) -> None:
    """Register each of ``records`` this process does not know yet (a pool's initializer)."""
    for world in records:
        if world.name not in _REGISTRY:
            _REGISTRY.register(world)
