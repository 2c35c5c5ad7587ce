"""The engine registry: which engine runs a batch, and the one error an unusable engine raises.

One ``Engine`` record per engine in the shared registry (``sim.registry.Registry``), the
only place an engine is named:

- ``numba`` (the default, CPU: ``sim.numba_engine``);
- ``cuda`` (NVIDIA GPUs through numba-cuda, or its simulator: ``sim.cuda_engine``);
- ``sleep`` (no physics, only the time: ``sim.sleep_engine``, for benches of the system
  around the simulator).

Every engine module has ``simulate_many(scenes, device=None, ...)`` taking the same scenes
and returning the same ``Result`` (``sim.result``). This registry names each engine's
module as a string and imports it on first use (``module(name)``), so it imports no engine
and no engine imports another: the cuda engine's numba-cuda, say, is loaded only when it
is asked for. ``simulate_many``/``simulate`` below are the entry points that dispatch
(``sim.simulate_many`` is this one).

API: ``ENGINE_REGISTRY`` (a ``sim.registry.Registry``: ``register``, ``unregister``,
``names()``), ``ENGINES`` (the built-in names), ``DEFAULT``, ``get(name)`` (the record;
``EngineUnavailable`` for an unknown name), ``module(name)``, ``check_engine(name)``,
``simulate_many``, ``simulate``.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from softevo.sim.registry import Registry


class EngineUnavailable(RuntimeError):
    """The engine asked for cannot run here: an unknown engine name, numba-cuda not
    installed, or no such device. The message is one line meant for a person (the CLI prints it, exit 2)."""


@dataclass(frozen=True)
class Engine:
    """One engine: its name, the module that implements it (``simulate_many``), whether it
    takes numba's ``threads``, and a one-line description."""

    name: str
    module: str
    threads: bool
    description: str


ENGINE_REGISTRY: Registry[Engine] = Registry("engine", (
    Engine("numba", "softevo.sim.numba_engine", True,
           "CPU, numba: one robot per core (the default)"),
    Engine("cuda", "softevo.sim.cuda_engine", False,
           "NVIDIA GPU through numba-cuda (device cuda:N), or numba-cuda's simulator"),
    Engine("sleep", "softevo.sim.sleep_engine", False,
           "no physics: sleeps each evaluation's modelled cost (device x<speed-up>)"),
))
register, unregister, names = ENGINE_REGISTRY.register, ENGINE_REGISTRY.unregister, ENGINE_REGISTRY.names
ENGINES = names()  # the built-in engines' names (``names()``: with any registered since)
DEFAULT = "numba"


def get(name: str) -> Engine:
    """The engine called ``name``; ``EngineUnavailable`` naming the choices."""
    if not isinstance(name, str) or name not in ENGINE_REGISTRY:
        raise EngineUnavailable(f"engine: must be one of {', '.join(names())} (got {name!r})")
    return ENGINE_REGISTRY.get(name)


def check_engine(engine: str) -> str:
    """``engine`` if it is a registered engine's name; else ``EngineUnavailable``."""
    return get(engine).name


def module(name: str) -> ModuleType:
    """The module of the engine called ``name``, imported on first use."""
    return importlib.import_module(get(name).module)


def simulate_many(scenes: list, threads: int | None = None, engine: str = DEFAULT,
                  device: str | None = None) -> list:
    """Simulate many robots on ``engine``; ``Result``s in the order of ``scenes``.

    ``threads`` caps numba's threads for this call (the numba engine; default: all cores
    numba was given). ``device``: the cuda engine's "cuda:N", the sleep engine's speed-up
    "x<factor>" (e.g. "x100")."""
    record = get(engine)
    options: dict[str, Any] = {"device": device}
    if record.threads:
        options["threads"] = threads
    return module(engine).simulate_many(scenes, **options)


def simulate(scene: Any, threads: int | None = 1, engine: str = DEFAULT,
             device: str | None = None):
    """Simulate one robot (docs/spec.md section 1); ``engine``/``device`` as ``simulate_many``."""
    return simulate_many([scene], threads=threads, engine=engine, device=device)[0]
