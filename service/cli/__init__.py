"""The ``softevo`` command line.

Each command group lives in its own module of this package and registers itself on the
shared Typer app: ``sim`` (simulate), ``evolution`` (describe), ``runs`` (run, experiment,
status, resume, export, lineage, ...), ``service`` (serve, worker), ``dashboard``,
``analysis`` (report, show, power, VXA files), ``phylogeny`` and ``plan``; ``options`` holds
the options several of them share. A user's mistake (bad arguments,
a malformed scene, a database that cannot be written) is reported as one line on stderr with
exit status 2, never as a traceback.
"""

from __future__ import annotations

import sys

import typer

from softevo.service.cli.options import take_notes

app = typer.Typer(
    name="softevo",
    help="Evolve soft voxel robots on land and in water.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _user_error_types() -> tuple[type[BaseException], ...]:
    from softevo.errors import UserError
    from softevo.worker.physics import EngineUnavailable, SceneError

    return (UserError, SceneError, EngineUnavailable)


def _print_version(value: bool) -> None:
    if value:
        from softevo import __version__

        typer.echo(f"softevo {__version__}")
        raise typer.Exit()


@app.callback()
def _group(
    version: bool = typer.Option(
        False, "--version", is_eager=True, callback=_print_version, help="print the version and exit"
    ),
) -> None:
    """Evolve soft voxel robots on land and in water."""


def usage_error_line(message: str) -> str:
    """``error: <message>`` of a click usage message ("Missing option '--env'."), read as
    softevo's own (``error: no run 5``): lower-case first word, no closing full stop."""
    text = " ".join(str(message).split())
    if text[:1].isupper() and not text[1:2].isupper():
        text = text[0].lower() + text[1:]
    return f"error: {text.removesuffix('.')}"


def _register() -> None:
    """Add every command group to ``app``, once per process.

    ``main`` may be called many times in one process (the tests do); adding the commands again
    each time would grow typer's command list, and its lookup time with it, without end.
    """
    if app.registered_commands or app.registered_groups:
        return
    from softevo.service.cli import (
        analysis,
        archive,
        dashboard,
        evolution,
        phylogeny,
        plan,
        runs,
        service,
        sim,
    )

    for module in (sim, evolution, runs, service, analysis, dashboard, phylogeny, archive, plan):
        module.register(app)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``softevo`` console script."""
    _register()
    user_errors = _user_error_types()
    take_notes()
    try:
        from softevo.plugins import load_plugins

        load_plugins()  # SOFTEVO_PLUGINS: traits, objectives, worlds a deployment registers
        # standalone_mode=False: click returns a ``typer.Exit``'s code instead of exiting
        # (Ctrl-C during a run: 130, so ``softevo run ... && softevo report`` stops there)
        code = app(args=argv, standalone_mode=False)
    except user_errors as exc:
        notes = "; ".join(take_notes())  # what a bare number was taken as, in the one line
        print(f"error: {exc}" + (f" ({notes})" if notes else ""), file=sys.stderr)
        sys.exit(2)
    except typer.Abort:
        print("aborted", file=sys.stderr)
        sys.exit(130)
    except Exception as exc:
        # usage errors (unknown option, missing argument) from typer's bundled click
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):
            if exc.format_message().strip():  # empty: no arguments, the help is shown
                print(usage_error_line(exc.format_message()), file=sys.stderr)
            sys.exit(2)
        raise
    for note in take_notes():
        print(f"note: {note}", file=sys.stderr)
    if isinstance(code, int) and not isinstance(code, bool) and code:
        sys.exit(code)

