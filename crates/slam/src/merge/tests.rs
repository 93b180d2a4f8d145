use super::pcm::{max_clique, select, PcmConfig};
use super::*;
use crate::lidar::{MapKeyframe, MapScan};
use nalgebra::{Point2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slamkit_lidar::pose_graph::Edge;
use slamkit_lidar::sim_scan::SegmentWorld;

/// A map of `world` made by a robot that drove through `world_path` (world frame) and put its
/// map frame where it started: keyframes every pose, consecutive edges, one scan per keyframe.
fn map_along(world: &SegmentWorld, world_path: &[Pose2], t0: f64) -> LidarMap {
    let start_from_world = world_path[0].inverse();
    let config = crate::LidarSlamConfig::default().icp.loop_closure;
    let mut map = LidarMap::default();
    for (i, world_from_base) in world_path.iter().enumerate() {
        let pose = start_from_world * world_from_base;
        let mut scan = world.scan(world_from_base, 361, 4.7, 20.0);
        scan.timestamp = t0 + i as f64;
        if let Some(last) = map.keyframes.last() {
            map.edges.push(Edge {
                from: i - 1,
                to: i,
                from_from_to: last.world_from_base.inverse() * pose,
                information: config.edge_information(),
                robust_scale: None,
            });
        }
        map.keyframes.push(MapKeyframe {
            world_from_base: pose,
            scan,
        });
        map.scans.push(MapScan {
            timestamp: t0 + i as f64,
            keyframe: Some(i),
            keyframe_from_base: Pose2::identity(),
        });
    }
    map
}

/// Poses from `(x0, y0)` to `(x1, y1)`, `n` of them, heading `theta`.
fn line(from: (f64, f64), to: (f64, f64), n: usize, theta: f64) -> Vec<Pose2> {
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1) as f64;
            let p = Vector2::new(from.0 + s * (to.0 - from.0), from.1 + s * (to.1 - from.1));
            Pose2::new(p, theta + 0.05 * (i as f64).sin())
        })
        .collect()
}

/// Settings for the small synthetic room: queries a metre apart, so a few metres of path hold
/// enough of them for the consistency check.
fn small_world_config() -> MergeConfig {
    let mut config = MergeConfig::default();
    config.places.spacing_m = 1.0;
    config.places.half_keyframes = 3;
    config.verify.half_keyframes = 3;
    config
}

#[test]
fn two_maps_with_a_known_offset_are_merged_at_it_and_a_stranger_is_left_out() {
    // the test room with more furniture: the bare room seen from its far side looks much
    // like itself turned half a turn, and a merge then (rightly) finds two stories
    let mut room = SegmentWorld::room();
    for corners in [
        [(3.5, 2.6), (4.3, 2.6), (4.3, 3.3), (3.5, 3.3)],
        [(-4.2, -4.0), (-4.0, -4.0), (-4.0, -2.8), (-4.2, -2.8)],
        [(-0.5, 3.0), (0.5, 3.0), (0.5, 4.0), (-0.5, 4.0)],
    ] {
        room.segments
            .extend(SegmentWorld::polygon(&corners).segments);
    }
    // robot A goes left to right along y = -2, robot B right to left along y = 2.2 then down;
    // both see the whole room, and each map is in its own start frame
    let path_a = line((-4.5, -2.0), (3.5, -2.2), 16, 0.1);
    let mut path_b = line((4.0, 2.2), (-4.0, 2.5), 16, 3.0);
    path_b.extend(line((-4.5, 2.0), (-4.5, -2.0), 8, -1.6));
    let a = map_along(&room, &path_a, 0.0);
    let b = map_along(&room, &path_b, 100.0);
    let a_from_b = path_a[0].inverse() * path_b[0];
    // C: a corridor elsewhere with an alcove, never seen by A or B
    let corridor = SegmentWorld::polygon(&[
        (0.0, 0.0),
        (20.0, 0.0),
        (20.0, 1.5),
        (9.0, 1.5),
        (9.0, 4.0),
        (7.0, 4.0),
        (7.0, 1.5),
        (0.0, 1.5),
    ]);
    let c = map_along(&corridor, &line((1.0, 0.7), (15.0, 0.8), 20, 0.0), 200.0);
    let outcome = merge_maps(&[a, b, c], &small_world_config()).unwrap();

    assert_eq!(outcome.unmerged(), [2], "{:?}", outcome.stats);
    let frame = outcome.inputs[1].merged_from_input.unwrap();
    let err = a_from_b.inverse() * frame;
    assert!(err.translation.vector.norm() < 0.02, "{err:?}");
    assert!(err.rotation.angle().abs() < 0.5f64.to_radians(), "{err:?}");
    assert_eq!(outcome.inputs[0].merged_from_input, Some(Pose2::identity()));
    // every keyframe of B lands where it was in A's frame
    let trajectory = outcome.inputs[1].trajectory.as_ref().unwrap();
    assert_eq!(trajectory.len(), path_b.len());
    for (stamped, truth) in trajectory.poses.iter().zip(&path_b) {
        let truth = path_a[0].inverse() * truth;
        let got = slamkit_core::pose::pose3_to_pose2(&stamped.pose);
        assert!((got.translation.vector - truth.translation.vector).norm() < 0.03);
    }
    // no closure joins C, and every accepted closure is right
    assert!(outcome.stats.accepted >= 3, "{:?}", outcome.stats);
    for cl in &outcome.closures {
        if cl.status != ClosureStatus::Accepted {
            continue;
        }
        assert!(cl.from_map != 2 && cl.to_map != 2);
        let truth = path_a[cl.from_keyframe].inverse() * path_b[cl.to_keyframe];
        let e = truth.inverse() * cl.from_from_to;
        assert!(e.translation.vector.norm() < 0.05, "{cl:?}");
    }
    // the merged map holds A's and B's keyframes and scans, with the accepted closures as edges
    assert_eq!(outcome.map.keyframes.len(), 16 + 24);
    assert_eq!(outcome.map.scans.len(), 16 + 24);
    assert_eq!(outcome.map.edges.len(), 15 + 23 + outcome.stats.accepted);
    assert!(outcome.optimisation.is_some());
}

