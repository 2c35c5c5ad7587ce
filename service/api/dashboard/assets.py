"""Static assets of the dashboard: files under ``static/`` and plotly.js from the ``plotly``
Python package (its bundled ``plotly.min.js``; never a CDN).

Only files that exist under ``static/`` when the router is built are served (a fixed table,
so no path from a request ever reaches the file system). Vendored libraries are cached by
the browser for a day; the dashboard's own files are revalidated on every load.
"""

from __future__ import annotations

import importlib.util
from functools import cache
from pathlib import Path

from fastapi import APIRouter, HTTPException
from fastapi.responses import FileResponse

STATIC_DIR = Path(__file__).parent / "static"
PLOTLY_NAME = "vendor/plotly.min.js"
MEDIA_TYPES = {
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
    ".txt": "text/plain; charset=utf-8",
    ".md": "text/markdown; charset=utf-8",
}
VENDOR_CACHE = "public, max-age=86400"
OWN_CACHE = "no-cache"

router = APIRouter()


@cache
def static_files() -> dict[str, Path]:
    """Relative POSIX name -> file, for every file under ``static/``."""
    return {
        path.relative_to(STATIC_DIR).as_posix(): path
        for path in sorted(STATIC_DIR.rglob("*"))
        if path.is_file() and path.suffix in MEDIA_TYPES
    }


@cache
def plotly_js() -> Path | None:
    """``plotly.min.js`` of the installed ``plotly`` package, or None without it."""
    spec = importlib.util.find_spec("plotly")
    if spec is None or spec.origin is None:
        return None
    path = Path(spec.origin).parent / "package_data" / "plotly.min.js"
    return path if path.is_file() else None


def _asset(name: str) -> Path:
    if name == PLOTLY_NAME:
        path = plotly_js()
        if path is None:
            raise HTTPException(404, "plotly is not installed: pip install plotly")
        return path
    path = static_files().get(name)
    if path is None:
        raise HTTPException(404, f"no dashboard asset {name!r}")
    return path


@router.get("/static/{name:path}")
def asset(name: str) -> FileResponse:
    """One asset by its name under ``static/`` (e.g. ``js/run.js``)."""
    path = _asset(name)
    cache_control = VENDOR_CACHE if name.startswith("vendor/") else OWN_CACHE
    return FileResponse(path, media_type=MEDIA_TYPES[path.suffix], headers={"Cache-Control": cache_control})
