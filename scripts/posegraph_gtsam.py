#!/usr/bin/env python3
"""Optimise a g2o SE(3) pose graph with GTSAM's Levenberg-Marquardt and print one JSON object:
initial and final cost, iterations and the wall time of each optimisation.

The problem is the one slamkit's `vo::pose_graph` solves: one BetweenFactorPose3 per
EDGE_SE3:QUAT (error Logmap(Z^-1 T_i^-1 T_j); GTSAM's Pose3 chart is the exponential map,
checked below), Gaussian noise with the edge's information matrix, reordered from g2o's
(translation, rotation) to GTSAM's (rotation, translation) tangent order; the first vertex (or
the FIX ones) held by a prior with information 1e12 at its initial pose (its cost is reported
apart and stays ~0: the gauge leaves it free to be met exactly). Costs are 0.5 * sum e' Omega e
over the edges. LM parameters are GTSAM's defaults (relative and absolute tolerance 1e-5, as
slamkit's LmConfig). The timed part builds the optimiser (which orders the variables, COLAMD)
and runs it; reading the file is not timed.

usage: posegraph_gtsam.py FILE.g2o [REPEATS]
"""
import json
import sys
import time

import gtsam
from importlib.metadata import version
import numpy as np


def read_g2o(path):
    """Vertices {id: Pose3}, edges [(i, j, Pose3, information 6x6 in g2o order)], fixed ids."""
    vertices, edges, fixed = {}, [], []
    with open(path) as f:
        for number, line in enumerate(f, 1):
            tok = line.split()
            if not tok or tok[0].startswith("#"):
                continue
            if tok[0] == "VERTEX_SE3:QUAT" and len(tok) == 9:
                vertices[int(tok[1])] = pose(tok[2:9])
            elif tok[0] == "EDGE_SE3:QUAT" and len(tok) == 31:
                upper = [float(v) for v in tok[10:31]]
                info = np.zeros((6, 6))
                info[np.triu_indices(6)] = upper
                info = info + np.triu(info, 1).T
                edges.append((int(tok[1]), int(tok[2]), pose(tok[3:10]), info))
            elif tok[0] == "FIX":
                fixed += [int(t) for t in tok[1:]]
            else:
                sys.exit(f"{path}:{number}: unsupported line")
    return vertices, edges, fixed or [next(iter(vertices))]


def pose(values):
    x, y, z, qx, qy, qz, qw = (float(v) for v in values)
    # g2o normalises quaternions on reading (so does slamkit); Rot3.Quaternion would not.
    n = np.linalg.norm([qw, qx, qy, qz])
    qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
    return gtsam.Pose3(gtsam.Rot3.Quaternion(qw, qx, qy, qz), gtsam.Point3(x, y, z))


def build(vertices, edges, fixed):
    graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
    for key, p in vertices.items():
        initial.insert(key, p)
    order = [3, 4, 5, 0, 1, 2]  # g2o (t, R) -> GTSAM (R, t)
    for i, j, z, info in edges:
        noise = gtsam.noiseModel.Gaussian.Information(info[np.ix_(order, order)])
        graph.add(gtsam.BetweenFactorPose3(i, j, z, noise))
    priors = gtsam.NonlinearFactorGraph()
    for key in fixed:
        priors.add(gtsam.PriorFactorPose3(key, vertices[key], gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    return graph, priors, initial


def main():
    path = sys.argv[1]
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    # The same chart as slamkit: localCoordinates is the exact SE(3) logarithm.
    p = gtsam.Pose3(gtsam.Rot3.Rodrigues(0.3, -0.2, 0.5), gtsam.Point3(1, 2, 3))
    assert np.allclose(gtsam.Pose3().localCoordinates(p), gtsam.Pose3.Logmap(p))
    vertices, edges, fixed = read_g2o(path)
    times, result, iterations = [], None, 0
    for _ in range(max(repeats, 1)):
        graph, priors, initial = build(vertices, edges, fixed)
        full = gtsam.NonlinearFactorGraph(graph)
        full.push_back(priors)
        start = time.perf_counter()
        optimizer = gtsam.LevenbergMarquardtOptimizer(full, initial, gtsam.LevenbergMarquardtParams())
        result = optimizer.optimize()
        times.append(time.perf_counter() - start)
        iterations = optimizer.iterations()
    print(json.dumps({
        "optimiser": "gtsam " + version("gtsam"),
        "vertices": len(vertices),
        "edges": len(edges),
        "initial_cost": graph.error(initial),
        "final_cost": graph.error(result),
        "final_prior_cost": priors.error(result),
        "iterations": iterations,
        "times_s": [round(t, 6) for t in times],
        "median_s": round(sorted(times)[len(times) // 2], 6),
    }))


if __name__ == "__main__":
    main()
