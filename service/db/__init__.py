"""SQL storage of experiments, runs and every individual that ever lived.

Every SQL statement of the service lives in this package (SQLAlchemy core, bound
parameters), one module per noun:

- ``engine``: ``open_database`` (engine + migrations), ``make_engine``, ``database_reachable``;
- ``models``: the tables; ``migrate``: Alembic upgrades;
- ``experiments``: API listings and ``load_experiment(engine, id) -> ExperimentData``;
- ``runs``: run summaries and details, ``active_run_ids`` and ``set_run_status`` (every
  status change goes through it);
- ``generations``: per-generation summaries and the Pareto front of a generation;
- ``individuals``: one individual and its evaluations, ``individual_record``;
- ``store``: the writes (``create_experiment``, ``record_generation``) and the CLI's run
  lookups (``run_row``, ``resolve_runs``, ``resolve_experiment``);
- ``status``: run summaries and lineage records for displays; ``phylogeny``: lineages;
  ``export``: CSV/Parquet files; ``rows``: result rows as JSON-ready dicts.
"""

from softevo.service.db.engine import database_url, make_engine, open_database
from softevo.service.db.models import RunStatus

__all__ = ["RunStatus", "database_url", "make_engine", "open_database"]
