"""evolution uses sim's one ``largest_component`` without loading the engine (numba)."""

from __future__ import annotations

import subprocess
import sys


def test_largest_component_is_sims():
    from softevo.evolution import descriptors, genotype
    from softevo.sim.system import largest_component

    assert genotype.largest_component is largest_component is descriptors.largest_component


def test_evolution_and_the_coordinator_do_not_import_numba():
    code = "import sys, softevo.evolution, softevo.service.runs.coordinator; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
