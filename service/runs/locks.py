"""Run locks: who drives which run, so that one coordinator at a time drives a run.

- ``RunLocks``: the protocol ``service.runs.driver.CoordinatorLoop`` takes;
- ``RedisLocks``: with Redis, a key per run (``SET NX PX``, renewed every ``ttl / 3``
  seconds by the coordinator's thread, re-taken after a Redis restart if nobody else did); a
  coordinator that dies lets its locks expire within ``ttl``. ``RedisLocks.peers`` counts the
  coordinators alive now;
- without Redis the database holds the locks: ``service.storage.advisory_locks.DatabaseLocks``
  (PostgreSQL advisory locks, a lock file beside a SQLite file, else within the process);
- ``locks_for`` and ``holding``: the same locks for ``softevo run`` and ``resume``
  (``service.runs.coordinator.Coordinator.run``), which so never drive a run a server drives.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Protocol

from softevo.errors import UserError

if TYPE_CHECKING:
    from sqlalchemy import Engine

log = logging.getLogger("softevo.coordinator")

RENEW_SCRIPT = """
local owner = redis.call('GET', KEYS[1])
if owner == ARGV[1] then
  return redis.call('PEXPIRE', KEYS[1], ARGV[2])
elseif not owner then
  return redis.call('SET', KEYS[1], ARGV[1], 'NX', 'PX', ARGV[2]) and 1 or 0
end
return 0
"""
TAKEOVER_SCRIPT = """
if redis.call('GET', KEYS[1]) == ARGV[1] then
  return redis.call('SET', KEYS[1], ARGV[2], 'PX', ARGV[3]) and 1 or 0
end
return 0
"""
RELEASE_SCRIPT = """
if redis.call('GET', KEYS[1]) == ARGV[1] then return redis.call('DEL', KEYS[1]) end
return 0
"""


class RunLocks(Protocol):
    """Who drives which run."""

    def acquire(self, run_id: int) -> bool: ...

    def renew(self) -> set[int]:
        """Extend every lock held; return the runs whose lock was lost."""
        ...

    def release(self, run_ids: Iterable[int]) -> None: ...

    def peers(self) -> int:
        """Coordinators sharing the runs now, this one included (at least 1)."""
        ...

    def leave(self) -> None:
        """Stop counting among the peers (this coordinator is stopping)."""
        ...


class RedisLocks:
    """One Redis key per run, ``softevo:<database>:run:<id>:coordinator`` = owner token."""

    def __init__(self, redis_url: str, namespace: str, ttl: float = 30.0) -> None:
        from softevo.service.runs.rq_executor import connect  # rq and redis: only for Redis locks

        self.connection = connect(redis_url)
        self.namespace = namespace
        self.ttl_ms = int(ttl * 1000)
        # host:pid:random: a coordinator restarted on the same host takes over at once the
        # locks of the dead process it replaces (``_dead_here``) instead of waiting ``ttl``
        self.token = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:16]}"
        self.held: set[int] = set()
        self._renew = self.connection.register_script(RENEW_SCRIPT)
        self._takeover = self.connection.register_script(TAKEOVER_SCRIPT)
        self._release = self.connection.register_script(RELEASE_SCRIPT)
        self._mutex = threading.Lock()

    def key(self, run_id: int) -> str:
        return f"softevo:{self.namespace}:run:{run_id}:coordinator"

    def peers(self) -> int:
        """Coordinators of this database alive now, this one included: each one that asks
        counts itself in for ``ttl`` (a sorted set scored by expiry), so a coordinator that
        died drops out within ``ttl``."""
        key = f"softevo:{self.namespace}:coordinators"
        now_ms = int(time.time() * 1000)
        with self.connection.pipeline(transaction=True) as pipe:
            pipe.zadd(key, {self.token: now_ms + self.ttl_ms})
            pipe.zremrangebyscore(key, "-inf", now_ms)
            pipe.zrange(key, 0, -1)
            pipe.pexpire(key, self.ttl_ms)
            tokens = [token.decode() for token in pipe.execute()[2]]
        dead = [token for token in tokens if _dead_here(token)]
        if dead:
            self.connection.zrem(key, *dead)
        return max(1, len(tokens) - len(dead))

    def leave(self) -> None:
        self.connection.zrem(f"softevo:{self.namespace}:coordinators", self.token)

    def acquire(self, run_id: int) -> bool:
        """Take the run's key if nobody holds it, or if this coordinator still does (a
        release that Redis missed while it was away)."""
        with self._mutex:
            if run_id in self.held:
                return False
            key = self.key(run_id)
            if self._renew(keys=[key], args=[self.token, self.ttl_ms]) or self._take_from_dead(key):
                self.held.add(run_id)
                return True
            return False

    def _take_from_dead(self, key: str) -> bool:
        """Take the key from a coordinator of this host whose process has ended."""
        owner = self.connection.get(key)
        if owner is None or not _dead_here(owner.decode()):
            return False
        return bool(self._takeover(keys=[key], args=[owner, self.token, self.ttl_ms]))

    def renew(self) -> set[int]:
        with self._mutex:
            lost = {
                run_id
                for run_id in self.held
                if not self._renew(keys=[self.key(run_id)], args=[self.token, self.ttl_ms])
            }
            self.held -= lost
            return lost

    def holds(self, run_id: int) -> bool:
        """Whether this coordinator holds the run's lock now, renewed (or taken again if
        nobody holds it: Redis emptied); asked before each generation's commit, as the renew
        thread may not know yet that another coordinator took the run. Redis away: as far
        as this coordinator knows (the commit itself needs no Redis)."""
        try:
            with self._mutex:
                key = self.key(run_id)
                if run_id in self.held and self._renew(keys=[key], args=[self.token, self.ttl_ms]):
                    return True
                self.held.discard(run_id)
                return False
        except Exception:  # noqa: BLE001
            return run_id in self.held

    def release(self, run_ids: Iterable[int]) -> None:
        """Stop holding the runs (and renewing them) first, then delete their keys: with
        Redis away the keys expire within ``ttl`` (or ``acquire`` takes them back)."""
        with self._mutex:
            released = self.held & set(run_ids)
            self.held -= released
            for run_id in sorted(released):
                self._release(keys=[self.key(run_id)], args=[self.token])

    def owner(self, run_id: int) -> str | None:
        """The token of the coordinator holding the run (None: nobody)."""
        value = self.connection.get(self.key(run_id))
        return value.decode() if value else None

    def holder(self, run_id: int) -> str:
        """Who holds ``run_id``'s lock, in words."""
        owner = self.owner(run_id)
        return f"Redis key {self.key(run_id)} is held by coordinator {owner or '(expired just now)'}"


