"""Progress display for the coordinator: one rich bar over all generations of all runs,
with the generation, best distance, evaluations per second and time left."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from softevo.service.runs.coordinator import GenerationReport


class ProgressReporter:
    """Listener for ``Coordinator(on_generation=...)`` that drives a rich progress bar."""

    def __init__(self, progress: Progress, total_generations: int, done: int = 0) -> None:
        self.progress = progress
        self.task = progress.add_task("starting", total=total_generations, completed=done, best="-", rate="-")
        self.best: dict[int, float] = {}
        self.evaluations = 0
        self.started = time.perf_counter()

    def __call__(self, report: GenerationReport) -> None:
        self.best[report.run_id] = report.best_distance
        self.evaluations += report.evaluations
        rate = self.evaluations / max(1e-9, time.perf_counter() - self.started)
        self.progress.update(
            self.task,
            advance=1,
            description=generation_text(report.run_id, report.generation, report.generations),
            best=f"{max(self.best.values()):.3f}",
            rate=f"{rate:.1f}",
        )


def generation_text(run_id: int, generation: int, generations: int) -> str:
    """A stored generation as REST and the exports number it (``generation``: from 0), with the
    count stored of the run's ``generations`` (docs/contracts.md, "Numbering")."""
    return f"run {run_id} generation {generation} stored ({generation + 1} of {generations})"


@contextmanager
def progress_bar(
    total_generations: int, done: int = 0, enabled: bool = True
) -> Iterator[ProgressReporter | None]:
    """A progress reporter on stderr (None when disabled)."""
    if not enabled:
        yield None
        return
    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("best {task.fields[best]}"),
        TextColumn("{task.fields[rate]} eval/s"),
        TimeElapsedColumn(),
        TextColumn("left"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=Console(stderr=True), transient=False) as progress:
        yield ProgressReporter(progress, total_generations, done)
