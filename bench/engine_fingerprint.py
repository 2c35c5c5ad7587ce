"""The engines' exact output on a fixed set of scenes, as hashes: a refactor of the kernels
that must not change any arithmetic is checked by comparing two prints.

    python bench/engine_fingerprint.py [--cuda] > before.json
    ... change the kernels ...
    python bench/engine_fingerprint.py [--cuda] | diff before.json -

Each line names a scene (world, model, precision) and gives the SHA-256 of its final
positions, recorded frames and centre-of-mass samples (their float64 bytes), its step count
and its reason. The numba engine runs the scenes of tests/sim/test_cuda_engine.py for longer
(a tenth of a second: many contact-list rebuilds, both link frames, the mesh drag) and a few
random robots of tests/sim/test_fuzz.py; ``--cuda`` runs the short scenes on numba-cuda's
simulator instead (slow: minutes). The hashes hold on one machine and one numba/LLVM build
(the compiled code's rounding may differ on another CPU), so they are a local tool, not a
test against stored values.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
if "--cuda" in sys.argv:
    os.environ["NUMBA_ENABLE_CUDASIM"] = "1"

import numpy as np  # noqa: E402

PRECISIONS = ("float64", "mixed")


def digest(result) -> str:
    h = hashlib.sha256()
    frames = result.frames["positions"] if result.frames else []
    for part in (result.final_positions, frames, result.com_trajectory["com"]):
        h.update(np.ascontiguousarray(np.asarray(part, dtype=np.float64)).tobytes())
    return h.hexdigest()[:32]


def scenes(cuda: bool) -> list[tuple[str, dict]]:
    from tests.sim import _support, test_cuda_engine
    from tests.sim.test_fuzz import random_scene

    out = []
    for precision in PRECISIONS:
        _support.PRECISION = precision
        names, short = test_cuda_engine._scenes()
        if cuda:
            out += [(f"{name}.{precision}", scene) for name, scene in zip(names, short, strict=True)]
            continue
        for name, args in test_cuda_engine.TRAJECTORIES.items():
            scene = test_cuda_engine._robot(*args[:5], model=args[5], size=4, seconds=0.1)
            out.append((f"{name}.long.{precision}", scene))
        rng = np.random.default_rng(56)
        for k in range(6):
            out.append((f"random{k}.{precision}",
                        _support.with_precision(random_scene(rng, k), precision)))
    return out


def main() -> None:
    cuda = "--cuda" in sys.argv
    from softevo import sim

    named = scenes(cuda)
    engine = {"engine": "cuda", "device": "cuda:0"} if cuda else {"engine": "numba"}
    results = sim.simulate_many([scene for _, scene in named], **engine)
    for (name, _), result in zip(named, results, strict=True):
        print(json.dumps({"scene": name, "hash": digest(result), "steps": result.steps,
                          "reason": result.reason}))


if __name__ == "__main__":
    main()
