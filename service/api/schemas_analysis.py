"""Response body of ``GET /experiments/{id}/analysis``: an experiment's treatments side by
side (``service.reports.report.experiment`` says how each part is computed). Every statistic's
unit is the run; missing or non-finite numbers are null."""

from __future__ import annotations

from pydantic import BaseModel, Field


class ExperimentName(BaseModel):
    id: int
    name: str


class Interval(BaseModel):
    n: int = Field(description="runs")
    mean: float | None
    low: float | None = Field(description="95% Student t interval over runs (null below 2 runs)")
    high: float | None


class AnalysisRun(BaseModel):
    run_id: int
    repetition: int
    seed: int
    status: str
    generation: int = Field(description="last stored generation (-1: none yet)")


class AnalysisTreatment(BaseModel):
    name: str
    environment: str
    schedule: str = Field(description="e.g. land:0,water:2500")
    stiffness_mpa: float
    model: str = Field(description="the physics model of its evaluations (sim.models)")
    switch_at: int | None
    generations: int
    population: int
    color: str = Field(description="the report's colour of the treatment, #rrggbb")
    display_generation: int | None = Field(description="the generation it is shown and compared at")
    best_distance: Interval = Field(description="run best distances at the display generation")
    runs: list[AnalysisRun]


class Curve(BaseModel):
    treatment: str
    generation: list[int]
    environment: list[str] = Field(
        description="the world each generation was evaluated in (distances of different worlds "
        "are not comparable: the dashboard draws one panel per world)"
    )
    n: list[int] = Field(description="runs that stored the generation")
    mean: list[float | None] = Field(description="mean best distance over runs (voxel lengths)")
    low: list[float | None] = Field(description="95% t interval, clipped at 0 (a distance is never negative)")
    high: list[float | None]


class QDCurve(BaseModel):
    treatment: str
    metric: str = Field(description="qd_score | coverage (analysis.qd.METRICS)")
    label: str
    generation: list[int]
    environment: list[str] = Field(description="the world whose archive each generation shows")
    n: list[int] = Field(description="runs that stored the generation")
    mean: list[float | None] = Field(description="mean over runs of their archives after the generation")
    low: list[float | None] = Field(description="95% t interval (null below 2 runs), clipped to its range")
    high: list[float | None]


class Points(BaseModel):
    individual_id: list[int]
    run_id: list[int]
    distance: list[float | None]
    active_share: list[float | None] = Field(description="share of active voxels: the energy objective")
    voxel_count: list[int | None]


class Front(BaseModel):
    treatment: str
    generation: int | None
    members: int = Field(description="population members of all runs at the generation")
    points: Points = Field(description="at most 2000 of them (an even sample holding the front)")
    front: Points = Field(description="their non-dominated front, by active share")


class DescriptorValues(BaseModel):
    treatment: str
    run_id: list[int]
    values: list[float | None] = Field(description="one per run: its population's mean (or best distance)")


class Descriptor(BaseModel):
    metric: str
    label: str
    treatments: list[DescriptorValues]


class StatisticRow(BaseModel):
    """A row of the report's statistics table (``analysis.stats_tables``)."""

    comparison: str = Field(description="between treatments | described | start vs end")
    family: str = Field(description="question | metric: Bonferroni runs within it")
    family_size: int
    test: str
    metric: str
    metric_label: str
    a: str
    b: str
    generation: int | None
    n_a: int
    n_b: int
    mean_a: float | None
    mean_b: float | None
    median_a: float | None
    median_b: float | None
    p: float | None
    p_bonferroni: float | None
    significance: str
    A12: float | None = Field(description="Vargha-Delaney effect size")
    detectable_A12: float | None
    difference: float | None = Field(description="mean a - mean b")
    difference_low: float | None
    difference_high: float | None
    interval: str


class ExperimentAnalysisOut(BaseModel):
    experiment: ExperimentName
    interval: str = Field(description="how the curves' and treatments' intervals are computed")
    treatments: list[AnalysisTreatment]
    curves: list[Curve]
    qd: list[QDCurve] = Field(description="QD score and coverage of the runs' MAP-Elites archives")
    fronts: list[Front]
    descriptors: list[Descriptor]
    statistics: list[StatisticRow]
