"""The dashboard over real HTTP (``softevo dashboard`` on a tiny run), without a browser:
pages, assets, the body endpoint, and that nothing points outside the server."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import httpx
import numpy as np
import pytest

from softevo.service.api.dashboard.assets import STATIC_DIR, plotly_js
from softevo.service.api.frames import decode_frames

TEMPLATES = Path(STATIC_DIR).parent / "templates"
OWN_FILES = [*TEMPLATES.glob("*.html"), *STATIC_DIR.glob("*.css"), *STATIC_DIR.glob("js/*.js")]
LOCAL_REFERENCE = re.compile(r'(?:src|href)="([^"]+)"')


def get(base: str, path: str, **kwargs) -> httpx.Response:
    return httpx.get(f"{base}{path}", timeout=300, **kwargs)


@pytest.mark.parametrize("path", ["/dashboard/", "/dashboard/runs/1", "/dashboard/individuals/1"])
def test_page_and_every_asset_it_references_are_served(dashboard_url, path):
    page = get(dashboard_url, path)
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    references = LOCAL_REFERENCE.findall(page.text)
    assert references, "a page with no script or stylesheet"
    for reference in references:
        assert reference.startswith("/"), f"{reference} is not on this server"
        if reference.startswith("/dashboard/static/"):
            assert get(dashboard_url, reference).status_code == 200, reference


def test_run_page_loads_plotly_from_the_server_and_individual_page_three(dashboard_url):
    assert "/dashboard/static/vendor/plotly.min.js" in get(dashboard_url, "/dashboard/runs/1").text
    individual = get(dashboard_url, "/dashboard/individuals/1").text
    assert '"three": "/dashboard/static/vendor/three.module.min.js"' in individual
    three = get(dashboard_url, "/dashboard/static/vendor/three.module.min.js")
    assert three.headers["content-type"].startswith("text/javascript")
    assert 'const t="170"' in three.text  # the vendored revision (vendor/README.md)
    assert (STATIC_DIR / "vendor" / "LICENSE-three.txt").read_text().startswith("The MIT License")


def test_plotly_comes_from_the_python_package(dashboard_url):
    if plotly_js() is None:
        pytest.skip("plotly is not installed")
    served = get(dashboard_url, "/dashboard/static/vendor/plotly.min.js")
    assert served.status_code == 200
    assert served.content == plotly_js().read_bytes()


@pytest.mark.parametrize("path", ["/dashboard/runs/999", "/dashboard/individuals/999"])
def test_unknown_run_or_individual_is_a_404_page(dashboard_url, path):
    page = get(dashboard_url, path)
    assert page.status_code == 404
    assert "There is no" in page.text


@pytest.mark.parametrize(
    "name",
    [
        "nope.js",
        "../pages.py",
        "..%2Fpages.py",
        "%2e%2e/%2e%2e/api/app.py",
        "js/../../__init__.py",
        "/etc/passwd",
    ],
)
def test_only_files_of_the_static_folder_are_served(dashboard_url, name):
    assert get(dashboard_url, f"/dashboard/static/{name}").status_code == 404


def test_body_matches_the_frames(dashboard_url, tiny_db):
    body = get(dashboard_url, f"/dashboard/api/individuals/{tiny_db.block_id}/body").json()
    frames = get(dashboard_url, f"/individuals/{tiny_db.block_id}/frames?max_frames=20")
    assert frames.headers["content-type"] == "application/octet-stream"
    motion = decode_frames(frames.content)
    lattice = {tuple(v[:3]) for v in body["voxels"]}
    assert lattice == {tuple(v) for v in motion["voxels"].tolist()}
    assert len(lattice) == 343 and body["workspace"] == [7, 7, 7]
    materials = {tuple(v[:3]): v[3] for v in body["voxels"]}
    assert [materials[tuple(v)] for v in motion["voxels"].tolist()] == motion["material"].tolist()
    assert body["environment"] == "land" and body["settle_seconds"] > 0
    assert body["voxel_size"] > 0 and body["frequency"] > 0 and body["amplitude"] > 0
    assert np.isfinite([v[4] for v in body["voxels"]]).all()


def test_body_of_an_unknown_individual_is_404(dashboard_url):
    assert get(dashboard_url, "/dashboard/api/individuals/999/body").status_code == 404


def test_dashboard_is_not_in_the_openapi_schema(dashboard_url):
    paths = get(dashboard_url, "/openapi.json").json()["paths"]
    assert not [path for path in paths if path.startswith("/dashboard")]


@pytest.mark.parametrize("path", OWN_FILES, ids=lambda p: p.name)
def test_no_dashboard_file_names_an_outside_url(path):
    text = path.read_text(encoding="utf-8")
    assert not re.findall(r"https?://|//cdn|@import", text), path


def test_dashboard_command_refuses_a_missing_database(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "dashboard",
         "--db", f"sqlite:///{tmp_path / 'none.db'}"],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert done.stderr.strip().startswith("error: no database at")
    assert len(done.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "none.db").exists()


def test_every_dashboard_file_is_package_data():
    """A file added under static/ or templates/ must match a glob of pyproject.toml's
    ``[tool.setuptools.package-data]``, or an installed softevo would miss it."""
    import tomllib

    package = Path(STATIC_DIR).parent
    pyproject = tomllib.loads((package.parents[2] / "pyproject.toml").read_text())
    patterns = pyproject["tool"]["setuptools"]["package-data"]["softevo.service.api.dashboard"]
    included = {path for pattern in patterns for path in package.glob(pattern)}
    files = {
        path for folder in ("static", "templates") for path in (package / folder).rglob("*") if path.is_file()
    }
    assert files - included == set()


def test_a_malformed_page_id_is_an_html_page(dashboard_url):
    """``/dashboard/runs/abc`` is a page saying there is no such page (issue 49.13: a JSON
    422); the dashboard's JSON helpers stay JSON."""
    page = get(dashboard_url, "/dashboard/runs/abc")
    assert page.status_code == 404 and page.headers["content-type"].startswith("text/html")
    assert "There is no page /dashboard/runs/abc" in page.text and "valid integer" in page.text
    helper = get(dashboard_url, "/dashboard/api/individuals/abc/body")
    assert helper.status_code == 422 and helper.json()["detail"].startswith("path.individual_id")


def test_the_root_leads_to_the_dashboard(dashboard_url):
    """``/`` redirects to the dashboard (issue 49.13: a 404)."""
    answer = get(dashboard_url, "/", follow_redirects=False)
    assert answer.status_code == 307 and answer.headers["location"] == "/dashboard/"
    assert get(dashboard_url, "/", follow_redirects=True).text.count("Experiments") >= 1
