"""numba's on-disk cache of the kernels (``sim/__pycache__/kernels.*.nbi`` and ``.nbc``).

numba names a cache entry by the source file's name, not by the module's, and unpickles its
index before it checks that the source is unchanged. An index written when these kernels were
imported under another module name (e.g. ``sim`` as a top-level package rather than
``softevo.sim``) fails to load with ``ModuleNotFoundError`` instead of being recompiled.
``drop_foreign_entries`` removes such entries; the engine calls it once, before its first
compilation, so that a cache holding them recompiles instead of failing.

numba also checks only the kernel file's own stamp: a constant the kernels take from another
module (``sim.physics``' ``COLLIDE_MARGIN``, ``sim.system``'s flags) is frozen into the cached
code, and changing it there left the old value running. ``drop_stale_entries`` keeps a hash
of every source the kernels read beside the cache and drops the kernels' entries when it
changes; the engine calls it with ``drop_foreign_entries``.
"""

from __future__ import annotations

import hashlib
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


def sources_hash(sources: list[Path]) -> str:
    """The SHA-256 of the sources' bytes, in the order given."""
    digest = hashlib.sha256()
    for source in sources:
        digest.update(source.read_bytes())
    return digest.hexdigest()


def drop_stale_entries(cache_dir: Path, sources: list[Path], stem: str = "kernels") -> int:
    """Remove every cache file of ``stem`` when ``sources`` are not those its entries were
    compiled from (their hash, kept in ``<stem>.sources``); returns how many files went. A
    cache directory that cannot be written is left to numba (which then compiles in memory)."""
    stamp = cache_dir / f"{stem}.sources"
    current = sources_hash(sources)
    try:
        if stamp.read_text() == current:
            return 0
    except OSError:
        pass
    dropped = 0
    for path in [*cache_dir.glob(f"{stem}.*.nbi"), *cache_dir.glob(f"{stem}.*.nbc")]:
        try:
            path.unlink(missing_ok=True)
        except OSError:  # read-only: numba caches elsewhere (its user-wide directory)
            continue
        dropped += 1
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
        stamp.write_text(current)
    except OSError:
        pass
    return dropped
