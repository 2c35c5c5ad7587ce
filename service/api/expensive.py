"""The API's expensive reads (recorded frames, reports): bounded, shared and cached.

They run in one spawned background process (numba holds the GIL, and the API and the
coordinator loop must stay responsive). ``ExpensiveReads.compute(key, function, *args)``:

- computes each key at most once at a time: concurrent requests for one key share one
  computation;
- keeps the answers of cacheable keys in memory, least recently used dropped first, up to
  ``cache_bytes`` (``SOFTEVO_FRAMES_CACHE_MB``);
- admits at most ``limit`` keys computing or waiting at once (``SOFTEVO_BACKGROUND_QUEUE``),
  and at most ``per_client`` of them started by one client address
  (``SOFTEVO_BACKGROUND_PER_CLIENT``): one more raises ``Busy`` with the seconds to wait
  (``Retry-After``), estimated from the recent durations, instead of queueing without bound;
- bounds each computation by its ``timeout``: one that runs past it raises ``TimeoutError``
  to every request waiting for it, frees its slot at once and ends the background process
  (it would go on simulating); reads queued behind it run again on a fresh process.
"""

from __future__ import annotations

import asyncio
import math
import multiprocessing
import threading
import time
from collections import Counter, OrderedDict, deque
from collections.abc import Callable, Hashable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from softevo.evolution import environments as worlds
from softevo.worker.evaluate import ensure_compiled, init_pool_process

DEFAULT_RETRY_AFTER_S = 5
MAX_RETRY_AFTER_S = 600


class Busy(Exception):
    """Too many expensive reads computing or waiting; try again after ``retry_after`` s."""

    def __init__(self, retry_after: int) -> None:
        super().__init__(f"the server is busy with other simulations and reports; retry in {retry_after} s")
        self.retry_after = retry_after


class ExpensiveReads:
    """See the module doc."""

    def __init__(self, limit: int, cache_bytes: int, per_client: int | None = None) -> None:
        self.limit = limit
        self.per_client = per_client or limit
        self._clients: Counter[str] = Counter()  # keys computing or waiting, by who started them
        self.cache_bytes = cache_bytes
        self.cached_bytes = 0
        self.computed = 0  # computations started (for tests and the bench)
        self._cache: OrderedDict[Hashable, Any] = OrderedDict()
        self._running: dict[Hashable, asyncio.Future] = {}
        self._durations: deque[float] = deque(maxlen=16)
        self._pool: ProcessPoolExecutor | None = None
        self._mutex = threading.Lock()

    # -- the pool ----------------------------------------------------------------------------

    def _background(self) -> ProcessPoolExecutor:
        with self._mutex:
            if self._pool is None:
                ensure_compiled()  # the simulator loads only when a read first needs it
                self._pool = ProcessPoolExecutor(
                    max_workers=1,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=init_pool_process,
                    initargs=(worlds.added(),),
                )
            return self._pool

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)

    def _end(self, pool: ProcessPoolExecutor) -> None:
        """End ``pool``'s process now (a computation past its time-out); the next read starts
        a fresh one. ProcessPoolExecutor cannot cancel a running call, so its process goes."""
        with self._mutex:
            if self._pool is pool:
                self._pool = None
        for process in list((pool._processes or {}).values()):  # noqa: SLF001 - no public way before 3.14
            process.terminate()
        pool.shutdown(wait=False, cancel_futures=True)

    # -- admission, sharing, caching ---------------------------------------------------------

    def retry_after(self) -> int:
        """Seconds until a slot is likely free: the queue's length times the mean duration."""
        if not self._durations:
            return DEFAULT_RETRY_AFTER_S
        mean = sum(self._durations) / len(self._durations)
        return int(min(MAX_RETRY_AFTER_S, max(1, math.ceil(mean * len(self._running)))))

    def cached(self, key: Hashable) -> Any | None:
        value = self._cache.get(key)
        if value is not None:
            self._cache.move_to_end(key)
        return value

    async def compute(
        self,
        key: Hashable,
        function: Callable[..., Any],
        *args: Any,
        cache: bool = True,
        timeout: float | None = None,
        client: str = "",
    ) -> Any:
        """``function(*args)`` in the background process (see the module doc); ``Busy`` when
        the queue, or ``client``'s share of it, is full; ``TimeoutError`` past ``timeout``
        seconds. ``function`` must be a module-level function (the pool pickles it by name)."""
        if cache:
            value = self.cached(key)
            if value is not None:
                return value
        running = self._running.get(key)
        if running is None:
            if len(self._running) >= self.limit or self._clients[client] >= self.per_client:
                raise Busy(self.retry_after())
            running = asyncio.ensure_future(self._run(key, function, args, cache, timeout))
            self._running[key] = running
            self._clients[client] += 1
            running.add_done_callback(lambda _: self._release(key, client))
        return await asyncio.shield(running)

    def _release(self, key: Hashable, client: str) -> None:
        self._running.pop(key, None)
        self._clients[client] -= 1
        if self._clients[client] <= 0:
            del self._clients[client]

    async def _run(self, key: Hashable, function, args, cache: bool, timeout: float | None) -> Any:
        self.computed += 1
        start = time.monotonic()
        for attempt in range(2):
            pool = await asyncio.to_thread(self._background)  # may compile: off the event loop
            try:
                value = await asyncio.wait_for(asyncio.wrap_future(pool.submit(function, *args)), timeout)
                break
            except TimeoutError:
                self._end(pool)  # its slot is free once this raises; its CPU now
                raise
            except BrokenProcessPool:  # another read's time-out ended the process: run again
                if attempt:
                    raise
        self._durations.append(time.monotonic() - start)
        if cache:
            self._store(key, value)
        return value

    def _store(self, key: Hashable, value: Any) -> None:
        size = _size(value)
        if size > self.cache_bytes:
            return
        self._cache[key] = value
        self.cached_bytes += size
        while self.cached_bytes > self.cache_bytes:
            _, dropped = self._cache.popitem(last=False)
            self.cached_bytes -= _size(dropped)


def _size(value: Any) -> int:
    """Bytes a cached answer holds (its body; headers are negligible)."""
    body = value[0] if isinstance(value, tuple) else value
    return len(body) if isinstance(body, bytes | bytearray) else 1024
