"""``ReadCache``: the ASGI middleware that answers repeated JSON and dashboard reads from
memory for ``SOFTEVO_READ_CACHE_SECONDS`` (default 1 s; 0 turns it off).

Clients polling a live run (status, runs, generations, front, lineage, the dashboard's pages)
ask the same few URLs many times a second, while the answers change once per generation.
A ``GET`` answered 200 is kept, keyed by path and query string, for that long (a reused
answer carries ``X-Read-Cache: hit``); concurrent
requests for a key that is being computed wait for that one answer instead of each querying
the database. Any other method that succeeds (a write through this server, status below 400)
empties the cache, so a client reads its own writes; a refused one (401, 403, 422, ...)
leaves it alone, so unauthenticated POSTs cannot make every poll hit the database. A
generation stored by the coordinator shows within the TTL.

Not cached: ``/health``, the expensive reads (``.../frames``, ``.../report``,
``.../analysis``: their own cache and token, ``service.api.expensive``), the downloads
(``.../export``: streamed), answers over ``MAX_BODY`` bytes or streamed.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

MAX_BODY = 2_000_000  # bytes of one cached answer, at most
MAX_ENTRIES = 2000
EXCLUDED_SUFFIXES = ("/frames", "/report", "/analysis", "/export")
EXCLUDED_PATHS = ("/health",)


class ReadCache:
    """See the module doc."""

    def __init__(self, app: ASGIApp, seconds: float) -> None:
        self.app = app
        self.seconds = seconds
        self._entries: dict[tuple[str, bytes], tuple[float, list[Message]]] = {}
        self._computing: dict[tuple[str, bytes], asyncio.Future] = {}
        self.hits = 0

    def _cacheable(self, scope: Scope) -> bool:
        path = scope["path"]
        return (
            self.seconds > 0
            and scope["method"] == "GET"
            and path not in EXCLUDED_PATHS
            and not path.endswith(EXCLUDED_SUFFIXES)
        )

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if not self._cacheable(scope):
            if scope["method"] in ("GET", "HEAD", "OPTIONS"):
                await self.app(scope, receive, send)
                return
            status = 500

            async def watch(message: Message) -> None:
                nonlocal status
                if message["type"] == "http.response.start":
                    status = message["status"]
                await send(message)

            await self.app(scope, receive, watch)
            if status < 400:  # a write that went through: nobody reads an answer from before it
                self._entries.clear()
            return
        key = (scope["path"], scope.get("query_string", b""))
        while True:
            entry = self._entries.get(key)
            if entry is not None and time.monotonic() - entry[0] < self.seconds:
                self.hits += 1
                start, body = entry[1]
                await send({**start, "headers": [*start.get("headers", []), (b"x-read-cache", b"hit")]})
                await send(body)
                return
            computing = self._computing.get(key)
            if computing is None:
                break
            await asyncio.shield(computing)  # then read the answer it stored (or compute)
            if key not in self._entries:
                break
        future = asyncio.get_running_loop().create_future()
        self._computing[key] = future
        try:
            await self._compute(key, scope, receive, send)
        finally:
            del self._computing[key]
            future.set_result(None)

    async def _compute(self, key, scope: Scope, receive: Receive, send: Send) -> None:
        messages: list[Message] = []
        size, keep = 0, True

        async def capture(message: Message) -> None:
            nonlocal size, keep
            if message["type"] == "http.response.start" and message["status"] != 200:
                keep = False
            if message["type"] == "http.response.body":
                size += len(message.get("body", b""))
                keep = keep and size <= MAX_BODY
            if keep:
                messages.append(message)
            await send(message)

        started = time.monotonic()
        await self.app(scope, receive, capture)
        if keep and messages and not messages[-1].get("more_body", False):
            if len(self._entries) >= MAX_ENTRIES:
                self._drop_expired()
            if len(self._entries) < MAX_ENTRIES:
                self._entries[key] = (started, _plain(messages))

    def _drop_expired(self) -> None:
        now = time.monotonic()
        for key in [k for k, (t, _) in self._entries.items() if now - t >= self.seconds]:
            del self._entries[key]


def _plain(messages: list[Message]) -> list[dict[str, Any]]:
    """The response as sent, body chunks joined into one message."""
    start = dict(messages[0])
    body = b"".join(m.get("body", b"") for m in messages[1:])
    return [start, {"type": "http.response.body", "body": body, "more_body": False}]
