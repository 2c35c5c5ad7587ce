"""Run locks kept by the database itself, for coordinators without Redis
(``service.runs.locks.RunLocks``): two ``softevo serve`` started on one database never
drive the same run; the second says who holds it and waits.

- PostgreSQL: a session advisory lock per run (``pg_try_advisory_lock(LOCK_CLASS, run)``)
  on a connection of its own; a coordinator that dies or loses its connection releases
  them with its session. After a server restart ``renew`` reconnects and takes its locks
  back, unless another coordinator took them meanwhile (those runs are lost).
- SQLite: one exclusive ``flock`` on ``<database file>.coordinator-lock`` (holding the
  holder's pid) for the whole database (SQLite has one writer anyway); the kernel releases
  it when the process dies.
- Anything else (an in-memory database): locks within this process only.
"""

from __future__ import annotations

import fcntl
import os
import threading
from collections.abc import Iterable
from pathlib import Path

from sqlalchemy import Connection, Engine, text

LOCK_CLASS = 0x50F7  # advisory lock class of softevo's run locks (first key of the pair)


class DatabaseLocks:
    """See the module doc."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self.held: set[int] = set()
        self._mutex = threading.Lock()
        self._connection: Connection | None = None
        self._file = None
        self.kind = "process"
        database = engine.url.database
        if engine.dialect.name == "postgresql":
            self.kind = "postgresql"
        elif engine.dialect.name == "sqlite" and database and database != ":memory:":
            self.kind = "sqlite"
            self.path = (
                Path(database).expanduser().resolve().with_name(Path(database).name + ".coordinator-lock")
            )

    # -- RunLocks ----------------------------------------------------------------------------

    def acquire(self, run_id: int) -> bool:
        with self._mutex:
            if run_id in self.held:
                return False
            if not self._take(run_id):
                return False
            self.held.add(run_id)
            return True

    def renew(self) -> set[int]:
        """PostgreSQL: reconnect after a lost connection and take the locks back; return the
        runs another coordinator took meanwhile."""
        if self.kind != "postgresql":
            return set()
        with self._mutex:
            try:
                self._session().execute(text("SELECT 1"))
                return set()
            except Exception:
                self._drop_connection()
            lost = {run_id for run_id in self.held if not self._take(run_id)}
            self.held -= lost
            return lost

    def peers(self) -> int:
        """1: coordinators sharing a database without Redis do not know of each other, so
        each takes what nobody holds (the first to start drives every run)."""
        return 1

    def leave(self) -> None:
        pass

    def release(self, run_ids: Iterable[int]) -> None:
        with self._mutex:
            for run_id in list(run_ids):
                if run_id not in self.held:
                    continue
                self.held.discard(run_id)
                if self.kind == "postgresql":
                    try:
                        self._session().execute(
                            text("SELECT pg_advisory_unlock(:c, :r)"), {"c": LOCK_CLASS, "r": run_id}
                        )
                    except Exception:
                        self._drop_connection()  # the session's locks went with it
            if self.kind == "sqlite" and not self.held and self._file is not None:
                self._file.close()  # closing the file drops the flock
                self._file = None

    def holder(self, run_id: int) -> str:
        """Who holds ``run_id``'s lock, in words (for the log line of a waiting coordinator)."""
        if self.kind == "postgresql":
            query = text(
                "SELECT pid FROM pg_locks WHERE locktype = 'advisory' AND classid = :c "
                "AND objid = :r AND granted AND database = "
                "(SELECT oid FROM pg_database WHERE datname = current_database())"
            )
            with self.engine.connect() as conn:
                pids = list(conn.execute(query, {"c": LOCK_CLASS, "r": run_id}).scalars())
            who = f"backend pid {pids[0]}" if pids else "a session that just ended"
            return f"its PostgreSQL advisory lock ({LOCK_CLASS}, {run_id}) is held by {who}"
        if self.kind == "sqlite":
            try:
                pid = self.path.read_text().strip() or "?"
            except OSError:
                pid = "?"
            return f"the lock file {self.path} is held by process {pid}"
        return "this process drives it already"

    # -- internals ---------------------------------------------------------------------------

    def _session(self) -> Connection:
        if self._connection is None:
            self._connection = self.engine.connect().execution_options(isolation_level="AUTOCOMMIT")
        return self._connection

    def _drop_connection(self) -> None:
        if self._connection is not None:
            try:
                self._connection.invalidate()
                self._connection.close()
            except Exception:
                pass
            self._connection = None

    def _take(self, run_id: int) -> bool:
        if self.kind == "postgresql":
            query = text("SELECT pg_try_advisory_lock(:c, :r)")
            try:
                return bool(self._session().execute(query, {"c": LOCK_CLASS, "r": run_id}).scalar())
            except Exception:
                self._drop_connection()
                raise
        if self.kind == "sqlite":
            return self._lock_file()
        return True

    def _lock_file(self) -> bool:
        if self._file is not None:
            return True
        handle = open(self.path, "a+")  # noqa: SIM115 - held open while the lock is held
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            return False
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        self._file = handle
        return True
