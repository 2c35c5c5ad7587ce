"""Commands registered on the softevo CLI by the evolution layer: ``softevo describe``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from softevo.errors import UserError


def _read_scene(path: Path):
    """The validated scene in ``path`` (sim.parse_scene); a UserError for an unreadable file."""
    from softevo.worker import physics as sim

    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise UserError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    except json.JSONDecodeError as exc:
        raise UserError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from exc
    return sim.parse_scene(data)


def describe(
    scene_path: Annotated[Path, typer.Argument(help="A scene JSON file (docs/spec.md section 1).")],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Shape descriptors of the scene's body: symmetry, branching, shape entropy, voxel
    count, active share and frequency (largest face-connected component, as simulated)."""
    from softevo.evolution.descriptors import describe as describe_body

    scene = _read_scene(scene_path)
    if not scene.body.any():
        raise UserError(f"{scene_path}: body: has no voxel")
    result = describe_body(scene.body, scene.actuation.frequency)
    if as_json:
        typer.echo(json.dumps(result))
        return
    for key, value in result.items():
        shown = f"{value:.4f}" if isinstance(value, float) else str(value)
        typer.echo(f"{key:>14}  {shown}")


def register(app: typer.Typer) -> None:
    """Add this module's commands to ``app``."""
    app.command("describe")(describe)
