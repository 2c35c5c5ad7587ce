"""Column names shared by the database layer and the analyses: plain constants, no imports.

``service.db`` stores and exports these columns; ``analysis`` computes on them. Both import
them from here, so the analyses need nothing from ``service``.
"""

# What each evaluation measures (docs/spec.md sections 3-4): objectives and descriptors.
TRAITS = (
    "distance",
    "active_share",
    "voxel_count",
    "frequency",
    "symmetry",
    "branching",
    "shape_entropy",
)

# One row per evaluation of an individual (the export's ``individuals`` file, and
# ``ExperimentData.evaluations`` before its treatment and repetition labels).
INDIVIDUAL_COLUMNS = [
    "individual_id",
    "run_id",
    "parent_id",
    "generation",
    "generation_born",
    "age",
    "environment",
    *TRAITS,
    "stable",
    "error",
]
