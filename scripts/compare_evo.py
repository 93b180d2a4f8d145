#!/usr/bin/env python3
"""Runs evo_ape / evo_rpe and `slamkit eval ... --json` on the same trajectory pairs and prints
their statistics side by side. Called by compare_evo.sh, which sets up evo and builds slamkit.

KITTI files hold rotation matrices rounded to ~7 digits, so they are not exactly orthonormal.
slamkit reads every pose as a rigid transform (re-orthonormalised), whereas evo uses the raw
matrices and inverts them by transposition; RPE then differs in the ~1e-6 range on long deltas.
For KITTI pairs evo is therefore also run on the same rigid poses slamkit reads (the polar
factor of each rotation, written back at full precision): column "evo rigid". The gate compares
slamkit with that column; the difference to evo on the raw files is printed as well.

Exit status 1 when any statistic differs by more than TOLERANCE or any pair count differs."""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from evo.core.trajectory import PosePath3D
from evo.tools import file_interface

TOLERANCE = 1e-6
STATS = ["rmse", "mean", "median", "std", "min", "max"]
MAX_DIFF = "0.02"

# (name, evo format, reference, estimate, sim3 sensible, RPE delta in metres)
PAIRS = [
    ("fr1_xyz rgbdslam", "tum", "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt", False, 0.5),
    ("fr2_desk ORB", "tum", "fr2_desk_groundtruth.txt", "fr2_desk_ORB.txt", True, 0.5),
    ("KITTI_00 ORB", "kitti", "KITTI_00_gt.txt", "KITTI_00_ORB.txt", True, 100.0),
    ("KITTI_00 SPTAM", "kitti", "KITTI_00_gt.txt", "KITTI_00_SPTAM.txt", True, 100.0),
    ("V102", "euroc", "V102_groundtruth.csv", "V102.txt", True, 0.5),
]


def cases(delta_m, sim3):
    """(label, evo arguments, slamkit arguments) of each metric run on a pair."""
    out = [
        ("ATE se3", ["evo_ape", "-a"], ["ate", "--align", "se3"]),
        ("ATE none", ["evo_ape"], ["ate", "--align", "none"]),
    ]
    if sim3:
        out.append(("ATE sim3", ["evo_ape", "-as"], ["ate", "--align", "sim3"]))
    out += [
        ("RPE 1 f", ["evo_rpe", "--delta", "1", "--delta_unit", "f"],
         ["rpe", "--delta", "1", "--unit", "frames"]),
        ("RPE 10 f all", ["evo_rpe", "--delta", "10", "--delta_unit", "f", "--all_pairs"],
         ["rpe", "--delta", "10", "--unit", "frames", "--all-pairs"]),
        (f"RPE {delta_m:g} m", ["evo_rpe", "--delta", str(delta_m), "--delta_unit", "m"],
         ["rpe", "--delta", str(delta_m), "--unit", "m"]),
    ]
    return out


def run_evo(evo_bin, cmd, fmt, ref, est, tmp):
    res = os.path.join(tmp, "res.zip")
    if os.path.exists(res):
        os.remove(res)
    args = [os.path.join(evo_bin, cmd[0]), fmt, ref, est, *cmd[1:], "--save_results", res, "--no_warnings"]
    if fmt != "kitti":
        args += ["--t_max_diff", MAX_DIFF]
    subprocess.run(args, check=True, capture_output=True, text=True)
    result = file_interface.load_res_file(res)
    stats = {k: float(result.stats[k]) for k in STATS}
    stats["pairs"] = len(result.np_arrays["error_array"])
    return stats


def rigid_kitti_copy(path, tmp):
    """The KITTI file with each rotation replaced by its nearest rotation (polar factor)."""
    poses = []
    for pose in file_interface.read_kitti_poses_file(path).poses_se3:
        u, _, vt = np.linalg.svd(pose[:3, :3])
        rigid = pose.copy()
        rigid[:3, :3] = u @ vt
        poses.append(rigid)
    out = os.path.join(tmp, "rigid_" + os.path.basename(path))
    file_interface.write_kitti_poses_file(out, PosePath3D(poses_se3=poses))
    return out


def run_slamkit(slamkit, cmd, ref, est):
    args = [slamkit, "eval", *cmd, "--gt", ref, "--est", est, "--max-diff", MAX_DIFF, "--json"]
    out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", required=True)
    parser.add_argument("--slamkit", required=True)
    parser.add_argument("--evo-bin", required=True)
    args = parser.parse_args()

    import evo
    print(f"evo {evo.__version__.lstrip('v')}; tolerance {TOLERANCE:g}; max time diff {MAX_DIFF} s")
    print()
    header = (f"| {'pair':<16} | {'metric':<12} | {'stat':<6} | {'evo':>14} | {'slamkit':>14} "
              f"| {'abs diff':>9} | {'evo rigid':>14} | {'diff rigid':>10} |")
    print(header)
    print("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|")
    worst_raw, worst, failures = 0.0, 0.0, []
    with tempfile.TemporaryDirectory() as tmp:
        for name, fmt, ref, est, sim3, delta_m in PAIRS:
            ref_path, est_path = os.path.join(args.data, ref), os.path.join(args.data, est)
            rigid = None
            if fmt == "kitti":
                rigid = (rigid_kitti_copy(ref_path, tmp), rigid_kitti_copy(est_path, tmp))
            for label, evo_cmd, sk_cmd in cases(delta_m, sim3):
                evo_stats = run_evo(args.evo_bin, evo_cmd, fmt, ref_path, est_path, tmp)
                rigid_stats = run_evo(args.evo_bin, evo_cmd, fmt, *rigid, tmp) if rigid else evo_stats
                sk_stats = run_slamkit(args.slamkit, sk_cmd, ref_path, est_path)
                for key in STATS + ["pairs"]:
                    a, r, b = evo_stats[key], rigid_stats[key], sk_stats[key]
                    diff_raw, diff = abs(a - b), abs(r - b)
                    if key == "pairs":
                        bad = a != b or r != b
                        fa, fr, fb = f"{a:>14d}", f"{r:>14d}" if rigid else "", f"{b:>14d}"
                    else:
                        bad = diff > TOLERANCE
                        worst_raw, worst = max(worst_raw, diff_raw), max(worst, diff)
                        fa, fr, fb = f"{a:>14.9f}", f"{r:>14.9f}" if rigid else "", f"{b:>14.9f}"
                    if bad:
                        failures.append(f"{name} {label} {key}: evo {r} slamkit {b}")
                    fd = f"{diff:>10.2e}" if rigid else ""
                    mark = " !" if bad else ""
                    print(f"| {name:<16} | {label:<12} | {key:<6} | {fa} | {fb} | {diff_raw:>9.2e} "
                          f"| {fr:>14} | {fd:>10} |{mark}")
    print()
    print(f"largest absolute difference to evo on the raw files:          {worst_raw:.3e}")
    print(f"largest absolute difference to evo on the same (rigid) poses: {worst:.3e}")
    if failures:
        print(f"{len(failures)} values differ by more than {TOLERANCE:g}:")
        for f in failures:
            print("  " + f)
        return 1
    print("all values agree within the tolerance")
    return 0


if __name__ == "__main__":
    sys.exit(main())
