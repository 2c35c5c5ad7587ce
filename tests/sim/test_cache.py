"""numba cache entries written under another module name are dropped, not fatal."""

from __future__ import annotations

import pickle

from softevo.sim.cache import drop_foreign_entries, foreign_entries


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
