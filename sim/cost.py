"""What an evaluation costs: its voxel-steps, and the seconds one CPU core takes for them.

- ``voxel_steps(scene)``: (voxels simulated, steps) of a validated ``Scene``: the engine's
  own count (``system.scene_steps``, which builds no robot when every voxel has one stiffness
  and density, the usual case).
- ``CostModel``: seconds of one evaluation on one core, ``overhead + voxels * steps / rate``
  with a rate per (physics model, world). ``MEASURED`` holds this project's figures
  (``measure`` re-measures them where it runs: ``softevo plan --measure``).

The sleep engine (``sim.sleep_engine``) and the planner (``service.plan.model``) read the cost
from here, and nowhere else.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from . import engines, worlds
from .scene import Scene
from .system import largest_component, scene_steps


def voxel_steps(scene: Scene) -> tuple[int, int]:
    """(voxels, steps) the engine simulates for ``scene`` (0, 0 for an empty body)."""
    voxels = int(np.count_nonzero(largest_component(scene.body)))
    return (voxels, scene_steps(scene)) if voxels else (0, 0)


@dataclass(frozen=True)
class CostModel:
    """Seconds of one evaluation on one core: ``overhead_seconds`` (building the robot,
    reading the result) plus its voxel-steps at ``rates[(model, world)]`` voxel-steps/s."""

    rates: dict[tuple[str, str], float] = field(default_factory=dict)
    overhead_seconds: float = 0.0
    default_rate: float = 1e7
    source: str = "measured"

    def rate(self, model: str, world: str) -> float:
        return float(self.rates.get((model, world), self.default_rate))

    def seconds(self, voxels: int, steps: int, model: str, world: str) -> float:
        if voxels <= 0:
            return 0.0
        return self.overhead_seconds + voxels * steps / self.rate(model, world)

    def scene_seconds(self, scene: Scene) -> float:
        voxels, steps = voxel_steps(scene)
        return self.seconds(voxels, steps, scene.model, scene.environment.kind)

    def to_dict(self) -> dict:
        return {
            "rates": {f"{m}/{w}": r for (m, w), r in sorted(self.rates.items())},
            "overhead_seconds": self.overhead_seconds,
            "default_rate": self.default_rate,
            "source": self.source,
        }


# One core of this project's machine (docs/benchmarks.md "Cost model"), random paper-like 7^3
# robots, numba, one thread per robot, whole evaluations: voxel-steps/s by model and world.
# ``measure`` over the tiny grid's sampled robots, 3 repeats, twice, on the idle 2-core Intel
# Xeon (Sapphire Rapids class, AVX-512), 2026-12-07 (after the vectorized voxel update; they
# were 1.6e7 / 8.0e6 / 1.45e7 / 9.5e6 before it, 2026-12-04, CPU not recorded).
MEASURED = CostModel(
    rates={
        ("voxcad-land-water", worlds.LAND.name): 2.2e7,
        ("voxcad-land-water", worlds.WATER.name): 1.15e7,
        ("voxcad-land-water", worlds.VOID.name): 2.2e7,
        ("voxelyze-2", worlds.LAND.name): 1.5e7,
        ("voxelyze-2", worlds.WATER.name): 1.25e7,
        ("voxelyze-2", worlds.VOID.name): 1.5e7,
    },
    overhead_seconds=0.002,
    default_rate=1.5e7,
    source="docs/benchmarks.md",
)


def measure(scenes_by_key: dict[tuple[str, str], list[dict]], repeats: int = 3) -> CostModel:
    """A ``CostModel`` measured here: each key's scenes simulated one by one on one thread
    (after a warm-up), the rate the median over ``repeats`` of voxel-steps per second, the
    overhead a one-step scene's seconds."""
    from .scene import parse_scene

    engines.simulate_many([next(iter(scenes_by_key.values()))[0]], threads=1)  # compile / load
    rates = {}
    for key, scenes in scenes_by_key.items():
        parsed = [parse_scene(dict(s)) for s in scenes]
        work = sum(v * s for v, s in map(voxel_steps, parsed))
        runs = []
        for _ in range(repeats):
            start = time.perf_counter()
            engines.simulate_many(parsed, threads=1)
            runs.append(time.perf_counter() - start)
        rates[key] = work / float(np.median(runs))
    tiny = dict(next(iter(scenes_by_key.values()))[0], duration={"cycles": 1, "max_seconds": 1e-4})
    start = time.perf_counter()
    for _ in range(5):
        engines.simulate_many([tiny], threads=1)
    overhead = (time.perf_counter() - start) / 5
    return CostModel(rates, overhead, float(np.median(list(rates.values()))), "measured here")
