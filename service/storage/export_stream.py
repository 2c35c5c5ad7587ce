"""The export's tables as a stream of bytes (the REST downloads), a chunk of rows at a time.

``stream_table(engine, table, run_ids, fmt)`` yields one table of ``service.storage.export``
(``runs``, ``individuals`` or ``populations``) as CSV (header first) or as a Parquet file
(one row group per chunk): the same rows and columns as ``softevo export`` writes, and never
more than one chunk (``export.CHUNK_ROWS`` rows) in memory, whatever the table's size.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

from sqlalchemy import Engine

from softevo.errors import UserError
from softevo.service.storage.export import FORMATS, require_pyarrow, table_chunks

MEDIA_TYPES = {"csv": "text/csv; charset=utf-8", "parquet": "application/vnd.apache.parquet"}


def stream_table(engine: Engine, table: str, run_ids: Sequence[int], fmt: str) -> Iterator[bytes]:
    """Bytes of export table ``table`` of ``run_ids`` in format ``fmt`` (csv or parquet)."""
    if fmt not in FORMATS:
        raise UserError(f"unknown format {fmt!r}; choose csv or parquet")
    if fmt == "parquet":
        require_pyarrow()
    with engine.connect() as conn:
        chunks = table_chunks(conn, table, run_ids)
        yield from _csv(chunks) if fmt == "csv" else _parquet(chunks)


def _csv(chunks) -> Iterator[bytes]:
    for index, frame in enumerate(chunks):
        yield frame.to_csv(index=False, header=index == 0).encode()


class _Pending:
    """A write-only file that keeps what was written until ``take``n (Parquet's sink)."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.position = 0
        self.closed = False

    def write(self, data) -> int:
        self.parts.append(bytes(data))
        self.position += len(data)
        return len(data)

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True

    def take(self) -> bytes:
        data, self.parts = b"".join(self.parts), []
        return data


def _parquet(chunks) -> Iterator[bytes]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    sink, writer = _Pending(), None
    for frame in chunks:
        batch = pa.Table.from_pandas(frame, preserve_index=False)
        if writer is None:
            writer = pq.ParquetWriter(pa.PythonFile(sink, mode="w"), batch.schema)
        writer.write_table(batch.cast(writer.schema))
        yield sink.take()
    writer.close()
    yield sink.take()