#[test]
fn a_merge_needs_two_maps_with_keyframes() {
    let room = SegmentWorld::room();
    let a = map_along(&room, &line((0.0, 0.0), (1.0, 0.0), 3, 0.0), 0.0);
    let err = merge_maps(&[a.clone(), LidarMap::default()], &MergeConfig::default()).unwrap_err();
    assert!(err.to_string().contains("map 2 holds no keyframe"), "{err}");
    let err = merge_maps(&[a], &MergeConfig::default()).unwrap_err();
    assert!(err.to_string().contains("at least two"), "{err}");
    let mut bad = MergeConfig::default();
    bad.pcm.min_consistent = 0;
    let err = merge_maps(&[], &bad).unwrap_err();
    assert!(err.to_string().contains("pcm"), "{err}");
}

/// Keyframes at `poses` (no points: the consistency check reads only poses).
fn keyframes_at(poses: &[Pose2]) -> Vec<slamkit_lidar::point_map::Keyframe> {
    poses
        .iter()
        .map(|p| slamkit_lidar::point_map::Keyframe {
            world_from_base: *p,
            points: Vec::new(),
            normals: Vec::new(),
        })
        .collect()
}

#[test]
fn pcm_rejects_a_planted_wrong_closure_and_joins_only_on_enough_agreement() {
    // two maps of one corridor, B's frame 10 m along and turned by 90° in A's
    let a_from_b = Pose2::new(Vector2::new(10.0, -3.0), std::f64::consts::FRAC_PI_2);
    let a_poses: Vec<Pose2> = (0..20)
        .map(|i| Pose2::new(Vector2::new(i as f64, 0.0), 0.0))
        .collect();
    let b_poses: Vec<Pose2> = a_poses.iter().map(|p| a_from_b.inverse() * p).collect();
    let keyframes = vec![keyframes_at(&a_poses), keyframes_at(&b_poses)];
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let closure = |from: usize, to: usize, wrong: Pose2, rng: &mut ChaCha8Rng| {
        // the true relative pose with centimetre noise, times `wrong`
        let noise = Pose2::new(
            Vector2::new(rng.gen_range(-0.02..0.02), rng.gen_range(-0.02..0.02)),
            rng.gen_range(-0.005..0.005),
        );
        InterClosure {
            from_map: 0,
            from_keyframe: from,
            to_map: 1,
            to_keyframe: to,
            from_from_to: a_poses[from].inverse() * a_from_b * b_poses[to] * noise * wrong,
            goodness: 0.9,
            reverse_goodness: Some(0.9),
            free_space_conflict: None,
            status: ClosureStatus::Inconsistent,
        }
    };
    let right = Pose2::identity();
    let mut closures: Vec<InterClosure> = [(0, 1), (3, 3), (6, 7), (10, 9), (15, 16), (19, 18)]
        .iter()
        .map(|&(f, t)| closure(f, t, right, &mut rng))
        .collect();
    // a corridor's aliasing: the match slid 2 m along it
    closures.insert(
        3,
        closure(8, 8, Pose2::new(Vector2::new(2.0, 0.0), 0.0), &mut rng),
    );
    let config = PcmConfig::default();
    let links = select(&keyframes, &mut closures, &config);
    let statuses: Vec<ClosureStatus> = closures.iter().map(|c| c.status).collect();
    use ClosureStatus::{Accepted, Inconsistent};
    assert_eq!(
        statuses,
        [
            Accepted,
            Accepted,
            Accepted,
            Inconsistent,
            Accepted,
            Accepted,
            Accepted
        ]
    );
    assert_eq!(links.len(), 1);
    let err = a_from_b.inverse() * links[0].from_from_to_frame;
    assert!(err.translation.vector.norm() < 0.1, "{err:?}");

    // two right closures and two wrong ones that disagree: too few to join
    let mut few = vec![
        closure(0, 1, right, &mut rng),
        closure(5, 5, right, &mut rng),
        closure(9, 9, Pose2::new(Vector2::new(0.0, 1.5), 0.3), &mut rng),
        closure(12, 12, Pose2::new(Vector2::new(3.0, 0.0), -0.4), &mut rng),
    ];
    assert!(select(&keyframes, &mut few, &config).is_empty());
    assert_eq!(few[0].status, ClosureStatus::TooFewConsistent);
    assert_eq!(few[2].status, ClosureStatus::Inconsistent);

    // four right closures and three that agree on another frame: two stories, no join
    let other = Pose2::new(Vector2::new(0.0, 4.0), 3.0);
    let mut two_stories: Vec<InterClosure> = [(0, 1), (4, 4), (8, 8), (12, 12)]
        .iter()
        .map(|&(f, t)| closure(f, t, right, &mut rng))
        .collect();
    for k in [2, 6, 10] {
        let mut c = closure(k, k, right, &mut rng);
        // the querying keyframe seen at the place `other` moves it to, in A's frame
        c.from_from_to = a_poses[k].inverse() * other * a_from_b * b_poses[k];
        two_stories.push(c);
    }
    assert!(select(&keyframes, &mut two_stories, &config).is_empty());
    assert!(two_stories[..4]
        .iter()
        .all(|c| c.status == ClosureStatus::Ambiguous));

    // found both ways (with `places.both_ways`): two closures from A's queries searched in B,
    // stated from B to A, and one the usual way meet in one consistent set of three and place
    // B where the usual three do; two of each direction alone would be too few
    let mut both_ways: Vec<InterClosure> = [(0, 1), (8, 8), (15, 16)]
        .iter()
        .map(|&(f, t)| closure(f, t, right, &mut rng))
        .collect();
    for c in &mut both_ways[1..] {
        *c = InterClosure {
            from_map: 1,
            from_keyframe: c.to_keyframe,
            to_map: 0,
            to_keyframe: c.from_keyframe,
            from_from_to: c.from_from_to.inverse(),
            ..*c
        };
    }
    let links = select(&keyframes, &mut both_ways, &config);
    assert!(
        both_ways.iter().all(|c| c.status == Accepted),
        "{both_ways:?}"
    );
    assert_eq!((links.len(), links[0].from_map, links[0].to_map), (1, 0, 1));
    let err = a_from_b.inverse() * links[0].from_from_to_frame;
    assert!(err.translation.vector.norm() < 0.1, "{err:?}");
}

