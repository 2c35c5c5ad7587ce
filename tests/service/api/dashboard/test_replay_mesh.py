"""In headless Chromium: the replay draws one connected surface mesh (two triangles per
exposed face, as the frames' mesh says), its vertices where ``sim.mesh`` puts them for the
same frame, and no cubes. Skips where Chromium or Playwright is missing (see conftest)."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from softevo.service.api.frames import decode_frames
from softevo.sim.mesh import deformed_mesh, lattice_mesh
from tests.service.api.dashboard.chromium import browser_missing
from tests.service.api.dashboard.test_browser import open_replay

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


MESH_JS = """async ([lattice, positions, meshVert, size]) => {
  const mesh = await import("/dashboard/static/js/mesh.js");
  const count = lattice.length / 3;
  const nbr = mesh.neighbours(Int32Array.from(lattice), count);
  const centres = Float64Array.from(positions);
  const axes = mesh.voxelAxes(centres, nbr, size, count, new Float64Array(9 * count));
  const out = new Float64Array((meshVert.length / 8) * 3);
  const vertices = mesh.meshVertices(Int32Array.from(meshVert), centres, axes, out);
  return {nbr: Array.from(nbr), vertices: Array.from(vertices)};
}"""


@pytest.mark.parametrize("seed", range(4))
def test_mesh_js_is_sim_mesh_on_irregular_deformed_robots(dashboard_url, open_page, seed):
    """Chains, sheets and lone voxels: every way an axis is completed, in the browser."""
    rng = np.random.default_rng(seed)
    voxels = np.argwhere(rng.random((5, 4, 3)) < 0.45)
    voxels = voxels[rng.permutation(len(voxels))]
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    turn *= np.sign(np.linalg.det(turn))
    size = 0.01
    centres = (voxels + 0.5) * size @ turn.T + rng.normal(0, 0.1 * size, (len(voxels), 3))
    nbr, mesh_vert, _ = lattice_mesh(voxels)
    page = open_page(dashboard_url).page
    page.goto(f"{dashboard_url}/dashboard/")
    args = [voxels.ravel().tolist(), centres.ravel().tolist(), mesh_vert.ravel().tolist(), size]
    drawn = page.evaluate(MESH_JS, args)
    assert np.array(drawn["nbr"]).reshape(-1, 6).tolist() == nbr.tolist()
    expected = deformed_mesh(centres, nbr, mesh_vert, size)
    assert np.array(drawn["vertices"]).reshape(-1, 3) == pytest.approx(expected, abs=1e-12)
