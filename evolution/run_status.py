"""A run's life cycle, the one vocabulary of run states: storage writes these values, the
REST API and the command line show them."""

from __future__ import annotations

import enum


class RunStatus(enum.StrEnum):
    """Where a run stands; stored and shown as the plain strings."""

    PENDING = "pending"  # created, not yet driven
    RUNNING = "running"  # a coordinator drives it
    FINISHED = "finished"  # every generation done
    FAILED = "failed"  # stopped by an error (kept with the run); resumable
    CANCELLED = "cancelled"  # stopped on request; resumable
