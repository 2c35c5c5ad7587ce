"""``softevo simulate SCENE.json``: run one scene through the physics engine.

Plain output is a short human summary; ``--json`` prints exactly ``Result.to_dict()`` as one
JSON object (with ``--energy``, plus an ``energy`` object: ``sim.energy``'s audit of the
run, docs/physics.md "Energy"); ``--record out.npz`` also writes the frames (``t`` (n_frames,) seconds,
``positions`` (n_frames, n_voxels, 3) metres, ``voxels`` (n_voxels, 3) body indices). A scene
without a ``record`` field is recorded at about ``worker.tasks.DEFAULT_RECORD_FPS`` frames
per simulated second (``worker.tasks.default_record_every``) when ``--record`` is given.

Mistakes (missing file, invalid JSON, malformed scene, a scene over the limits of
``service.runs.limits``: ``SOFTEVO_MAX_VOXELS``, ``SOFTEVO_MAX_VOXEL_STEPS``, unwritable output) raise
``UserError`` / ``sim.SceneError``; ``service.cli.main`` turns them into one line and exit 2.
An unstable robot is a result, not an error: it is reported with its reason and exit 0.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from softevo.errors import UserError
from softevo.evolution import environments as environments
from softevo.service.cli.options import device_option, engine_option
from softevo.worker.tasks import default_record_every


def _read_scene(path: Path) -> dict[str, Any]:
    """Load a scene document from a JSON file; every failure is one UserError line."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a directory, expected a scene JSON file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read ({exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(
            f"{path}: invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}"
        ) from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: scene: must be a JSON object (got {type(data).__name__})")
    return data


def _write_record(out: Path, result: Any) -> int:
    """Write the frames of ``result`` to ``out`` (.npz); return the number of frames."""
    import numpy as np

    frames = result.frames or {"t": [], "positions": []}
    t = np.asarray(frames["t"], dtype=np.float64)
    positions = np.asarray(frames["positions"], dtype=np.float64)
    voxels = np.asarray(result.voxels, dtype=np.int64).reshape(-1, 3)
    positions = positions.reshape(len(t), len(voxels), 3)
    try:
        with open(out, "wb") as fh:  # a file object keeps the name exactly as given
            np.savez_compressed(fh, t=t, positions=positions, voxels=voxels)
    except OSError as exc:
        raise UserError(f"--record: cannot write {out} ({exc.strerror or exc})") from None
    return len(t)


def distance_axes(scene: Any) -> str:
    """How the scene's distance is measured, in words: ``"horizontal"`` or ``"3-D"``. A world
    without a floor measures 3-D; on a floor the model's ``distance`` option decides (the
    paper's model measures 3-D there too, ``sim.scene.ModelOptions.distance``)."""
    axes = environments.get(scene.environment.kind).distance
    if axes == environments.HORIZONTAL and scene.options.distance == "3d":
        return environments.THREE_D
    return axes


def _summary(result: Any, wall_seconds: float, environment: str, axes: str) -> str:
    """A few stable-format lines a person can read at a glance."""
    lines = [
        f"stable     {'yes' if result.stable else 'NO: ' + str(result.reason)}",
        f"distance   {result.distance:.4g} voxel lengths ({axes}, {environment})",
        f"simulated  {result.simulated_seconds:.4g} s in {result.steps:,} steps "
        f"(dt {result.dt:.3g} s)",
        f"wall time  {wall_seconds:.2f} s",
    ]
    return "\n".join(lines)


def _energy_summary(audit: dict) -> str:
    """The energy audit's balance in three lines (joules; docs/physics.md "Energy")."""
    rest = (audit["unaccounted"] - audit["integrator_term"] + audit["link_nonconservative"]
            + audit["frame_switches"])
    return "\n".join([
        f"energy     actuator work {audit['actuator_work']:.4g} J, mechanical change "
        f"{audit['mechanical_change']:.4g} J, dissipated {audit['dissipated_known']:.4g} J",
        f"           unaccounted {audit['unaccounted']:.3g} J = the beam's non-gradient loads "
        f"{-audit['link_nonconservative']:.3g} J + frame switches {-audit['frame_switches']:.3g} J",
        f"           + the step's term {audit['integrator_term']:.3g} J (tolerance "
        f"{audit['tolerance']:.3g} J) + the rest {rest:.3g} J",
    ])


def simulate(
    scene_path: Annotated[
        Path, typer.Argument(metavar="SCENE.json", help="Scene file (docs/spec.md section 1).")
    ],
    as_json: Annotated[
        bool, typer.Option("--json", help="Print Result.to_dict() as one JSON object.")
    ] = False,
    record: Annotated[
        Path | None,
        typer.Option("--record", metavar="OUT.npz", help="Write frames (t, positions, voxels)."),
    ] = None,
    engine: engine_option("default numba") = None,
    device: device_option("default cuda:0 with --engine cuda") = None,
    precision: Annotated[
        str | None,
        typer.Option("--precision", metavar="float64|mixed",
                     help="The arithmetic, over the scene's model_options.precision: float64, or "
                          "mixed (each link's beam in float32; docs/fidelity.md)."),
    ] = None,
    energy: Annotated[
        bool, typer.Option("--energy", help="Audit the run's energy: actuator work, mechanical "
                                            "change, dissipation (docs/physics.md, Energy).")
    ] = False,
) -> None:
    """Simulate one scene and print its result."""
    from softevo.service.runs.limits import check_scene
    from softevo.worker import physics as sim

    scene_dict = _read_scene(scene_path)
    if precision is not None:
        if precision not in sim.PRECISIONS:
            raise UserError(f"--precision: must be one of {', '.join(sim.PRECISIONS)} (got {precision!r})")
        options = scene_dict.get("model_options")
        scene_dict = {**scene_dict, "model_options": {
            **(options if isinstance(options, dict) else {}), "precision": precision}}
    check_scene(scene_dict)  # fail fast, before compiling anything: malformed, too large or too long
    if record is not None and "record" not in scene_dict:
        scene_dict = {**scene_dict, "record": {"every": default_record_every(scene_dict)}}
    started = time.perf_counter()
    engine = engine or "numba"
    if device is not None and engine not in ("cuda", "sleep"):
        raise UserError("--device: only the cuda and sleep engines take a device (add --engine cuda)")
    if energy and engine == "sleep":
        raise UserError("--energy: the sleep engine has no physics to audit (use numba or cuda)")
    result = sim.simulate(scene_dict, engine=engine, device=device)
    wall = time.perf_counter() - started
    n_frames = _write_record(record, result) if record is not None else 0
    audit = (sim.energy_audit(scene_dict, engine, result.final_positions) if energy else None)
    if as_json:
        out = result.to_dict()
        if audit is not None:
            out["energy"] = audit
        typer.echo(json.dumps(out))
        return
    scene = sim.parse_scene(scene_dict)
    typer.echo(_summary(result, wall, scene.environment.kind, distance_axes(scene)))
    if audit is not None:
        typer.echo(_energy_summary(audit))
    if record is not None:
        typer.echo(f"recorded   {n_frames} frames -> {record}")


def register(app: typer.Typer) -> None:
    """Add the ``simulate`` command to ``app``."""
    app.command("simulate")(simulate)
