"""Animations of a stored individual's evaluated motion.

``task_motion`` re-simulates a ``worker.tasks.Task`` with frame recording on
(``worker.tasks.replay``, about ``worker.tasks.DEFAULT_RECORD_FPS`` frames per simulated
second); ``stored_motion`` does it for a stored record (same genome, encoding, stiffness,
cycles and environment as its evaluation; the simulator is deterministic) and
``record_motion`` for a stored individual's id.
``animate`` draws each frame's deformed surface mesh (``sim.mesh``, as the dashboard's replay
and VoxCAD: one vertex per shared lattice corner, one quadrilateral per exposed face, coloured
by its voxel: active red, passive cyan), the centre of mass's path, and the floor on land,
and writes a GIF (Pillow) or an MP4 (ffmpeg, when it is installed).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import animation  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from softevo.analysis.render import ACTIVE_COLOR, EDGE_COLOR, PASSIVE_COLOR, VIEW  # noqa: E402
from softevo.errors import UserError  # noqa: E402
from softevo.sim import worlds  # noqa: E402
from softevo.sim.mesh import deformed_mesh, lattice_mesh  # noqa: E402

FORMATS = (".gif", ".mp4")
PLAYBACK_FPS = 20
MAX_FRAMES = 240
SIZE_INCHES = 6.0
ANIMATION_DPI = 80


@dataclass(frozen=True)
class Motion:
    """Recorded motion of one robot.

    t: (f,) seconds; positions: (f, n, 3) metres; voxels: (n, 3) body indices;
    materials: (n,) 1 passive / 2 active; voxel_size: metres.
    """

    t: np.ndarray
    positions: np.ndarray
    voxels: np.ndarray
    materials: np.ndarray
    voxel_size: float
    environment: str
    distance: float
    stored_distance: float | None
    label: str


def task_motion(task, label: str = "", stored_distance: float | None = None) -> Motion:
    """The motion of a ``worker.tasks.Task`` (``worker.tasks.replay`` at the default
    frame rate), labelled ``label``; ``stored_distance`` is the distance its evaluation
    stored, if known."""
    from softevo.worker.tasks import replay

    try:
        frames = replay(task)
    except ValueError as exc:
        raise UserError(f"individual {task.id} has an empty body: nothing to simulate") from exc
    if len(frames["t"]) == 0:
        raise UserError(f"individual {task.id}: the simulation recorded no frames")
    return Motion(
        t=frames["t"],
        positions=frames["positions"],
        voxels=frames["voxels"].astype(int),
        materials=frames["material"].astype(int),
        voxel_size=float(frames["voxel_size"]),
        environment=task.environment,
        distance=float(frames["distance"]) if frames["stable"] else float("nan"),
        stored_distance=stored_distance,
        label=label,
    )


def stored_motion(record: dict, environment: str | None = None) -> Motion:
    """The motion of a stored record (``service.storage.individuals.individual_record``) in
    ``environment`` (default: that of its latest evaluation; one it was never evaluated in
    replays it there, its stored distance None)."""
    from softevo.analysis.robots import stored_distance, stored_task

    task = stored_task(record, environment, elsewhere=True)
    label = f"individual {record['id']} \u00b7 {record['treatment_name']} \u00b7 {task.environment}"
    return task_motion(task, label, stored_distance(record, task.environment))


def face_quads(mesh_face: np.ndarray) -> np.ndarray:
    """The exposed faces of a surface mesh (``sim.mesh``: two consecutive triangles per
    face, sharing a diagonal) as quadrilaterals: (q, 4) vertex indices, counter-clockwise
    from outside, each triangle pair's second vertex off the diagonal put between the
    diagonal's ends."""
    quads = []
    for first, second in zip(mesh_face[0::2, :3], mesh_face[1::2, :3], strict=True):
        (extra,) = set(second.tolist()) - set(first.tolist())
        for k in range(3):  # the diagonal is the edge of ``first`` that ``second`` also has
            a, b = first[k], first[(k + 1) % 3]
            if a in second and b in second:
                quads.append([a, extra, b, first[(k + 2) % 3]])
                break
    return np.array(quads, dtype=int).reshape(-1, 4)


