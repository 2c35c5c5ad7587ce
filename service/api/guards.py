"""The API's ASGI guards: ``BodyLimits`` refuses request bodies the API should never parse;
``ConcurrencyLimit`` lets at most ``SOFTEVO_MAX_CONCURRENT_REQUESTS`` requests into the routes
at once (the others wait their turn in the event loop): below the thread pool's 40 threads
and the database pool's connections, so that requests holding a connection never wait for a
thread held by requests waiting for a connection.

- A body over ``max_bytes`` (``SOFTEVO_MAX_BODY_BYTES``, default 1 MB) is refused with 413,
  from its ``Content-Length`` before anything is read, or while it streams in (chunked):
  at most ``max_bytes`` are ever held.
- A JSON body nested deeper than ``max_depth`` (``SOFTEVO_MAX_JSON_DEPTH``), or holding
  ``NaN``, ``Infinity`` or a number too large for a float (``1e999``), is refused with 422:
  those are not JSON numbers (RFC 8259), and Python's parser would let them through.

Errors have the API's shape, ``{"detail": message, "errors": [...]}``.
"""

from __future__ import annotations

import asyncio
import json
import math
from typing import Any

from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send


class BodyRefused(ValueError):
    """Why a body is refused, with its status."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def _reject_constant(name: str) -> Any:
    raise BodyRefused(422, f"body: {name} is not a JSON number (finite numbers only)")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise BodyRefused(422, f"body: {text} is not a finite number")
    return value


def json_depth(value: Any) -> int:
    """Nesting depth of parsed JSON (a scalar 0, ``[]`` 1, ``[[1]]`` 2), without recursion."""
    depth, stack = 0, [(value, 1)]
    while stack:
        item, level = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is None:
            continue
        depth = max(depth, level)
        stack.extend((child, level + 1) for child in children)
    return depth


def check_json(body: bytes, max_depth: int) -> None:
    """BodyRefused (422) if ``body`` nests deeper than ``max_depth`` or holds a non-finite
    number. Malformed JSON passes: the route's own parsing reports it."""
    try:
        value = json.loads(body, parse_constant=_reject_constant, parse_float=_finite_float)
    except RecursionError:
        raise BodyRefused(422, f"body: JSON nested deeper than {max_depth} levels") from None
    except BodyRefused:
        raise
    except ValueError as exc:  # malformed, or an integer of thousands of digits
        if "digits" in str(exc):
            raise BodyRefused(422, f"body: {exc}") from None
        return
    if json_depth(value) > max_depth:
        raise BodyRefused(422, f"body: JSON nested deeper than {max_depth} levels")


class BodyLimits:
    """See the module doc."""

    def __init__(self, app: ASGIApp, max_bytes: int, max_depth: int) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.max_depth = max_depth

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        try:
            declared = headers.get(b"content-length")
            if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
                raise BodyRefused(413, self._too_large())
            body = await self._read(receive)
            content_type = headers.get(b"content-type", b"").split(b";")[0].strip().lower()
            if body and (content_type == b"application/json" or content_type.endswith(b"+json")):
                check_json(body, self.max_depth)
        except BodyRefused as refused:
            detail = str(refused)
            response = JSONResponse({"detail": detail, "errors": [{"loc": ["body"], "msg": detail}]},
                                    status_code=refused.status)  # fmt: skip
            await response(scope, receive, send)
            return
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if replayed:
                return await receive()
            replayed = True
            return {"type": "http.request", "body": body, "more_body": False}

        await self.app(scope, replay, send)

    def _too_large(self) -> str:
        return f"request body larger than {self.max_bytes} bytes (SOFTEVO_MAX_BODY_BYTES)"

    async def _read(self, receive: Receive) -> bytes:
        parts, size = [], 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                break
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                raise BodyRefused(413, self._too_large())
            parts.append(chunk)
            if not message.get("more_body", False):
                break
        return b"".join(parts)


UNLIMITED_SUFFIXES = ("/frames", "/report")  # they wait on the background process, holding no
# connection, and ``service.api.expensive`` bounds them itself (429)


class ConcurrencyLimit:
    """See the module doc."""

    def __init__(self, app: ASGIApp, limit: int) -> None:
        self.app = app
        self.limit = limit
        self._slots: asyncio.Semaphore | None = None  # made in the server's event loop

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["path"].endswith(UNLIMITED_SUFFIXES):
            await self.app(scope, receive, send)
            return
        if self._slots is None:
            self._slots = asyncio.Semaphore(self.limit)
        async with self._slots:
            await self.app(scope, receive, send)
