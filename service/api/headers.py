"""Response headers for browsers (docs/security.md): every response says
``X-Content-Type-Options: nosniff``; every HTML page gets a Content-Security-Policy with
``frame-ancestors 'none'`` (and ``X-Frame-Options: DENY``), so no other site can frame it and
no script from elsewhere runs on the origin where users paste their token.

A page that sets its own policy keeps it (the dashboard's pages and ``/docs`` name the hashes
of their inline scripts: ``policy``); any other HTML (the experiment reports: inline CSS and
``data:`` images, no script) gets ``STRICT``.
"""

from __future__ import annotations

import base64
import hashlib
import re

from starlette.datastructures import MutableHeaders
from starlette.types import ASGIApp, Message, Receive, Scope, Send

STRICT = (
    "default-src 'none'; style-src 'unsafe-inline'; img-src data:; "
    "base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
)
INLINE_SCRIPT = re.compile(r"<script(?![^>]*\bsrc=)[^>]*>(.*?)</script>", re.DOTALL | re.IGNORECASE)


def script_hashes(page: str) -> list[str]:
    """CSP sources (``'sha256-...'``) of the inline scripts (import maps too) of ``page``."""
    return [
        "'sha256-" + base64.b64encode(hashlib.sha256(body.encode()).digest()).decode() + "'"
        for body in INLINE_SCRIPT.findall(page)
    ]


def policy(page: str, scripts: str = "'self'", styles: str = "'self' 'unsafe-inline'") -> str:
    """The CSP of one of our own pages: its scripts from this origin (``scripts``) and its
    inline scripts by hash; data from this origin only; never framed."""
    script_src = " ".join([scripts, *script_hashes(page)])
    return (
        f"default-src 'self'; script-src {script_src}; style-src {styles}; "
        "img-src 'self' data: blob:; connect-src 'self'; worker-src 'self' blob:; "
        "object-src 'none'; base-uri 'self'; form-action 'self'; frame-ancestors 'none'"
    )


class SecurityHeaders:
    """ASGI middleware adding the headers of the module doc to every HTTP response."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = MutableHeaders(scope=message)
                headers.setdefault("X-Content-Type-Options", "nosniff")
                if headers.get("content-type", "").startswith("text/html"):
                    headers.setdefault("Content-Security-Policy", STRICT)
                    headers.setdefault("X-Frame-Options", "DENY")
                    headers.setdefault("Referrer-Policy", "no-referrer")
            await send(message)

        await self.app(scope, receive, send_with_headers)
