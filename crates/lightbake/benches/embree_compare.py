#!/usr/bin/env python3
"""Embree 4 on the same triangles and rays as lightbake's BVH.

    cargo run --release -p lightbake --example ray_workload -- /tmp/rays
    pip install embreex numpy
    python3 crates/lightbake/benches/embree_compare.py /tmp/rays

Reads triangles.f32, gather.f32, shadow.f32 and lightbake.json written by the example,
traces the gather rays (closest hit, INTERSECT) and the shadow rays (any hit, OCCLUDED) with
embreex (Embree 4, one ray at a time on one thread: the same setting as the example's
timing), best of twenty passes, and prints both tracers' rates, hit counts and the ratio
lightbake / Embree. Results go in docs/benchmarks.md.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

REPEATS = 20


def load_rays(path):
    r = np.fromfile(path, dtype="<f4").reshape(-1, 7)
    origins = np.ascontiguousarray(r[:, 0:3])
    dirs = np.ascontiguousarray(r[:, 3:6])
    tmax = np.ascontiguousarray(r[:, 6])
    # Embree wants finite far distances.
    tmax[~np.isfinite(tmax)] = 1e30
    return origins, dirs, tmax


def best(fn, count):
    rate, result = 0.0, None
    for _ in range(REPEATS):
        start = time.perf_counter()
        result = fn()
        rate = max(rate, count / (time.perf_counter() - start))
    return rate, result


def main():
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "ray_workload")
    tris = np.fromfile(folder / "triangles.f32", dtype="<f4").reshape(-1, 3, 3)
    ours = json.loads((folder / "lightbake.json").read_text())
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, tris)
    go, gd, gt = load_rays(folder / "gather.f32")
    so, sd, st = load_rays(folder / "shadow.f32")
    n = len(go)
    closest, ids = best(lambda: scene.run(go, gd, dists=gt.copy(), query="INTERSECT"), n)
    shadow, occ = best(lambda: scene.run(so, sd, dists=st.copy(), query="OCCLUDED"), len(so))
    hits = int((np.asarray(ids) >= 0).sum())
    occluded = int((np.asarray(occ) >= 0).sum()) if np.asarray(occ).dtype != bool else int(np.asarray(occ).sum())
    print(f"{len(tris)} triangles, {n} gather rays, {len(so)} shadow rays; one thread, best of {REPEATS}")
    print(f"{'':12} {'lightbake':>12} {'Embree 4':>12} {'ratio':>7}   hits (lightbake / Embree)")
    print(f"{'closest hit':12} {ours['closest_per_second'] / 1e6:>10.3f} M {closest / 1e6:>10.3f} M "
          f"{ours['closest_per_second'] / closest:>7.2f}   {ours['closest_hits']} / {hits}")
    print(f"{'any hit':12} {ours['shadow_per_second'] / 1e6:>10.3f} M {shadow / 1e6:>10.3f} M "
          f"{ours['shadow_per_second'] / shadow:>7.2f}   {ours['shadow_occluded']} / {occluded}")


if __name__ == "__main__":
    main()
