#!/usr/bin/env python3
"""Times slamkit's octree insertion against OctoMap's on the same clouds, single thread, and
checks that OctoMap reads slamkit's .bt and agrees with its own tree cell by cell.

Clouds (both sides get the same float32 points and sensor origins, world frame):
  7-Scenes   RedKitchen depth frames 0, 10, 20, ... from $SLAMKIT_DATA, every 4th pixel in u and
             v, back-projected with fx = fy = 585, cx = 320, cy = 240 (depth in mm, 0 and 65535
             invalid) and moved to the world with the ground-truth world_from_camera poses
             (rotations re-orthonormalised by SVD).
  synthetic  a closed 8 x 6 x 3 m room holding a 1 m sphere, scanned from a few origins with
             rays in random directions (seeded), end points on the first surface hit.

Both sides use the same sensor model (slamkit's defaults, set on OctoMap's tree: OctoMap's own
p_hit default is 0.7), the same resolution and the same maximum range. OctoMap is the
`pyoctomap` PyPI binding (OctoMap 1.10, built without OpenMP), installed by this script into a
virtualenv with NumPy and Pillow (default target/octomap-venv; override with
SLAMKIT_OCTOMAP_VENV). Times are thread CPU times; each is the median of --reps builds of a new
tree from all scans.

OctoMap columns:
  eager      `insertPointCloud(points, origin, max_range)` per scan, as a user calls it. The
             binding copies the points one by one into an octomap::Pointcloud in a Cython loop
             and calls updateInnerOccupancy() after every scan (redundant after an eager insert).
  lazy       `insertPointCloud(..., lazy_eval=True)` per scan and one updateInnerOccupancy() at
             the end: no inner-node update or pruning per voxel, so less work than OctoMap's
             normal insertion; a lower bound on its native cost.
  floor      the eager call with every point moved to the sensor origin (zero-length rays): the
             binding's per-point and per-scan overhead, an upper bound on what the wrapper adds.

Memory: OctoMap's memoryUsage() and slamkit's node-storage bytes (OctreeStats::bytes, allocated
capacity), each divided by the number of occupied leaves.

Usage: SLAMKIT_DATA=/path/to/data scripts/bench_octree_vs_octomap.py [--reps N] [--frames N]
"""
import argparse
import json
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

from bench_common import ROOT, build_example, ensure_venv

VENV = Path(os.environ.get("SLAMKIT_OCTOMAP_VENV", ROOT / "target" / "octomap-venv"))
# slamkit's OctreeConfig defaults (OctoMap's own defaults except p_hit, 0.7 there).
SENSOR = dict(p_hit=0.85, p_miss=0.4, p_min=0.12, p_max=0.97, threshold=0.5)
MAX_RANGE_M = 3.5
FX, CX, CY = 585.0, 320.0, 240.0


def read_depth_mm(path):
    """A 16-bit depth PNG as a float array [mm]."""
    import numpy as np
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im, dtype=np.float64)


def sevenscenes_scans(data, frames, stride=4):
    import numpy as np

    folder = data / "rgbd" / "7scenes_redkitchen_frames_0000-0599"
    scans = []
    for i in range(frames):
        stem = folder / f"frame-{10 * i:06d}"
        depth = read_depth_mm(f"{stem}.depth.png")[::stride, ::stride]
        v, u = np.mgrid[0:480:stride, 0:640:stride]
        ok = (depth > 0) & (depth < 65535)
        z = depth[ok] / 1000.0
        cam = np.stack([(u[ok] - CX) * z / FX, (v[ok] - CY) * z / FX, z], axis=1)
        pose = np.loadtxt(f"{stem}.pose.txt")
        uu, _, vt = np.linalg.svd(pose[:3, :3])
        rot = uu @ vt
        world = cam @ rot.T + pose[:3, 3]
        scans.append((pose[:3, 3].copy(), world.astype(np.float32)))
    return scans


