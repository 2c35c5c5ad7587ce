"""Downloads: ``GET /runs/{id}/export`` and ``GET /experiments/{id}/export``.

One table per request (``table``: runs, individuals or populations; the files of
``softevo export``, ``service.storage.export``) in one format (``format``: csv or parquet), so
a CSV and a Parquet download hold the same thing and neither needs an archive. The body is
streamed a chunk of rows at a time (``service.storage.export_stream``): memory stays bounded
whatever the table's size. At most ``MAX_DOWNLOADS`` downloads stream at once per server
(each holds a database connection while it streams); one more is 429 with ``Retry-After``.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Annotated, Literal

from fastapi import APIRouter, Depends, HTTPException, Query, Request
from fastapi.responses import StreamingResponse

from softevo.errors import UserError
from softevo.service.api.deps import BUSY, COMMON, NOT_FOUND, ServicesDep
from softevo.service.api.expensive import Busy
from softevo.service.api.params import ExperimentId, RunId
from softevo.service.storage import experiments as db_experiments
from softevo.service.storage import runs as db_runs
from softevo.service.storage.export_stream import MEDIA_TYPES, stream_table

router = APIRouter(tags=["export"], responses=COMMON)

MAX_DOWNLOADS = 4
RETRY_AFTER_S = 5
Format = Annotated[Literal["csv", "parquet"], Query(alias="format", description="csv or parquet")]
Table = Annotated[
    Literal["runs", "individuals", "populations"],
    Query(description="runs (one row per run), individuals (one per evaluation) or populations"),
]
RESPONSES = {
    200: {
        "content": {media: {} for media in MEDIA_TYPES.values()},
        "description": "The table as CSV (header first) or Parquet, streamed",
    },
    **NOT_FOUND,
    429: BUSY[429],
}


class Downloads:
    """How many downloads are streaming; ``enter`` raises ``Busy`` past ``limit``."""

    def __init__(self, limit: int) -> None:
        self.limit, self.active = limit, 0
        self._lock = threading.Lock()

    def enter(self) -> None:
        with self._lock:
            if self.active >= self.limit:
                raise Busy(RETRY_AFTER_S)
            self.active += 1

    def leave(self) -> None:
        with self._lock:
            self.active -= 1


_CREATING = threading.Lock()


def _downloads(request: Request) -> Downloads:
    """The app's ``Downloads`` (made on the first download)."""
    state = request.app.state
    with _CREATING:
        if not hasattr(state, "downloads"):
            state.downloads = Downloads(MAX_DOWNLOADS)
    return state.downloads


@dataclass
class Download:
    """One download's request: its table and format, and what serves it."""

    request: Request
    services: ServicesDep
    table: Table = "individuals"
    fmt: Format = "csv"

    def stream(self, run_ids: list[int], name: str) -> StreamingResponse:
        """The table of ``run_ids`` streamed as ``<name>-<table>.<format>``."""
        downloads = _downloads(self.request)
        downloads.enter()

        def body() -> Iterator[bytes]:
            try:
                yield from stream_table(self.services.engine, self.table, run_ids, self.fmt)
            finally:
                downloads.leave()

        filename = f"{name}-{self.table}.{self.fmt}"
        return StreamingResponse(
            body(),
            media_type=MEDIA_TYPES[self.fmt],
            headers={"Content-Disposition": f'attachment; filename="{filename}"'},
        )


DownloadDep = Annotated[Download, Depends()]


@router.get("/runs/{run_id}/export", response_class=StreamingResponse, responses=RESPONSES)
def export_run(run_id: RunId, download: DownloadDep):
    """One table of the run's export (``softevo export RUN``), streamed."""
    with download.services.engine.connect() as conn:
        if db_runs.run_status(conn, run_id) is None:
            raise HTTPException(404, f"no run {run_id}")
    return download.stream([run_id], f"run-{run_id}")


@router.get("/experiments/{experiment_id}/export", response_class=StreamingResponse, responses=RESPONSES)
def export_experiment(experiment_id: ExperimentId, download: DownloadDep):
    """One table of the export of every run of the experiment (``softevo export eID``),
    streamed."""
    with download.services.engine.connect() as conn:
        if not db_experiments.experiment_exists(conn, experiment_id):
            raise HTTPException(404, f"no experiment {experiment_id}")
        try:
            run_ids = db_runs.resolve_runs(conn, f"e{experiment_id}")
        except UserError:  # an experiment without runs: the tables' headers alone
            run_ids = []
    return download.stream(run_ids, f"experiment-{experiment_id}")
