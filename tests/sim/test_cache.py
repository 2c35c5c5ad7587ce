"""numba cache entries written under another module name are dropped, not fatal."""

from __future__ import annotations

import pickle

from softevo.sim.cache import drop_foreign_entries, drop_stale_entries, foreign_entries


def write_index(path, payload: bytes) -> None:
    path.write_bytes(pickle.dumps("0.68.1") + payload)


def test_an_index_naming_a_missing_module_is_dropped_with_its_data(tmp_path):
    foreign = tmp_path / "kernels.run_batch-700.py311.nbi"
    write_index(foreign, b"cno_such_softevo_module\nBatch\n.")  # a pickled global of a gone module
    (tmp_path / "kernels.run_batch-700.py311.1.nbc").write_bytes(b"machine code")
    good = tmp_path / "kernels.step-300.py311.nbi"
    write_index(good, pickle.dumps((1.0, {})))
    (tmp_path / "kernels.step-300.py311.1.nbc").write_bytes(b"machine code")
    other = tmp_path / "engine.run-1.py311.nbi"
    write_index(other, b"cno_such_softevo_module\nBatch\n.")

    assert foreign_entries(tmp_path) == [foreign]
    assert drop_foreign_entries(tmp_path) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "engine.run-1.py311.nbi",
        "kernels.step-300.py311.1.nbc",
        "kernels.step-300.py311.nbi",
    ]
    assert drop_foreign_entries(tmp_path) == 0


def test_kernels_compiled_from_other_sources_are_dropped(tmp_path):
    """A constant of ``sim.physics`` is frozen into the cached kernels: when any source the
    kernels read changes, their entries go (and only theirs), once."""
    physics = tmp_path / "physics.py"
    physics.write_text("COLLIDE_MARGIN = 0.2\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    entries = ["kernels.run_batch-700.py311.nbi", "kernels.run_batch-700.py311.1.nbc"]
    for name in [*entries, "tables.within_hops-66.py311.nbi"]:
        (cache / name).write_bytes(b"machine code")
    assert drop_stale_entries(cache, [physics]) == 2  # no stamp yet: compiled from unknown sources
    assert sorted(p.name for p in cache.iterdir()) == ["kernels.sources", "tables.within_hops-66.py311.nbi"]
    for name in entries:
        (cache / name).write_bytes(b"machine code")
    assert drop_stale_entries(cache, [physics]) == 0  # the same sources: kept
    physics.write_text("COLLIDE_MARGIN = 0.3\n")
    assert drop_stale_entries(cache, [physics]) == 2
    assert drop_stale_entries(cache, [physics]) == 0


def test_the_engine_names_every_source_its_kernels_import():
    """``KERNEL_SOURCES`` covers the sim modules ``kernels`` imports (a new one must join)."""
    import ast
    from pathlib import Path

    from softevo.sim import kernels, numba_engine

    tree = ast.parse(Path(kernels.__file__).read_text())
    imported = {node.module for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module}
    imported |= {alias.name for node in ast.walk(tree)
                 if isinstance(node, ast.ImportFrom) and node.level == 1 and not node.module
                 for alias in node.names}
    named = {p.stem for p in numba_engine.KERNEL_SOURCES}
    assert imported <= named, imported - named
    assert "kernels" in named


def test_files_that_cannot_be_removed_or_written_do_not_fail_the_import(tmp_path):
    """An installed package may sit where no one may write: the check must not fail the import
    there (numba then caches in its user-wide directory). Stood in for, as root too, by an
    entry and a stamp that are directories (unlink and write raise OSError)."""
    physics = tmp_path / "physics.py"
    physics.write_text("COLLIDE_MARGIN = 0.3\n")
    cache = tmp_path / "__pycache__"
    (cache / "kernels.run_batch-700.py311.nbi").mkdir(parents=True)
    (cache / "kernels.sources").mkdir()
    (cache / "kernels.step-300.py311.1.nbc").write_bytes(b"machine code")
    assert drop_stale_entries(cache, [physics]) == 1  # the one file that could go
    assert sorted(p.name for p in cache.iterdir()) == ["kernels.run_batch-700.py311.nbi",
                                                      "kernels.sources"]
