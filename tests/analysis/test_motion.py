"""Motion of a stored individual: re-simulated exactly, animated as a GIF; ``softevo show``."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
from matplotlib import animation
from PIL import Image

from softevo.analysis.motion import (
    ANIMATION_DPI,
    SIZE_INCHES,
    animate,
    face_directions,
    face_quads,
    frame_indices,
    stored_motion,
)
from softevo.service.storage.individuals import individual_record
from softevo.sim.mesh import deformed_mesh, lattice_mesh
from tests.support import softevo


@pytest.fixture(scope="module")
def best(tiny_data):
    final = tiny_data.final_populations()
    return final.loc[final["distance"].idxmax()]


@pytest.fixture(scope="module")
def motion(tiny, best):
    return stored_motion(individual_record(tiny.engine, int(best["individual_id"])))


def test_the_replay_is_the_evaluation(motion, best):
    assert motion.environment == best["environment"]
    assert motion.stored_distance == pytest.approx(best["distance"])
    assert motion.distance == pytest.approx(best["distance"], rel=1e-9, abs=1e-12)
    n = len(motion.voxels)
    assert motion.positions.shape == (len(motion.t), n, 3) and len(motion.t) > 10
    assert set(np.unique(motion.materials)) <= {1, 2}
    assert np.all(np.diff(motion.t) > 0)


def test_animation_is_a_gif_of_the_frames(motion, tmp_path):
    out = animate(motion, tmp_path / "m.gif", fps=10)
    indices, speed = frame_indices(motion.t, 10)
    with Image.open(out) as image:
        assert image.format == "GIF"
        side = int(SIZE_INCHES * ANIMATION_DPI)
        assert image.size == (side, side)
        assert image.n_frames == len(indices) > 1


def test_frame_indices_play_in_real_time_or_thin_evenly():
    t = np.arange(0, 2.0001, 0.01)  # 2 s recorded at 100 frames per second
    indices, speed = frame_indices(t, fps=20)
    assert speed == 1.0 and len(indices) == 41 and t[indices[1]] == pytest.approx(0.05)
    indices, speed = frame_indices(t, fps=20, max_frames=10)
    assert speed == pytest.approx(4.1) and len(indices) == 10 and indices[-1] == len(t) - 1


def test_the_animation_draws_the_surface_mesh_as_quads_of_two_voxels():
    voxels = np.array([[0, 0, 0], [1, 0, 0]])
    nbr, mesh_vert, mesh_face = lattice_mesh(voxels)
    quads = face_quads(mesh_face)
    assert len(quads) == 10  # 12 faces, 2 of them shared
    rest = deformed_mesh((voxels + 0.5) * 0.05, nbr, mesh_vert, 0.05)
    assert len(rest) == 12  # the shared face's 4 corners are one vertex each
    directions = face_directions(quads, rest)
    assert np.bincount(directions).tolist() == [1, 1, 2, 2, 2, 2]  # +x, -x, +y, -y, +z, -z
    for quad, direction in zip(quads, directions, strict=True):
        corners = rest[quad]
        axis, sign = direction // 2, -1 if direction % 2 else 1
        assert np.ptp(corners[:, axis]) == 0  # planar, across its axis
        assert len({tuple(np.round(c / 0.05, 6)) for c in corners}) == 4
        normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
        assert sign * normal[axis] > 0  # counter-clockwise from outside
        assert np.cross(corners[3] - corners[2], corners[0] - corners[2])[axis] * sign > 0


def test_show_command_writes_a_gif(capsys, tiny, best, tmp_path):
    out = tmp_path / "best.gif"
    individual = str(int(best["individual_id"]))
    code, stdout, err = softevo(capsys, "show", individual, "--out", str(out), "--db", tiny.url, "-q")
    assert code == 0, err
    assert out.stat().st_size > 0 and stdout.startswith(f"{out}: individual {individual}")


def test_show_mp4_without_ffmpeg_is_a_clear_error(capsys, tiny, best, tmp_path, monkeypatch):
    monkeypatch.setitem(matplotlib.rcParams, "animation.ffmpeg_path", str(tmp_path / "no-ffmpeg"))
    assert not animation.writers.is_available("ffmpeg")
    individual = str(int(best["individual_id"]))
    code, _, err = softevo(capsys, "show", individual, "--out", str(tmp_path / "m.mp4"), "--db", tiny.url)
    assert code == 2 and "MP4 needs ffmpeg" in err


@pytest.mark.skipif(not animation.writers.is_available("ffmpeg"), reason="no ffmpeg")
def test_show_mp4_with_ffmpeg(capsys, tiny, best, tmp_path):
    out = tmp_path / "m.mp4"
    individual = str(int(best["individual_id"]))
    code, _, err = softevo(capsys, "show", individual, "--out", str(out), "--db", tiny.url, "-q")
    assert code == 0, err
    assert out.stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["999999", "--out", "x.gif"], "no individual 999999"),
        (["1", "--out", "x.png"], "--out must end in .gif or .mp4"),
        (["1", "--out", "missing/x.gif"], "does not exist"),
    ],
)
def test_show_mistakes_are_one_line_and_exit_2(capsys, tiny, tmp_path, args, message):
    args = [str(tmp_path / a) if a.startswith(("x.", "missing")) else a for a in args]
    code, _, err = softevo(capsys, "show", *args, "--db", tiny.url, "-q")
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err
