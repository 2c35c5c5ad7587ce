"""The effect of each of the paper's engine's physics choices, one switch at a time.

For a land and a water robot from the paper's own engine (the VoxCAD land/water fork's sample
robots, tests/sim/reference/voxcad), imported as a user would, this runs our model of that
engine (``"model": "voxcad-land-water"``) in full and then with each choice turned back to
Voxelyze 2.0's, and prints the distance (normAbsoluteDisplacement: 3-D, voxel lengths) of
each, its ratio to the full model and the paper's engine's own figure. docs/fidelity.md
holds the table.

    python bench/voxcad_fidelity.py [--land sample_quadruped_land] [--water sample_hexapus]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from softevo import sim
from softevo.analysis.vxa_import import vxa_to_scene
from softevo.sim import models

DATA = Path(__file__).resolve().parents[1] / "tests" / "sim" / "reference" / "voxcad"
PLAIN = models.options("voxelyze-2")

# (item of issue 24, what changes): each a change from the fork's model back to Voxelyze 2's.
SWITCHES = [
    ("1 rotation damping x10 -> x1", {"model_options": {"rotation_damping": PLAIN.rotation_damping}}),
    ("2 no contact within 3 hops -> bonded only",
     {"model_options": {"collision_horizon": PLAIN.collision_horizon}}),
    ("2b contact spheres of 1.5 L -> touching cubes", {"model_options": {"contact": PLAIN.contact}}),
    ("3 absolute actuation clock -> since settling",
     {"model_options": {"actuation_clock": PLAIN.actuation_clock}}),
    ("3b actuation one step late -> on time", {"model_options": {"actuation_lag": PLAIN.actuation_lag}}),
    ("3c the fork's floor friction -> Voxelyze 2's", {"model_options": {"friction": PLAIN.friction}}),
    ("4 3-D distance -> horizontal", {"model_options": {"distance": PLAIN.distance}}),
    ("5 drag on the mesh -> on voxel faces", {"model_options": {"drag": PLAIN.drag}}),
    ("6 dt 0.7, no floor -> dt 0.5, 2000 steps/cycle",
     {"dt_fraction": models.get("voxelyze-2").dt_fraction,
      "model_options": {"min_steps_per_cycle": PLAIN.min_steps_per_cycle}}),
    ("10 amplitude 0.14 -> 0.39", {"actuation": {"amplitude": models.get("voxelyze-2").amplitude}}),
    ("all: the voxelyze-2 model", None),
]


def variant(scene: dict, change: dict | None) -> dict:
    """``scene`` with one change applied (None: the plain voxelyze-2 model, same robot)."""
    if change is None:
        plain = {k: v for k, v in scene.items() if k not in ("model", "model_options", "dt_fraction")}
        plain["actuation"] = {k: v for k, v in scene["actuation"].items() if k != "amplitude"}
        return plain
    out = {**scene, **{k: v for k, v in change.items() if k not in ("model_options", "actuation")}}
    out["model_options"] = {**scene.get("model_options", {}), **change.get("model_options", {})}
    out["actuation"] = {**scene.get("actuation", {}), **change.get("actuation", {})}
    return out


def table(names: list[str]) -> list[dict]:
    rows = []
    for name in names:
        case = json.loads((DATA / f"{name}.json").read_text())
        scene = vxa_to_scene(case["vxa"].encode(), name).scene
        scenes = [scene] + [variant(scene, change) for _, change in SWITCHES]
        results = sim.simulate_many(scenes)
        full = results[0].distance
        rows.append({"robot": name, "fork": case["voxcad"]["fitness"]["normAbsoluteDisplacement"],
                     "full": full,
                     "switches": {label: r.distance for (label, _), r in
                                  zip(SWITCHES, results[1:], strict=True)}})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--land", default="sample_quadruped_land")
    parser.add_argument("--water", default="sample_hexapus")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args()
    rows = table([args.land, args.water])
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    print(f"{'change (fork -> Voxelyze 2)':<50}" + "".join(f"{r['robot'][7:]:>30}" for r in rows))
    print(f"{'the paper engine itself':<50}" + "".join(f"{r['fork']:>30.2f}" for r in rows))
    print(f"{'our model of it, all switches as the fork':<50}"
          + "".join(f"{r['full']:>22.2f} ({r['full'] / r['fork']:4.2f}x)" for r in rows))
    for label, _ in SWITCHES:
        print(f"{label:<50}" + "".join(
            f"{r['switches'][label]:>22.2f} ({r['switches'][label] / r['full']:4.2f}x)" for r in rows))


if __name__ == "__main__":
    main()
