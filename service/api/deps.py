"""Dependencies of the routes: settings, services, a database connection, the bearer token."""

from __future__ import annotations

import secrets
from collections.abc import Iterator
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import Connection

from softevo.service.api.schemas import ErrorOut, ValidationErrorOut
from softevo.service.settings import Settings

if TYPE_CHECKING:
    from softevo.service.api.app import Services

bearer = HTTPBearer(auto_error=False, description="SOFTEVO_TOKEN of the server")

NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorOut, "description": "No such id"}}
UNAUTHORIZED: dict[int | str, dict[str, Any]] = {
    401: {"model": ErrorOut, "description": "Missing or wrong bearer token"}
}
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


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


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

    A server without a token (allowed on loopback only) lets every request write.
    """
    expected = request.app.state.settings.token_value
    if expected is None:
        return
    given = credentials.credentials if credentials else ""
    if not secrets.compare_digest(given.encode(), expected.encode()):
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            "missing or wrong bearer token: send 'Authorization: Bearer <SOFTEVO_TOKEN>'",
            headers={"WWW-Authenticate": "Bearer"},
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


SettingsDep = Annotated[Settings, Depends(get_settings)]
ServicesDep = Annotated["Services", Depends(get_services)]
ConnectionDep = Annotated[Connection, Depends(get_connection)]
WriteAccess = Depends(require_token)
ExpensiveReadAccess = Depends(require_read_token)