#[test]
fn max_clique_matches_brute_force_on_random_graphs() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for trial in 0..40 {
        let n = rng.gen_range(1..13);
        let density = rng.gen_range(0.1..0.9);
        let mut adj = vec![vec![false; n]; n];
        let pairs: Vec<(usize, usize)> = (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .collect();
        for (i, j) in pairs {
            let e = rng.gen_bool(density);
            adj[i][j] = e;
            adj[j][i] = e;
        }
        let weights: Vec<f64> = (0..n).map(|_| rng.gen_range(0.0..1.0)).collect();
        let mut best = (0usize, f64::NEG_INFINITY);
        for mask in 1u32..(1 << n) {
            let members: Vec<usize> = (0..n).filter(|&i| mask & (1 << i) != 0).collect();
            let clique = members
                .iter()
                .all(|&a| members.iter().all(|&b| a == b || adj[a][b]));
            let w: f64 = members.iter().map(|&i| weights[i]).sum();
            if clique && (members.len() > best.0 || (members.len() == best.0 && w > best.1)) {
                best = (members.len(), w);
            }
        }
        let got = max_clique(&adj, &weights);
        let w: f64 = got.iter().map(|&i| weights[i]).sum();
        assert!(
            got.iter()
                .all(|&a| got.iter().all(|&b| a == b || adj[a][b])),
            "trial {trial}: not a clique"
        );
        assert_eq!(got.len(), best.0, "trial {trial}");
        assert!(
            (w - best.1).abs() < 1e-12,
            "trial {trial}: weight {w} vs {}",
            best.1
        );
    }
    assert!(max_clique(&[], &[]).is_empty());
}

