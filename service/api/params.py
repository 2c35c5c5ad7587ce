"""The path and query parameters the routes share, each typed and bounded once: ids are
positive 32-bit integers, offsets and generations non-negative ones."""

from __future__ import annotations

from typing import Annotated

from fastapi import Path, Query

from softevo.service.api.schemas import MAX_INT32

ExperimentId = Annotated[int, Path(ge=1, le=MAX_INT32, description="experiment id")]
RunId = Annotated[int, Path(ge=1, le=MAX_INT32, description="run id")]
IndividualId = Annotated[int, Path(ge=1, le=MAX_INT32, description="individual id")]
Offset = Annotated[int, Query(ge=0, le=MAX_INT32, description="rows skipped")]


def generation_query(description: str):
    """An optional generation (``?generation=G``), described for its route."""
    return Annotated[int | None, Query(ge=0, le=MAX_INT32, description=description)]
