"""The options and arguments several ``softevo`` commands share, each declared once."""

from __future__ import annotations

from typing import Annotated

import typer

ENGINES = "numba (CPU), cuda (NVIDIA GPUs: docs/gpu.md) or sleep (no physics, its time only: docs/cluster.md)"
DEVICES = "CUDA device cuda:0, cuda:1, ... (--engine cuda), or the sleep engine's speed-up x<factor>"
RUN_HELP = "5, r5, run-5; or latest, e2, a name: an experiment of one run"
INDIVIDUAL_HELP = "an individual id (12), or a run (latest, r5, a name) for its best in its last world"

DbOption = Annotated[
    str | None,
    typer.Option("--db", help="SQLAlchemy URL (default $SOFTEVO_DB or sqlite:///softevo.db)"),
]
WorkersOption = Annotated[
    int | None,
    typer.Option("--workers", help="evaluation processes (default: all cores; 0: inline)"),
]
QuietOption = Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar")]
JsonOption = Annotated[bool, typer.Option("--json", help="print JSON")]
RunArgument = Annotated[str, typer.Argument(metavar="RUN", help=RUN_HELP)]


# What a bare number (``5``) names, per kind of argument, and how to name the others: a
# bare number is a run in best/status/export, an individual in lineage and an experiment in
# report, so each command says what it took it as (issue 49.5).
BARE_NUMBER = {
    "run": "run {n}; e{n} names experiment {n}",
    "individual": "individual {n}; r{n} names run {n}'s best individual",
    "experiment": "experiment {n}; r{n}'s experiment: softevo status r{n}",
}


_NOTES: list[str] = []  # what this command took bare numbers as (``take_notes``)


def say_bare_number(reference: str | None, kind: str) -> None:
    """Note what the bare number ``reference`` was taken as (``kind``: run, individual or
    experiment); nothing for any other reference. ``service.cli.main`` prints the notes as
    ``note:`` lines on stderr when the command ends, or adds them to its one error line."""
    text = (reference or "").strip()
    if text.isdigit():
        _NOTES.append(f"{text} is taken as {BARE_NUMBER[kind].format(n=int(text))}")


def take_notes() -> list[str]:
    """The notes ``say_bare_number`` made since the last call (and forget them)."""
    notes = list(_NOTES)
    _NOTES.clear()
    return notes


def engine_option(default: str):
    """``--engine NAME``, its default said as ``default``."""
    return Annotated[str | None, typer.Option("--engine", help=f"{ENGINES}; {default}")]


def device_option(default: str):
    """``--device DEVICE``, its default said as ``default``."""
    return Annotated[str | None, typer.Option("--device", help=f"{DEVICES}; {default}")]


def redis_url_option(default: str):
    """``--redis-url URL``, its default said as ``default``."""
    return Annotated[str | None, typer.Option("--redis-url", help=default)]