def redis_error(exc: BaseException) -> bool:
    """Whether ``exc`` is Redis's (without importing redis where it is not installed)."""
    return any(cls.__module__.startswith("redis") for cls in type(exc).__mro__)


def _dead_here(token: str) -> bool:
    """Whether ``token`` (``host:pid:random``) is a coordinator of this host whose process
    has ended."""
    host, _, rest = token.partition(":")
    pid = rest.partition(":")[0]
    if host != socket.gethostname() or not pid.isdigit() or int(pid) == os.getpid():
        return False
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # alive, another user's
        return False
    return False


def locks_for(engine: Engine) -> RunLocks:
    """The run locks ``softevo serve`` takes on ``engine``'s database: Redis's when
    ``SOFTEVO_REDIS_URL`` is set (the key of ``Settings.database_namespace``), else the
    database's own (``service.storage.advisory_locks.DatabaseLocks``)."""
    from softevo.service.settings import Settings
    from softevo.service.storage.advisory_locks import DatabaseLocks

    settings = Settings(db=engine.url.render_as_string(hide_password=False))  # the one reader of SOFTEVO_*
    if settings.redis_url:
        return RedisLocks(settings.redis_url, settings.database_namespace())
    return DatabaseLocks(engine)


@contextmanager
def holding(locks: RunLocks, run_ids: Iterable[int], renew_seconds: float = 10.0) -> Iterator[list[int]]:
    """Take each run's lock; yield the runs held (a run held by another coordinator is left
    to it, said in one line); renew the locks in a thread meanwhile; release them at the
    end (they expire by themselves if Redis or the database is away then)."""
    held = []
    for run_id in run_ids:
        try:
            taken = locks.acquire(run_id)
        except Exception as exc:
            if not redis_error(exc):
                raise
            raise UserError(
                f"Redis cannot be reached to take run {run_id}'s lock ({exc}): start it, or unset "
                "SOFTEVO_REDIS_URL if no softevo serve drives this database"
            ) from exc
        if taken:
            held.append(run_id)
            continue
        describe = getattr(locks, "holder", None)
        who = describe(run_id) if describe else "its lock is taken"
        log.warning(
            "run %d is driven by a softevo serve (%s): it goes on there by itself; "
            "follow it with softevo status r%d", run_id, who, run_id,
        )  # fmt: skip
    stop = threading.Event()

    def renew() -> None:
        while not stop.wait(renew_seconds):
            try:
                locks.renew()
            except Exception as exc:  # noqa: BLE001 - Redis away: re-taken once it is back
                log.warning("cannot renew run locks: %s", exc)

    thread = threading.Thread(target=renew, name="run-locks", daemon=True)
    thread.start()
    try:
        yield held
    finally:
        stop.set()
        try:
            locks.release(held)
        except Exception as exc:  # noqa: BLE001
            log.warning("cannot release the locks of run(s) %s now (%s); they expire", held, exc)
