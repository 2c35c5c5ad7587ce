"""A small discrete-event simulation of how runs' generations are dispatched to workers.

Each run is a list of generations; a generation is a set of jobs (seconds each, on one
worker) and the coordinator's seconds for it (tell, store, ask: a coordinator does one
generation at a time; with ``coordinators`` K, run ``r``'s generations go to coordinator
``r mod K``). A run's first generation can also carry the seconds its coordinator spends
asking for it before any of its jobs is dispatched (a new population is drawn, not bred):
at the start each coordinator asks its runs one after the other. ``W`` workers take jobs
first in, first out. Two policies:

- ``"rounds"`` (``service.runs.coordinator.Coordinator.round``): every active run's generation is
  dispatched together; the next round starts when the whole round is done and the
  coordinator has told and stored every run of it.
- ``"per-run"``: a run's next generation is dispatched as soon as its own generation is done
  and the coordinator has told and stored it, whatever the other runs do.

``simulate(runs, workers, policy, coordinators)`` returns (makespan seconds, busy
worker-seconds).
"""

from __future__ import annotations

import heapq
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

POLICIES = ("rounds", "per-run")
_RELEASE, _FINISH = 0, 1


@dataclass(frozen=True)
class Generation:
    """One generation of one run: ``jobs`` (seconds of each job on one worker), the
    coordinator's ``coordinator_seconds`` once its jobs are done and, for a run's first
    generation, ``ask_seconds`` of the coordinator before its jobs are dispatched."""

    jobs: np.ndarray
    coordinator_seconds: float = 0.0
    ask_seconds: float = 0.0


def simulate(
    runs: Sequence[Sequence[Generation]], workers: int, policy: str = "rounds", coordinators: int = 1
) -> tuple[float, float]:
    """(makespan, busy worker-seconds) of ``runs`` on ``workers`` workers under ``policy``,
    told by ``coordinators`` coordinators (rounds: their tell seconds shared out evenly)."""
    if policy not in POLICIES:
        raise ValueError(f"unknown dispatch policy {policy!r}; choose {' or '.join(POLICIES)}")
    return _Dispatch(runs, workers, policy == "rounds", coordinators).run()


class _Dispatch:
    def __init__(
        self, runs: Sequence[Sequence[Generation]], workers: int, rounds: bool, coordinators: int = 1
    ) -> None:
        self.runs, self.idle, self.rounds = runs, int(workers), rounds
        self.events: list[tuple[float, int, int, int]] = []
        self.ready: deque[tuple[int, float]] = deque()
        self.position = [0] * len(runs)  # the generation each run is at
        self.remaining = [0] * len(runs)  # its jobs not finished
        self.waiting: set[int] = set()  # runs of the round not done (rounds)
        self.now = self.end = self.busy = 0.0
        self.coordinator_free = [0.0] * max(1, int(coordinators))  # when each is free next
        self.sequence = 0

    def run(self) -> tuple[float, float]:
        live = [r for r, generations in enumerate(self.runs) if generations]
        self.waiting = set(live)
        released = {}
        for r in live:
            coordinator = r % len(self.coordinator_free)
            self.coordinator_free[coordinator] += self.runs[r][0].ask_seconds
            released[r] = self.coordinator_free[coordinator]
        for r in live:  # a round is dispatched once every run of it is asked
            self._push(max(released.values()) if self.rounds else released[r], _RELEASE, r)
        while True:
            while self.idle and self.ready:
                r, seconds = self.ready.popleft()
                self.idle -= 1
                self.busy += seconds
                self._push(self.now + seconds, _FINISH, r)
            if not self.events:
                return max(self.end, self.now), self.busy
            self.now, _, kind, r = heapq.heappop(self.events)
            if kind == _RELEASE:
                self._release(r)
            else:
                self.idle += 1
                self.remaining[r] -= 1
                if self.remaining[r] == 0:
                    self._done(r)

    def _push(self, time: float, kind: int, r: int) -> None:
        self.sequence += 1
        heapq.heappush(self.events, (time, self.sequence, kind, r))

    def _release(self, r: int) -> None:
        jobs = self.runs[r][self.position[r]].jobs
        self.remaining[r] = len(jobs)
        self.ready.extend((r, float(seconds)) for seconds in jobs)
        if not len(jobs):  # nothing to simulate: done at once
            self._done(r)

    def _done(self, r: int) -> None:
        if not self.rounds:
            seconds = self.runs[r][self.position[r]].coordinator_seconds
            self._told([r], seconds, r % len(self.coordinator_free))
            return
        self.waiting.discard(r)
        if self.waiting:
            return
        told = [s for s, generations in enumerate(self.runs) if self.position[s] < len(generations)]
        seconds = sum(self.runs[s][self.position[s]].coordinator_seconds for s in told)
        self._told(told, seconds / len(self.coordinator_free), 0)

    def _told(self, told: list[int], seconds: float, coordinator: int) -> None:
        """``coordinator`` tells and stores ``told``'s generations, then releases the next."""
        free = max(self.now, self.coordinator_free[coordinator]) + seconds
        self.coordinator_free[coordinator] = free
        self.end = max(self.end, free)
        for r in told:
            self.position[r] += 1
            if self.position[r] < len(self.runs[r]):
                self.waiting.add(r)
                self._push(free, _RELEASE, r)
