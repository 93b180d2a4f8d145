#!/usr/bin/env python3
"""Times slamkit-vision's front-end kernels against OpenCV's on the same images, single thread.

Kernels and settings (both sides):
  CLAHE       clip 2.0, 8x8 tiles, on grey and on RGB (via 8-bit Lab, L channel)
  Shi-Tomasi  500 corners, quality 0.01, min distance 10 px, 3x3 block (no grid bucketing)
  KLT         the Shi-Tomasi corners tracked into the next frame and back (forward-backward),
              21x21 window, max level 3, pyramids built from the grey images inside the timing
  ORB         500 features, scale 1.2, 8 levels, FAST 20, Harris ranking, descriptors

Data: 7-Scenes RedKitchen frames 0-9 (640x480 RGB) and KITTI 06 image_0 frames 0-9 (1226x370 grey)
from $SLAMKIT_DATA. OpenCV comes from opencv-python-headless, installed by this script into a
virtualenv (default target/opencv-venv; override with SLAMKIT_OPENCV_VENV). Prints a Markdown
table of medians (ms) and ratios slamkit / OpenCV (< 1 means slamkit is faster).

Usage: SLAMKIT_DATA=/path/to/data scripts/bench_vision_vs_opencv.py [--reps N] [--frames N]
"""
import argparse
import json
import os
import statistics
import subprocess
import time
from pathlib import Path

from bench_common import ROOT, build_example, ensure_venv

VENV = Path(os.environ.get("SLAMKIT_OPENCV_VENV", ROOT / "target" / "opencv-venv"))


def median_ms(reps, fn):
    """Median CPU time of the calling thread over `reps` runs [ms] (OpenCV runs single-threaded
    in this thread, so other processes on a shared machine do not count)."""
    times = []
    for _ in range(reps):
        t0 = time.thread_time_ns()
        fn()
        times.append((time.thread_time_ns() - t0) * 1e-6)
    return statistics.median(times)


def opencv_times(paths, reps):
    import cv2
    import numpy as np

    cv2.setNumThreads(1)
    rgbs = [cv2.cvtColor(cv2.imread(str(p), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB) for p in paths]
    grays = [cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in rgbs]
    clahe = cv2.createCLAHE(clipLimit=2.0, tileGridSize=(8, 8))
    orb = cv2.ORB_create(500)
    lk = dict(winSize=(21, 21), maxLevel=3,
              criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01))

    def clahe_rgb(im):
        lab = cv2.cvtColor(im, cv2.COLOR_RGB2Lab)
        lab[:, :, 0] = clahe.apply(lab[:, :, 0])
        return cv2.cvtColor(lab, cv2.COLOR_Lab2RGB)

    def gftt(g):
        return cv2.goodFeaturesToTrack(g, 500, 0.01, 10, blockSize=3)

    def klt_fb(a, b, pts):
        fwd, st1, _ = cv2.calcOpticalFlowPyrLK(a, b, pts, None, **lk)
        bwd, st2, _ = cv2.calcOpticalFlowPyrLK(b, a, fwd, None, **lk)
        err = np.linalg.norm((bwd - pts).reshape(-1, 2), axis=1)
        return int(((st1.ravel() == 1) & (st2.ravel() == 1) & (err <= 1.0)).sum())

    t = {k: [] for k in ["rgb_to_gray", "clahe_gray", "clahe_rgb", "shi_tomasi", "klt_fb", "orb"]}
    counts = {"shi_tomasi_corners": [], "klt_tracked": [], "orb_keypoints": []}
    for i, (rgb, g) in enumerate(zip(rgbs, grays)):
        t["rgb_to_gray"].append(median_ms(reps, lambda: cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)))
        t["clahe_gray"].append(median_ms(reps, lambda: clahe.apply(g)))
        t["clahe_rgb"].append(median_ms(reps, lambda: clahe_rgb(rgb)))
        t["shi_tomasi"].append(median_ms(reps, lambda: gftt(g)))
        pts = gftt(g)
        counts["shi_tomasi_corners"].append(len(pts))
        t["orb"].append(median_ms(reps, lambda: orb.detectAndCompute(g, None)))
        counts["orb_keypoints"].append(len(orb.detectAndCompute(g, None)[0]))
        if i + 1 < len(grays):
            nxt = grays[i + 1]
            t["klt_fb"].append(median_ms(reps, lambda: klt_fb(g, nxt, pts)))
            counts["klt_tracked"].append(klt_fb(g, nxt, pts))
    return ({k: statistics.median(v) for k, v in t.items()},
            {k: statistics.median(v) for k, v in counts.items()}, cv2.__version__)


def slamkit_times(paths, reps):
    exe = build_example("slamkit-vision", "kernel_timing")
    out = subprocess.run([str(exe), "--reps", str(reps), *map(str, paths)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def main():
    ensure_venv(VENV, ["opencv-python-headless", "numpy"], __file__)
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=15)
    ap.add_argument("--frames", type=int, default=10)
    args = ap.parse_args()
    data = Path(os.environ.get("SLAMKIT_DATA", ROOT.parent / "shared" / "data"))
    sets = {
        "7-Scenes 640x480 RGB": [data / "rgbd/7scenes_redkitchen_frames_0000-0599" /
                                 f"frame-{i:06d}.color.jpg" for i in range(args.frames)],
        "KITTI 06 1226x370 grey": [data / "stereo/kitti_odometry_06_0000-0050/image_0" /
                                   f"{i:06d}.png" for i in range(args.frames)],
    }
    rows = [("rgb_to_gray", "RGB to grey"), ("clahe_gray", "CLAHE grey"),
            ("clahe_rgb", "CLAHE RGB (Lab L)"), ("shi_tomasi", "Shi-Tomasi 500"),
            ("klt_fb", "KLT fwd+bwd"), ("orb", "ORB 500")]
    import cv2  # noqa: F401  (inside the venv now)
    print(f"single thread; median over {args.frames} frames of the median of {args.reps} runs")
    for name, paths in sets.items():
        cv_ms, cv_n, version = opencv_times(paths, args.reps)
        sk = slamkit_times(paths, args.reps)
        print(f"\n### {name} (OpenCV {version})\n")
        print("| kernel | slamkit ms | OpenCV ms | ratio |")
        print("|---|---:|---:|---:|")
        for key, label in rows:
            a, b = sk["ms"][key], cv_ms[key]
            print(f"| {label} | {a:.3f} | {b:.3f} | {a / b:.2f} |")
        print("\ncounts (slamkit / OpenCV): " + ", ".join(
            f"{k} {sk['counts'][k]:.0f} / {cv_n[k]:.0f}" for k in cv_n))


if __name__ == "__main__":
    main()
