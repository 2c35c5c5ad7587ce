"""What an evaluation returns: one ``Outcome``, the only result type between the simulator,
the workers, the algorithm, the coordinator and ``softevo.evolve``.

An outcome is scored when it is made (``Outcome.of_simulation``): an unstable simulation,
or a NaN or infinite distance, scores ``FAILED_DISTANCE`` and keeps why as its ``error``;
a crash is ``Outcome.failure``. A compound world's parts combine into one outcome
(``Outcome.combine``). Its JSON (``to_json`` / ``from_json``) is the evaluation's part of a
worker's result (``worker.tasks.TaskResult``): ``distance, stable, error, descriptors,
steps, simulated_seconds``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

FAILED_DISTANCE = 0.0
"""Distance given to a failed or unstable evaluation (the simulator's own convention).
Selection also ranks such an individual behind every successful one."""

JSON_KEYS = ("distance", "stable", "error", "descriptors", "steps", "simulated_seconds")


@dataclass(frozen=True)
class Outcome:
    """One evaluation: ``distance`` in voxel lengths (``FAILED_DISTANCE`` when it failed),
    ``stable``, ``error`` (why it failed; None when it did not), ``steps`` and
    ``simulated_seconds`` it cost (summed over a compound world's parts; settling included)
    and the shape ``descriptors`` its evaluator measured (None: not measured here)."""

    distance: float
    stable: bool = True
    error: str | None = None
    steps: int = 0
    simulated_seconds: float = 0.0
    descriptors: dict[str, Any] | None = None

    @property
    def ok(self) -> bool:
        return self.stable and self.error is None

    @classmethod
    def of_simulation(cls, distance: float, stable: bool, reason: str | None = None,
                      steps: int = 0, simulated_seconds: float = 0.0) -> Outcome:
        """The scored outcome of a finished simulation: an unstable one, or one with a NaN or
        infinite distance, scores ``FAILED_DISTANCE`` (unstable, ``reason`` or what went
        wrong as its error); a stable finite one keeps its distance."""
        cost = {"steps": int(steps), "simulated_seconds": float(simulated_seconds)}
        if not stable:
            return cls(FAILED_DISTANCE, False, str(reason) if reason else "unstable", **cost)
        if not math.isfinite(distance):
            return cls(FAILED_DISTANCE, False, str(reason) if reason else "non-finite distance", **cost)
        return cls(float(distance), True, None, **cost)

    @classmethod
    def of_result(cls, result: Any) -> Outcome:
        """The scored outcome of a ``sim.Result``."""
        return cls.of_simulation(float(result.distance), bool(result.stable), result.reason,
                                 int(result.steps), float(result.simulated_seconds))

    @classmethod
    def failure(cls, error: str) -> Outcome:
        """An evaluation that could not finish (a crash, an empty body, a lost job)."""
        return cls(FAILED_DISTANCE, False, str(error))

    @classmethod
    def crash(cls, exc: BaseException) -> Outcome:
        """The failure of an evaluation that raised ``exc``."""
        return cls.failure(f"{type(exc).__name__}: {exc}")

    @classmethod
    def combine(cls, parts: Sequence[Outcome]) -> Outcome:
        """One outcome of a compound world's parts, simulated one after the other: distance
        the sum of the parts' (each the distance travelled in its own world and share of the
        time), stable if every part is, else ``FAILED_DISTANCE`` with the first failed
        part's error; steps and simulated seconds summed. One part is returned as it is."""
        if len(parts) == 1:
            return parts[0]
        if not parts:
            raise ValueError("an evaluation has at least one part")
        cost = {"steps": sum(p.steps for p in parts),
                "simulated_seconds": float(sum(p.simulated_seconds for p in parts))}
        failed = [p for p in parts if not p.ok]
        if failed:
            return cls(FAILED_DISTANCE, False, failed[0].error, **cost)
        return cls.of_simulation(float(sum(p.distance for p in parts)), True, **cost)

    def with_descriptors(self, descriptors: dict[str, Any] | None) -> Outcome:
        """The same outcome with the shape descriptors its evaluator measured."""
        return Outcome(self.distance, self.stable, self.error, self.steps, self.simulated_seconds,
                       descriptors)

    def to_json(self) -> dict[str, Any]:
        """Plain JSON with the keys ``JSON_KEYS``."""
        return {key: getattr(self, key) for key in JSON_KEYS}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Outcome:
        """The outcome of ``to_json``'s JSON (or of a worker's result, which holds those keys
        among others); absent costs read as 0, absent descriptors as None. An error fails
        even a stable outcome (``FAILED_DISTANCE``)."""
        error = data.get("error") or None
        return cls(
            distance=FAILED_DISTANCE if error else float(data["distance"]),
            stable=bool(data["stable"]),
            error=error,
            steps=int(data.get("steps") or 0),
            simulated_seconds=float(data.get("simulated_seconds") or 0.0),
            descriptors=data.get("descriptors"),
        )
