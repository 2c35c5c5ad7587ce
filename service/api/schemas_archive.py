"""Response body of ``GET /runs/{id}/archive``: a run's MAP-Elites archive, computed from its
stored evaluations (``service.storage.archive`` and ``evolution.archive`` say what each field
means); the JSON of ``softevo archive RUN --json``."""

from __future__ import annotations

from pydantic import BaseModel, Field


class ArchiveElite(BaseModel):
    individual: int = Field(description="the elite's individual id (its page: /dashboard/individuals/{id})")
    cell: list[int] = Field(description="grid indices, one per measure")
    index: int = Field(description="the cell's flat (row-major) index")
    distance: float = Field(description="its distance in the archive's world (voxel lengths)")
    measures: dict[str, float] = Field(description="its value of each measure")
    generation: int = Field(description="the generation of the evaluation that put it there")


class ArchiveGeneration(BaseModel):
    generation: int
    coverage: float = Field(description="share of the cells filled after the generation")
    qd_score: float = Field(description="sum of the elites' distances after the generation")
    filled: int


class ArchiveOut(BaseModel):
    run: int
    generation: int = Field(description="the archive after this generation")
    environment: str = Field(description="the world whose evaluations fill it")
    environments: list[str] = Field(description="every world the run evaluated in, in the order met")
    measures: list[str] = Field(description="the traits of the grid's axes")
    bounds: list[list[float]] = Field(description="[low, high] of each measure")
    cells: list[int] = Field(description="cells per measure")
    coverage: float = Field(description="share of the cells filled")
    qd_score: float = Field(description="sum of the elites' distances")
    filled: int
    elites: list[ArchiveElite] = Field(description="one per filled cell, in flat-index order")
    history: list[ArchiveGeneration] = Field(description="after each generation 0 .. generation")