def synthetic_scans(n_scans=10, rays=20000, seed=7):
    """Rays from origins inside a box room [0,8]x[0,6]x[0,3] with a sphere (centre (5,3,1),
    radius 0.5); each end point is the first surface hit."""
    import numpy as np

    rng = np.random.default_rng(seed)
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([8.0, 6.0, 3.0])
    centre, radius = np.array([5.0, 3.0, 1.0]), 0.5
    scans = []
    for _ in range(n_scans):
        origin = rng.uniform([1.0, 1.0, 0.5], [3.5, 5.0, 2.5])
        d = rng.normal(size=(rays, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        with np.errstate(divide="ignore"):
            t_box = np.where(d > 0, (hi - origin) / d, (lo - origin) / d).min(axis=1)
        oc = origin - centre
        b = d @ oc
        disc = b * b - (oc @ oc - radius * radius)
        t_sph = np.where(disc > 0, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
        t = np.where((t_sph > 0) & (t_sph < t_box), t_sph, t_box)
        scans.append((origin, (origin + d * t[:, None]).astype(np.float32)))
    return scans


def write_scans(scans, path):
    import numpy as np

    with open(path, "wb") as f:
        f.write(np.uint32(len(scans)).tobytes())
        for origin, pts in scans:
            f.write(np.asarray(origin, "<f8").tobytes())
            f.write(np.uint32(len(pts)).tobytes())
            f.write(np.ascontiguousarray(pts, "<f4").tobytes())


def new_octomap(res):
    import pyoctomap

    tree = pyoctomap.OcTree(res)
    tree.setProbHit(SENSOR["p_hit"])
    tree.setProbMiss(SENSOR["p_miss"])
    tree.setClampingThresMin(SENSOR["p_min"])
    tree.setClampingThresMax(SENSOR["p_max"])
    tree.setOccupancyThres(SENSOR["threshold"])
    return tree


def octomap_build(scans, res, mode):
    """Builds a tree from all scans; returns (tree, thread CPU ms)."""
    import numpy as np

    tree = new_octomap(res)
    clouds = [(np.asarray(o, np.float64),
               np.repeat(np.asarray(o, np.float64)[None], len(p), axis=0) if mode == "floor"
               else p.astype(np.float64)) for o, p in scans]
    t0 = time.thread_time_ns()
    for origin, pts in clouds:
        tree.insertPointCloud(pts, origin, max_range=MAX_RANGE_M, lazy_eval=(mode == "lazy"))
    if mode == "lazy":
        tree.updateInnerOccupancy()
    return tree, (time.thread_time_ns() - t0) * 1e-6


def slamkit_run(exe, scans_path, res, reps, bt_path):
    out = subprocess.run([str(exe), "--reps", str(reps), "--max-range", str(MAX_RANGE_M),
                          "--bt", str(bt_path), str(res), str(scans_path)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def leaf_agreement(a, b):
    """Samples `b` at the centre of every leaf of `a`; volumes in finest voxels. Returns
    (leaves agreeing, leaves of a, volume agreeing, volume of a known, volume unknown in b)."""
    import numpy as np

    n_same = n_all = 0
    v_same = v_all = v_unknown = 0
    for it in a.begin_leafs():
        c = np.array(it.getCoordinate(), np.float64)
        w = 8 ** (16 - it.getDepth())
        n_all += 1
        v_all += w
        node = b.search(c)
        if node is None:
            v_unknown += w
            continue
        if a.isNodeOccupied(it) == b.isNodeOccupied(node):
            n_same += 1
            v_same += w
    return n_same, n_all, v_same, v_all, v_unknown


def occupied_leaves(tree):
    return sum(1 for it in tree.begin_leafs() if tree.isNodeOccupied(it))


def compare(exe, name, scans, res, reps, tmp):
    import pyoctomap

    scans_path = Path(tmp) / f"{name}.bin"
    bt_sk, bt_om = Path(tmp) / f"{name}_slamkit.bt", Path(tmp) / f"{name}_octomap.bt"
    write_scans(scans, scans_path)
    sk = slamkit_run(exe, scans_path, res, reps, bt_sk)
    ms = {m: statistics.median(octomap_build(scans, res, m)[1] for _ in range(reps))
          for m in ("eager", "lazy", "floor")}
    om, _ = octomap_build(scans, res, "eager")
    om_occ = occupied_leaves(om)
    om_mem, om_leaves, om_nodes = om.memoryUsage(), om.getNumLeafNodes(), om.size()
    loaded = pyoctomap.OcTree(0.1)
    if not loaded.readBinary(str(bt_sk)):
        raise RuntimeError(f"pyoctomap could not read {bt_sk}")
    fwd = leaf_agreement(om, loaded)
    back = leaf_agreement(loaded, om)
    om.writeBinary(str(bt_om))
    same_bytes = bt_sk.read_bytes() == bt_om.read_bytes()
    return dict(name=name, res=res, sk=sk, ms=ms, om_occ=om_occ, om_mem=om_mem,
                om_leaves=om_leaves, om_nodes=om_nodes, fwd=fwd, back=back,
                same_bytes=same_bytes, loaded_res=loaded.getResolution())


def report(r):
    sk, ms = r["sk"], r["ms"]
    a = sk["ms"]
    print(f"\n### {r['name']}, {r['res'] * 100:g} cm, max range {MAX_RANGE_M:g} m "
          f"({sk['scans']} scans, {sk['points']} points)\n")
    print("| | slamkit | OctoMap eager | OctoMap lazy | OctoMap wrapper floor |")
    print("|---|---:|---:|---:|---:|")
    print(f"| insert all scans, ms | {a:.1f} | {ms['eager']:.1f} | {ms['lazy']:.1f} | "
          f"{ms['floor']:.1f} |")
    print(f"| ratio slamkit / OctoMap | | {a / ms['eager']:.2f} | {a / ms['lazy']:.2f} | |")
    print(f"| ratio slamkit / (OctoMap eager - floor) | | "
          f"{a / max(ms['eager'] - ms['floor'], 1e-9):.2f} | | |")
    print("\n| | slamkit | OctoMap |")
    print("|---|---:|---:|")
    print(f"| nodes | {sk['nodes']} | {r['om_nodes']} |")
    print(f"| leaves | {sk['leaves']} | {r['om_leaves']} |")
    print(f"| occupied leaves | {sk['occupied_leaves']} | {r['om_occ']} |")
    print(f"| node memory, bytes | {sk['bytes']} | {r['om_mem']} |")
    print(f"| bytes per occupied leaf | {sk['bytes'] / max(sk['occupied_leaves'], 1):.1f} | "
          f"{r['om_mem'] / max(r['om_occ'], 1):.1f} |")
    print(f"| bytes per leaf | {sk['bytes'] / max(sk['leaves'], 1):.1f} | "
          f"{r['om_mem'] / max(r['om_leaves'], 1):.1f} |")
    for label, (ns, na, vs, va, vu) in (("OctoMap's leaves, sampled in slamkit's .bt", r["fwd"]),
                                        ("slamkit's .bt leaves, sampled in OctoMap", r["back"])):
        print(f"\n{label}: {ns}/{na} leaves agree ({ns / max(na, 1):.6f}); by volume "
              f"{vs / max(va, 1):.6f} agree, {vu / max(va, 1):.6f} unknown in the other")
    print(f"slamkit's .bt read by pyoctomap at resolution {r['loaded_res']:g}; "
          f"byte-identical to OctoMap's own writeBinary: {r['same_bytes']}")


def main():
    ensure_venv(VENV, ["pyoctomap==1.2.2", "numpy", "pillow"], __file__)
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    data = Path(os.environ.get("SLAMKIT_DATA", ROOT.parent / "shared" / "data"))
    exe = build_example("slamkit-map", "octree_timing")
    sets = {"7-Scenes RedKitchen": sevenscenes_scans(data, args.frames),
            "synthetic room": synthetic_scans()}
    print(f"single thread (thread CPU time); median of {args.reps} builds; OctoMap = pyoctomap "
          f"1.2.2; sensor model p_hit {SENSOR['p_hit']}, p_miss {SENSOR['p_miss']}, clamp "
          f"[{SENSOR['p_min']}, {SENSOR['p_max']}], threshold {SENSOR['threshold']}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, scans in sets.items():
            for res in (0.09, 0.05):
                report(compare(exe, name, scans, res, args.reps, tmp))


if __name__ == "__main__":
    main()
