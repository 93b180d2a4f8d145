#!/usr/bin/env python3
"""Where a 2D SLAM run's relations error is made: each benchmark relation (Kümmerle et al. 2009)
scored against a TUM trajectory, then summed per time bin of its first pose, with the place
(x, y of the estimate) and the relations spanning more than LONG seconds apart (loop closures)
listed by error. The mean over all relations equals `slamkit eval relations` to rounding (the
translational error of `delta_est ⊖ delta_gt`, poses taken at the nearest timestamp).

usage: scripts/relations_by_time.py RELATIONS TRAJECTORY.tum [--bin 50] [--long 5] [--top 15]
"""
import argparse
import bisect
import math


def read_tum(path):
    stamps, poses = [], []
    for line in open(path):
        if not line.strip() or line.startswith("#"):
            continue
        t, x, y, _z, qx, qy, qz, qw = map(float, line.split()[:8])
        yaw = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
        stamps.append(t)
        poses.append((x, y, yaw))
    return stamps, poses


def nearest(stamps, t):
    i = bisect.bisect_left(stamps, t)
    best = min((j for j in (i - 1, i) if 0 <= j < len(stamps)), key=lambda j: abs(stamps[j] - t))
    return best


def relative(a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    c, s = math.cos(a[2]), math.sin(a[2])
    return (c * dx + s * dy, -s * dx + c * dy, b[2] - a[2])


def main():
    p = argparse.ArgumentParser()
    p.add_argument("relations")
    p.add_argument("trajectory")
    p.add_argument("--bin", type=float, default=50.0)
    p.add_argument("--long", type=float, default=5.0)
    p.add_argument("--top", type=int, default=15)
    a = p.parse_args()
    stamps, poses = read_tum(a.trajectory)
    rows = []
    for line in open(a.relations):
        f = line.split()
        if len(f) < 8:
            continue
        t1, t2, gx, gy, _z, _r, _p, gyaw = map(float, f[:8])
        p1, p2 = poses[nearest(stamps, t1)], poses[nearest(stamps, t2)]
        ex, ey, _ = relative(p1, p2)
        # delta_gt^-1 * delta_est, translational part
        c, s = math.cos(gyaw), math.sin(gyaw)
        dx, dy = ex - gx, ey - gy
        err = math.hypot(c * dx + s * dy, -s * dx + c * dy)
        rows.append((t1, t2, err, p1[0], p1[1]))
    total = sum(r[2] for r in rows)
    print(f"{len(rows)} relations, mean {total / len(rows):.4f} m")
    long_rows = [r for r in rows if r[1] - r[0] > a.long]
    if long_rows:
        print(f"{len(long_rows)} spanning > {a.long} s: mean {sum(r[2] for r in long_rows) / len(long_rows):.4f} m, "
              f"their share of the total error {sum(r[2] for r in long_rows) / total:.0%}")
    t0 = min(r[0] for r in rows)
    bins = {}
    for r in rows:
        k = int((r[0] - t0) // a.bin)
        bins.setdefault(k, []).append(r)
    print(f"\nper {a.bin:.0f} s of the first pose (t from {t0:.1f}): relations, mean, share of total, place")
    for k in sorted(bins):
        b = bins[k]
        s = sum(r[2] for r in b)
        x = sum(r[3] for r in b) / len(b)
        y = sum(r[4] for r in b) / len(b)
        print(f"  {k * a.bin:7.0f} s  {len(b):4d}  {s / len(b):.4f} m  {s / total:5.1%}  ({x:6.1f}, {y:6.1f})")
    print(f"\nlargest errors (t1, t2, error, place of t1):")
    for r in sorted(rows, key=lambda r: -r[2])[: a.top]:
        print(f"  {r[0]:.1f} {r[1]:.1f}  {r[2]:.3f} m  ({r[3]:.1f}, {r[4]:.1f})")


if __name__ == "__main__":
    main()