#[test]
fn submap_points_are_in_the_centre_keyframes_frame() {
    let kfs = vec![
        slamkit_lidar::point_map::Keyframe {
            world_from_base: Pose2::new(Vector2::new(1.0, 0.0), 0.0),
            points: vec![Point2::new(1.0, 0.0)],
            normals: vec![None],
        },
        slamkit_lidar::point_map::Keyframe {
            world_from_base: Pose2::new(Vector2::new(2.0, 0.0), std::f64::consts::FRAC_PI_2),
            points: vec![Point2::new(1.0, 0.0)],
            normals: vec![None],
        },
    ];
    let points = submap_points(&kfs, 1, 5);
    // keyframe 0's point is at world (2, 0): in keyframe 1's frame, the origin
    assert!((points[0] - Point2::new(0.0, 0.0)).norm() < 1e-12);
    assert!((points[1] - Point2::new(1.0, 0.0)).norm() < 1e-12);
    assert!(submap_points(&kfs, 7, 1).is_empty());
}

#[test]
fn a_corridor_seen_the_other_way_round_conflicts_with_free_space_and_the_true_story_does_not() {
    use super::free_space::{conflict, FreeSpaceConfig, FreeSpaceMap};
    // a corridor 14 m long, closed at x = 0, opening into a room at x = 14; its walls fit
    // themselves turned half a turn about the corridor's middle, the two ends do not
    let world = SegmentWorld::polygon(&[
        (0.0, 0.0),
        (14.0, 0.0),
        (14.0, -3.0),
        (20.0, -3.0),
        (20.0, 4.5),
        (14.0, 4.5),
        (14.0, 1.5),
        (0.0, 1.5),
    ]);
    // A drives in from the room and back, B out of the closed end and back (the scans see
    // 270°, so each end is seen on the way towards it); each map in its start frame
    let pi = std::f64::consts::PI;
    let mut path_a = line((17.0, 0.7), (1.0, 0.8), 30, pi);
    path_a.extend(line((1.5, 0.8), (17.0, 0.7), 30, 0.0));
    let mut path_b = line((1.0, 0.75), (17.0, 0.75), 30, 0.0);
    path_b.extend(line((16.5, 0.7), (1.0, 0.7), 30, pi));
    let (a, b) = (
        map_along(&world, &path_a, 0.0),
        map_along(&world, &path_b, 100.0),
    );
    let config = FreeSpaceConfig {
        max_conflict: 0.05,
        ..FreeSpaceConfig::default()
    };
    let icp = MergeConfig::default().icp;
    let b_keyframes = b.matcher_keyframes(&icp);
    let a_grid = FreeSpaceMap::new(&a, &config).unwrap();
    let a_from_b_true = path_a[0].inverse() * path_b[0];
    // the reversed story: B's corridor turned half a turn about its middle (7, 0.75)
    let middle = Pose2::new(Vector2::new(7.0, 0.75), 0.0);
    let turn = middle * Pose2::new(Vector2::zeros(), std::f64::consts::PI) * middle.inverse();
    let a_from_b_reversed = path_a[0].inverse() * turn * path_b[0];
    // B's keyframe 12 is in the corridor, about x = 7.6
    let right = conflict(&b_keyframes, 12, &a_from_b_true, &a_grid, config.radius_m);
    let wrong = conflict(
        &b_keyframes,
        12,
        &a_from_b_reversed,
        &a_grid,
        config.radius_m,
    );
    assert!(right.known >= config.min_points, "{right:?}");
    assert_eq!(right.free, 0, "{right:?}");
    // only the two end walls tell (a few per cent of the points here; real corridors have
    // doors, rooms and clutter that tell more: BENCHMARKS.md)
    assert!(wrong.known >= config.min_points, "{wrong:?}");
    assert!(wrong.fraction() > 0.01, "{wrong:?}");
    // a map far away in a frame of its own lands nowhere known: nothing to judge
    let away = Pose2::new(Vector2::new(500.0, 0.0), 0.0);
    let nowhere = conflict(&b_keyframes, 12, &away, &a_grid, config.radius_m);
    assert_eq!(nowhere.known, 0);
}
