"""Environment schedules: which world each generation is evaluated in, and the switch.

A ``Schedule`` lists the worlds in order with the first generation of each, e.g.
``Schedule([(LAND.name, 0), (WATER.name, 50)])`` (the registry's worlds, ``sim.worlds``):
generations 0..49 on land, 50 and later in water. Its text form is ``land:0,water:50``
(``parse`` / ``format``). ``switch`` is the one place that decides an environment switch:
an algorithm whose environment is not the one of the generation about to start is moved
there (``Evolution.reevaluate_all``: the whole population is evaluated again in the new
world).

A world may be entered gradually: ``Schedule([(LAND.name, 0), (WATER.name, 50)], spans=[0, 10])``
(text ``land:0,water:50+10``) spends generations 50..59 in compound worlds
(``evolution.environments``: ``land>water@0.091`` .. ``land>water@0.909``, the water share rising
linearly) and is in pure water from generation 60. Each generation of the span is another
world, so ``switch`` moves the population (re-evaluates it) at every one of them.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from softevo.evolution import environments


class Schedule:
    """Worlds with the generation each starts; see the module doc."""

    __slots__ = ("entries", "spans")

    def __init__(self, entries: Iterable[tuple[str, int]], spans: Iterable[int] | None = None) -> None:
        checked: list[tuple[str, int]] = []
        for entry in entries:
            try:
                environment, first = entry
            except (TypeError, ValueError):
                raise ValueError(f"schedule entry {entry!r} is not (environment, first generation)") from None
            if not isinstance(environment, str) or not environment or any(c in environment for c in ":, "):
                raise ValueError(f"schedule: bad environment name {environment!r}")
            if isinstance(first, bool) or not isinstance(first, int) or first < 0:
                raise ValueError(
                    f"schedule: first generation of {environment} must be an integer >= 0 (got {first!r})"
                )
            if checked and first <= checked[-1][1]:
                before, start = checked[-1]
                raise ValueError(f"schedule: {environment} starts at {first}, not after {before} at {start}")
            if not checked and first != 0:
                raise ValueError(f"schedule: the first environment must start at generation 0 (got {first})")
            checked.append((environment, int(first)))
        if not checked:
            raise ValueError("schedule: no environment")
        self.entries: tuple[tuple[str, int], ...] = tuple(checked)
        self.spans: tuple[int, ...] = self._checked_spans(spans)

    def _checked_spans(self, spans: Iterable[int] | None) -> tuple[int, ...]:
        """Generations of compound worlds before each world is pure (0: entered at once)."""
        spans = tuple(spans) if spans is not None else (0,) * len(self.entries)
        if len(spans) != len(self.entries):
            raise ValueError(f"schedule: {len(spans)} switch-over spans for {len(self.entries)} worlds")
        for index, span in enumerate(spans):
            if isinstance(span, bool) or not isinstance(span, int) or span < 0:
                raise ValueError(f"schedule: switch-over of {self.entries[index][0]} must be an integer >= 0")
        if spans[0] != 0:
            raise ValueError("schedule: the first environment has nothing to switch over from")
        for (environment, first), span, (_, following) in zip(
            self.entries, spans, self.entries[1:], strict=False
        ):
            if first + span >= following:
                raise ValueError(
                    f"schedule: the switch-over to {environment} ({first}+{span}) must end before {following}"
                )
        return spans

    @classmethod
    def static(cls, environment: str) -> Schedule:
        """One world for every generation."""
        return cls([(environment, 0)])

    @classmethod
    def from_until(cls, entries: Iterable[tuple[str, int]]) -> Schedule:
        """From [(environment, until_generation), ...]: each world until (not including) its
        ``until``, the last one also after it."""
        entries = list(entries)
        starts = [0] + [int(until) for _, until in entries[:-1]]
        return cls([(environment, start) for (environment, _), start in zip(entries, starts, strict=True)])

    @classmethod
    def parse(cls, text: str) -> Schedule:
        """From the text form ``env:first,env:first,...`` (``evolution.environments.schedule_entries``);
        ValueError naming the problem."""
        return cls(*environments.schedule_entries(text))

    def format(self) -> str:
        """The text form, e.g. ``land:0,water:50`` (``water:50+10`` with a switch-over)."""
        return ",".join(
            f"{environment}:{first}" + (f"+{span}" if span else "")
            for (environment, first), span in zip(self.entries, self.spans, strict=True)
        )

    def environment_at(self, generation: int) -> str:
        """The world individuals are evaluated in at ``generation`` (a compound world's name
        within a switch-over, ``evolution.environments``)."""
        index = 0
        for position, (_, first) in enumerate(self.entries):
            if generation >= first:
                index = position
        environment, first = self.entries[index]
        span = self.spans[index]
        if span and generation < first + span:
            share = environments.share_at(generation - first, span)
            return environments.compound(self.entries[index - 1][0], environment, share)
        return environment

    def switches_at(self, generation: int) -> bool:
        """True if ``generation`` is evaluated in another world than the one before it."""
        return generation > 0 and self.environment_at(generation) != self.environment_at(generation - 1)

    @property
    def environments(self) -> list[str]:
        return [environment for environment, _ in self.entries]

    def switch(self, algorithm: Any, generation: int) -> bool:
        """Move ``algorithm`` (an ``Evolution``) into the world of ``generation`` if it is in
        another one (``reevaluate_all``); True if it moved."""
        environment = self.environment_at(generation)
        if algorithm.environment == environment:
            return False
        algorithm.reevaluate_all(environment)
        return True

    def __iter__(self) -> Iterator[tuple[str, int]]:
        return iter(self.entries)

    def __len__(self) -> int:
        return len(self.entries)

    def __getitem__(self, index: int) -> tuple[str, int]:
        return self.entries[index]

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Schedule):
            return self.entries == other.entries and self.spans == other.spans
        if isinstance(other, list | tuple):
            return not any(self.spans) and list(self.entries) == [tuple(entry) for entry in other]
        return NotImplemented

    def __hash__(self) -> int:
        return hash((self.entries, self.spans))

    def __repr__(self) -> str:
        if any(self.spans):
            return f"Schedule({list(self.entries)!r}, spans={list(self.spans)!r})"
        return f"Schedule({list(self.entries)!r})"

    def __str__(self) -> str:
        return self.format()
