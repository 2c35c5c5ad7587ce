"""Dependencies of the routes: settings, services, a database connection, the bearer token."""

from __future__ import annotations

import secrets
from collections.abc import Iterator
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import Connection

from softevo.service.api.schemas import ErrorOut, ValidationErrorOut

if TYPE_CHECKING:
    from softevo.service.api.app import Services

bearer = HTTPBearer(auto_error=False, description="SOFTEVO_TOKEN of the server")

NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorOut, "description": "No such id"}}
UNAUTHORIZED: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorOut, "description": "Missing or wrong bearer token"},
    403: {
        "model": ErrorOut,
        "description": "No token set on the server, and the write has neither a JSON body nor "
        "an X-Requested-With header (what a cross-site form or simple request cannot send)",
    },
}
SAME_SITE_HEADER = "X-Requested-With"  # any value; browsers send it cross-site only after CORS
BUSY: dict[int | str, dict[str, Any]] = {
    429: {
        "model": ErrorOut,
        "description": "Too many simulations and reports computing or waiting "
        "(SOFTEVO_BACKGROUND_QUEUE); retry after the seconds in Retry-After",
        "headers": {"Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}},
    },
    401: {"model": ErrorOut, "description": "SOFTEVO_READ_TOKEN is set and the bearer token is missing"},
}
COMMON: dict[int | str, dict[str, Any]] = {
    422: {"model": ValidationErrorOut, "description": "The request does not match the schema"},
    503: {"model": ErrorOut, "description": "The database is unreachable"},
}


def get_services(request: Request) -> Services:
    return request.app.state.services


def get_connection(request: Request) -> Iterator[Connection]:
    """A connection for one request (reads; writes open their own transaction)."""
    with request.app.state.services.engine.connect() as conn:
        yield conn


def require_token(
    request: Request,
    credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)],
) -> None:
    """401 unless the request carries ``Authorization: Bearer <SOFTEVO_TOKEN>``.

    A server without a token (allowed on loopback only) lets a write in when it has a JSON
    body or an ``X-Requested-With`` header, which a page of another site cannot send without
    a CORS preflight this server never grants (``same_site_only``).
    """
    expected = request.app.state.settings.token_value
    if expected is None:
        same_site_only(request)
        return
    given = credentials.credentials if credentials else ""
    if not secrets.compare_digest(given.encode(), expected.encode()):
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "missing or wrong bearer token: send 'Authorization: Bearer <SOFTEVO_TOKEN>'",
            headers={"WWW-Authenticate": "Bearer"},
        )


def client_of(request: Request) -> str:
    """The client's address (per-client limits of the expensive reads)."""
    return request.client.host if request.client else ""


def same_site_only(request: Request) -> None:
    """403 unless the request has a JSON ``Content-Type`` or ``X-Requested-With``: a
    cross-site "simple" request (a form, a body-less ``fetch``) carries neither."""
    media_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    is_json = media_type == "application/json" or media_type.endswith("+json")
    if not is_json and SAME_SITE_HEADER.lower() not in request.headers:
        raise HTTPException(
            status.HTTP_403_FORBIDDEN,
            f"a write needs a JSON body (Content-Type: application/json) or a {SAME_SITE_HEADER} "
            "header, which cross-site pages cannot send (docs/security.md)",
        )


def require_read_token(request: Request) -> None:
    """401 unless the request carries ``SOFTEVO_READ_TOKEN`` (or the write token) when the
    server sets one: the reads that simulate or write a report. Open when it is unset (so
    the OpenAPI schema names no security scheme for them; the 401 is documented)."""
    settings = request.app.state.settings
    expected = settings.read_token_value
    if expected is None:
        return
    scheme, _, value = request.headers.get("authorization", "").partition(" ")
    given = (value.strip() if scheme.lower() == "bearer" else "").encode()
    accepted = [expected] + ([settings.token_value] if settings.token_value else [])
    if not any(secrets.compare_digest(given, token.encode()) for token in accepted):
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "missing or wrong bearer token: this read needs 'Authorization: Bearer <SOFTEVO_READ_TOKEN>'",
            headers={"WWW-Authenticate": "Bearer"},
        )


ServicesDep = Annotated["Services", Depends(get_services)]
ConnectionDep = Annotated[Connection, Depends(get_connection)]
WriteAccess = Depends(require_token)
ExpensiveReadAccess = Depends(require_read_token)
