"""``/docs``: Swagger UI from the vendored files under the dashboard's ``static/vendor/``
(npm ``swagger-ui-dist``, see its README): no CDN on the origin where users paste their
token, and a CSP that allows this origin's scripts and the page's one inline script by hash.
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse

from softevo.service.api.headers import policy

router = APIRouter(include_in_schema=False)


@router.get("/docs")
def swagger_ui(request: Request) -> HTMLResponse:
    """The interactive API docs (Swagger UI) of ``/openapi.json``."""
    root = request.scope.get("root_path", "").rstrip("/")
    vendor = f"{root}/dashboard/static/vendor"
    page = get_swagger_ui_html(
        openapi_url=f"{root}{request.app.openapi_url}",
        title=f"{request.app.title} - API",
        swagger_js_url=f"{vendor}/swagger-ui-bundle.js",
        swagger_css_url=f"{vendor}/swagger-ui.css",
        swagger_favicon_url=f"{root}/dashboard/static/favicon.svg",
    )
    body = page.body.decode()
    return HTMLResponse(body, headers={"Content-Security-Policy": policy(body)})
