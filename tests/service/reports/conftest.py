"""The reports read the analyses' tiny experiment (``tests.analysis.conftest``): one real
experiment stored on SQLite, evaluated inline."""

from tests.analysis.conftest import TinyExperiment, tiny, tiny_data  # noqa: F401 (fixtures)
