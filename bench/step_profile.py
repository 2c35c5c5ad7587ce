"""Where a step of the CPU engine goes: the time-stamp counter read between the sub-steps of
whole runs of the paper's engine's samples, inside the compiled loop.

    python bench/step_profile.py [ROBOT ...] [--seconds S] [--precision float64|mixed]

For each robot (default: the fork's 8 samples, ``bench/voxcad_paired.py``), one run of S
simulated seconds (default 3) after a short one that compiles: the mean ticks per step of
each sub-step of ``sim.kernels.step`` (link_kernel, change_frames and link_sums are
``link_forces``'s three parts; the mesh's vertices and drag apart) and of the whole step. The
loop below calls the same sub-steps in the same order as ``kernels.step``, with a counter read
between them (``llvm.readcyclecounter``: rdtsc on x86, which counts at a fixed rate, not the
core's clock; the reads are not serialising, so a sub-step's figure includes some of its
neighbour's: on land, where the mesh sub-steps do nothing, each reads about 1,000 ticks).
Ticks, not seconds: compare figures from one machine, trees in turn.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import llvmlite.ir  # noqa: E402
import numpy as np  # noqa: E402
from numba import njit, types  # noqa: E402
from numba.core import cgutils  # noqa: E402
from numba.extending import intrinsic  # noqa: E402

PARTS = ("actuate", "link_kernel", "change_frames", "link_sums", "contact_list",
         "contact_forces", "mesh_vertices", "mesh_drag", "voxel_update", "step")


@intrinsic
def ticks(typingctx):
    """The time-stamp counter (``llvm.readcyclecounter``)."""

    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(
            builder.module, llvmlite.ir.FunctionType(llvmlite.ir.IntType(64), []),
            "llvm.readcyclecounter")
        return builder.call(fn, [])

    return types.uint64(), codegen


def profiled_run():
    from softevo.sim import kernels as K

    @njit
    def run(p, voxels, links, body, work, n):
        T = np.zeros(len(PARTS))
        contacts = K.Contacts(0, K.COLLIDE_MARGIN * p.L)
        for k in range(n):
            t = (k - p.act_start) * p.dt
            c0 = ticks()
            K.actuate(t, p, voxels, work)
            c1 = ticks()
            bad, moves = K.link_kernel(p, work.link_ends, work.split, body.pos, body.quat,
                                       work.size, work.link_buf)
            c2 = ticks()
            if moves:
                K.change_frames(p, work.link_buf, work.link_ends, work.vlink, work.link_id,
                                work.split, work.changed)
            c3 = ticks()
            K.link_sums(work.vlink, work.link_buf, work.force, work.moment)
            c4 = ticks()
            contacts = K.contact_list(p, voxels, body, work, contacts)
            c5 = ticks()
            K.contact_forces(p, voxels, body, work, contacts)
            c6 = ticks()
            K.mesh_vertices(p, voxels, body, work)
            c7 = ticks()
            K.mesh_drag(p, voxels, body, work)
            c8 = ticks()
            speed2 = K.voxel_update(p, voxels, body, work)
            c9 = ticks()
            contacts = K.Contacts(contacts.count, K.travel_after(contacts.travel, speed2, p.dt))
            for i, (a, b) in enumerate(((c0, c1), (c1, c2), (c2, c3), (c3, c4), (c4, c5),
                                        (c5, c6), (c6, c7), (c7, c8), (c8, c9), (c0, c9))):
                T[i] += b - a
        return T / max(n, 1)

    return run


def robot_state(scene: dict, precision: str):
    """A robot's parameters, constants, links, body and work, as ``kernels.run_robot`` makes
    them (the link buffer in float32 for the mixed precision)."""
    from softevo.sim import kernels, system
    from softevo.sim.scene import parse_scene

    robot = system.build_robot(parse_scene(scene))
    batch, state = system.pack([robot])
    p, voxels, links, body = kernels.take_robot(batch, state, 0)
    work = kernels.robot_work(len(robot.pos), links, batch.poff[1] - batch.poff[0],
                              voxels.surface, voxels.near, p.collide, len(voxels.mesh_vert),
                              np.zeros(0, np.float32 if precision == "mixed" else np.float64))
    return p, voxels, links, body, work


def main() -> None:
    import voxcad_paired as paired

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("robots", nargs="*", help="sample names (default: all 8)")
    ap.add_argument("--seconds", type=float, default=3.0, help="simulated seconds per run")
    ap.add_argument("--precision", default="float64", choices=("float64", "mixed"))
    args = ap.parse_args()
    samples = {r["name"]: r for r in paired.samples(None)}
    unknown = [name for name in args.robots if name not in samples]
    if unknown:
        ap.error(f"no sample named {', '.join(unknown)} (have: {', '.join(samples)})")
    run = profiled_run()
    print(f"{'robot':<28}" + "".join(f"{part:>15}" for part in PARTS))
    for name in args.robots or list(samples):
        scene = paired.scene_of(paired.cut(samples[name]["vxa"], args.seconds), args.precision)
        run(*robot_state(scene, args.precision), 10)  # compile
        p, voxels, links, body, work = robot_state(scene, args.precision)
        T = run(p, voxels, links, body, work, int(p.steps))
        print(f"{name:<28}" + "".join(f"{t:>15,.0f}" for t in T), flush=True)


if __name__ == "__main__":
    main()
