"""numba's on-disk cache of the kernels (``sim/__pycache__/kernels.*.nbi`` and ``.nbc``).

numba names a cache entry by the source file's name, not by the module's, and unpickles its
index before it checks that the source is unchanged. An index written when these kernels were
imported under another module name (e.g. ``sim`` as a top-level package rather than
``softevo.sim``) fails to load with ``ModuleNotFoundError`` instead of being recompiled.
``drop_foreign_entries`` removes such entries; the engine calls it once, before its first
compilation, so that a cache holding them recompiles instead of failing.
"""

from __future__ import annotations

import pickle
from pathlib import Path


def foreign_entries(cache_dir: Path, stem: str = "kernels") -> list[Path]:
    """Index files of ``stem`` in ``cache_dir`` whose pickled index cannot be read here."""
    foreign = []
    for index in sorted(cache_dir.glob(f"{stem}.*.nbi")):
        try:
            with open(index, "rb") as handle:
                pickle.load(handle)  # numba's version
                pickle.loads(handle.read())  # (source stamp, overloads)
        except (ModuleNotFoundError, AttributeError, ImportError):
            foreign.append(index)
        except Exception:  # anything else is numba's to handle (it rewrites stale entries)
            continue
    return foreign


def drop_foreign_entries(cache_dir: Path, stem: str = "kernels") -> int:
    """Remove the foreign index files of ``stem`` and their data files; returns how many."""
    dropped = 0
    for index in foreign_entries(cache_dir, stem):
        base = index.name[: -len(".nbi")]
        for path in [index, *cache_dir.glob(f"{base}.*.nbc")]:
            path.unlink(missing_ok=True)
        dropped += 1
    return dropped
