"""In headless Chromium: the replay draws one connected surface mesh (two triangles per
exposed face, as the frames' mesh says), its vertices where ``sim.mesh`` puts them for the
same frame, and no cubes. Skips where Chromium or Playwright is missing (see conftest)."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from softevo.service.api.frames import decode_frames
from softevo.sim.mesh import deformed_mesh, lattice_mesh
from tests.dashboard.chromium import browser_missing
from tests.dashboard.test_browser import open_replay

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing())),
]

FIRST_FRAME = """() => new Promise(resolve => {
  const replay = window.softevoReplay, rendered = replay.renderedFrames;
  replay.pause();
  replay.seek(0);
  (function wait() {
    if (replay.renderedFrames > rendered) {
      const position = replay.mesh.geometry.getAttribute("position");
      resolve({
        kind: replay.mesh.type,
        triangles: position.count / 3,
        indexed: replay.mesh.geometry.index !== null,
        vertices: Array.from(replay.vertices),
        environment: replay.body.environment,
      });
    } else requestAnimationFrame(wait);
  })();
})"""


def test_replay_renders_the_surface_mesh_of_the_frames(dashboard_url, tiny_db, open_page):
    page = open_replay(open_page(dashboard_url), dashboard_url, tiny_db.block_id)
    drawn = page.evaluate(FIRST_FRAME)
    query = f"environment={drawn['environment']}"
    base = f"{dashboard_url}/individuals/{tiny_db.block_id}"
    frames = httpx.get(f"{base}/frames?max_frames=1000&{query}", timeout=300)  # the page's
    motion = decode_frames(frames.content)
    body = httpx.get(f"{dashboard_url}/dashboard/api/individuals/{tiny_db.block_id}/body?{query}")
    exposed = 6 * 7 * 7  # the 7^3 block's outer faces
    assert drawn["kind"] == "Mesh"  # one mesh, not instanced cubes
    assert drawn["triangles"] == len(motion["mesh_face"]) == 2 * exposed
    nbr, mesh_vert, _ = lattice_mesh(motion["voxels"])
    assert mesh_vert.tolist() == motion["mesh_vert"].tolist()
    expected = deformed_mesh(motion["positions"][0].astype(float), nbr, mesh_vert, body.json()["voxel_size"])
    size = float(np.ptp(expected, axis=0).max())
    assert np.array(drawn["vertices"]).reshape(-1, 3) == pytest.approx(expected, abs=1e-5 * size)
