"""SQL storage of experiments, runs and every individual that ever lived.

Public API: ``open_database`` (engine + migrations), the models in ``models``, writes and
reads in ``store``, phylogeny queries in ``phylogeny``, CSV/Parquet export in ``export``.
"""

from softevo.service.db.engine import database_url, make_engine, open_database
from softevo.service.db.models import RunStatus

__all__ = ["RunStatus", "database_url", "make_engine", "open_database"]