def face_directions(quads: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Direction of each quad's outward normal in the rest mesh ``rest`` (nv, 3): 2 axis +
    (1 if it points to minus), i.e. +x, -x, +y, -y, +z, -z as ``_SHADE``."""
    a, b, c = rest[quads[:, 0]], rest[quads[:, 1]], rest[quads[:, 2]]
    normal = np.cross(b - a, c - a)
    axis = np.abs(normal).argmax(axis=1)
    negative = normal[np.arange(len(normal)), axis] < 0
    return 2 * axis + negative


def frame_indices(t: np.ndarray, fps: int = PLAYBACK_FPS, max_frames: int = MAX_FRAMES):
    """(indices into ``t``, speed-up): frames for real-time playback at ``fps``, thinned
    evenly (and played faster) when that needs more than ``max_frames``."""
    wanted = np.arange(0.0, t[-1] + 1e-12, 1.0 / fps)
    speed = max(1.0, len(wanted) / max_frames)
    if speed > 1.0:
        wanted = np.linspace(0.0, t[-1], max_frames)
    indices = np.unique(np.clip(np.searchsorted(t, wanted), 0, len(t) - 1))
    return indices, speed


def _has_floor(environment: str) -> bool:
    """Whether a pure world of the registry with a floor (a compound world is drawn without)."""
    return environment in worlds.names() and worlds.get(environment).floor


def _limits(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    half = motion.voxel_size
    low = motion.positions.min(axis=(0, 1)) - half
    high = motion.positions.max(axis=(0, 1)) + half
    if _has_floor(motion.environment):
        low[2] = 0.0
    span = high - low
    pad = np.maximum(0.0, 0.5 * (np.max(span[:2]) - span))  # square ground footprint
    pad[2] = 0.0
    return low - pad, high + pad


def _floor(ax, low: np.ndarray, high: np.ndarray) -> None:
    square = [[(low[0], low[1], 0), (high[0], low[1], 0), (high[0], high[1], 0), (low[0], high[1], 0)]]
    ax.add_collection3d(Poly3DCollection(square, facecolor="0.88", edgecolor="0.6", zorder=0))


# brightness of a face by direction (+x, -x, +y, -y, +z, -z): a light from above and the front
_SHADE = np.array([0.85, 0.7, 0.75, 0.9, 1.0, 0.55])


def _shaded_colors(materials: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """RGB (m, 3) of faces: active red / passive cyan, darkened by face direction."""
    from matplotlib.colors import to_rgb

    base = np.where((materials == 2)[:, None], to_rgb(ACTIVE_COLOR), to_rgb(PASSIVE_COLOR))
    return base * _SHADE[directions][:, None]


def animate(
    motion: Motion,
    out: str | Path,
    fps: int = PLAYBACK_FPS,
    max_frames: int = MAX_FRAMES,
    on_frame: Callable[[int, int], None] | None = None,
) -> Path:
    """Write ``motion`` as ``out`` (.gif or .mp4); ``on_frame(i, n)`` reports progress."""
    out = Path(out)
    writer = movie_writer(out, fps)
    indices, speed = frame_indices(motion.t, fps, max_frames)
    nbr, mesh_vert, mesh_face = lattice_mesh(motion.voxels)
    quads = face_quads(mesh_face)
    rest = deformed_mesh((motion.voxels + 0.5) * motion.voxel_size, nbr, mesh_vert, motion.voxel_size)
    directions = face_directions(quads, rest)
    colors = _shaded_colors(motion.materials[mesh_face[0::2, 3]], directions)
    fig = plt.figure(figsize=(SIZE_INCHES, SIZE_INCHES), dpi=ANIMATION_DPI)
    ax = fig.add_subplot(projection="3d")
    low, high = _limits(motion)
    ax.set(xlim=(low[0], high[0]), ylim=(low[1], high[1]), zlim=(low[2], high[2]))
    ax.set_box_aspect(high - low)
    ax.view_init(**VIEW)
    ax.computed_zorder = False  # floor, then body, then path: drawn in that order
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    if _has_floor(motion.environment):
        _floor(ax, low, high)
    body = Poly3DCollection([], facecolors=colors, edgecolor=EDGE_COLOR, linewidths=0.3, zorder=1)
    ax.add_collection3d(body)
    com = motion.positions.mean(axis=1)
    (trace,) = ax.plot([], [], [], color="black", lw=1.0, zorder=2)
    title = fig.suptitle("")

    def draw(k: int):
        f = indices[k]
        vertices = deformed_mesh(motion.positions[f], nbr, mesh_vert, motion.voxel_size)
        body.set_verts(vertices[quads])
        trace.set_data_3d(com[: f + 1, 0], com[: f + 1, 1], com[: f + 1, 2])
        pace = "" if speed == 1.0 else f"  (\u00d7{speed:.1f} speed)"
        title.set_text(f"{motion.label}\nt = {motion.t[f]:.2f} s{pace}")
        return body, trace, title

    movie = animation.FuncAnimation(fig, draw, frames=len(indices), blit=False)
    try:
        movie.save(out, writer=writer, dpi=ANIMATION_DPI, progress_callback=on_frame)
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from exc
    finally:
        plt.close(fig)
    return out


def movie_writer(out: Path, fps: int) -> animation.AbstractMovieWriter:
    suffix = out.suffix.lower()
    if suffix not in FORMATS:
        raise UserError(f"--out must end in .gif or .mp4 (got {out.name!r})")
    if not out.parent.exists():
        raise UserError(f"cannot write {out}: directory {out.parent} does not exist")
    if suffix == ".gif":
        return animation.PillowWriter(fps=fps)
    if not animation.writers.is_available("ffmpeg"):
        raise UserError("MP4 needs ffmpeg on PATH (not found); write a .gif instead")
    return animation.FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"])
