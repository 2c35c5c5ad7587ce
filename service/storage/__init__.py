"""SQL storage of experiments, runs and every individual that ever lived.

Every SQL statement of the service lives in this package (SQLAlchemy core, bound
parameters), one module per noun:

- ``engine``: ``open_database`` (engine + migrations), ``make_engine``, ``database_reachable``;
- ``models``: the tables; ``migrate``: Alembic upgrades;
- ``experiments``: ``create_experiment``, ``resolve_experiment``, API listings and
  ``load_experiment(engine, id) -> ExperimentData``;
- ``runs``: ``run_row``, ``resolve_runs``, run summaries and details, ``active_run_ids`` and
  ``set_run_status`` (every status change goes through it);
- ``generations``: ``record_generation``, per-generation summaries, the Pareto front;
- ``individuals``: one individual and its evaluations, ``individual_record``,
  ``local_to_db_ids``;
- ``status``: run summaries and lineage records for displays; ``phylogeny``: lineages;
  ``run_tree``: a run's tree (paged) and the dashboard's bounded sample of it;
  ``exaptation``: founders' lines across an environment switch (``docs/sql.md``);
  ``archive``: a run's MAP-Elites archive and its QD score per generation, from its evaluations;
  ``export``: CSV/Parquet files; ``rows``: result rows as JSON-ready dicts;
- ``store``: the write and lookup functions re-exported by their former home.
"""

from softevo.service.storage.engine import database_url, make_engine, open_database

__all__ = ["database_url", "make_engine", "open_database"]
