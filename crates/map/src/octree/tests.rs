use super::bt::{bt_bytes, parse_bt};
use super::key::{ray_keys, OctreeKey};
use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::{HashMap, HashSet};
use std::path::Path;

fn tree(resolution_m: f64) -> Octree {
    Octree::new(OctreeConfig {
        resolution_m,
        ..OctreeConfig::default()
    })
    .unwrap()
}

/// Slow reference: OctoMap's computeUpdate and updateNode on a flat map of finest voxels.
fn reference_insert(
    cells: &mut HashMap<OctreeKey, f32>,
    tree: &Octree,
    points: &[Point3<f64>],
    origin: &Point3<f64>,
) {
    let (mut free, mut occupied) = (HashSet::new(), HashSet::new());
    let o = origin.coords.map(|c| c as f32);
    for p in points {
        let e = p.coords.map(|c| c as f32);
        if ray_keys(o.into(), e.into(), tree.resolution_m(), |k| {
            free.insert(k);
        }) {
            if let Some(k) = tree.key_at(&e.cast::<f64>().into()) {
                occupied.insert(k);
            }
        }
    }
    let (l_min, l_max) = tree.log_odds_limits();
    for (keys, step) in [(&free, tree.l_miss), (&occupied, tree.l_hit)] {
        for k in keys {
            if keys == &free && occupied.contains(k) {
                continue;
            }
            let v = cells.entry(*k).or_insert(0.0);
            *v = (*v + step).clamp(l_min, l_max);
        }
    }
}

fn random_cloud(rng: &mut ChaCha8Rng, n: usize, half_m: f64) -> Vec<Point3<f64>> {
    (0..n)
        .map(|_| {
            Point3::new(
                rng.gen_range(-half_m..half_m),
                rng.gen_range(-half_m..half_m),
                rng.gen_range(-half_m / 3.0..half_m / 3.0),
            )
        })
        .collect()
}

#[test]
fn matches_the_slow_reference_voxel_by_voxel() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut t = tree(0.1);
    let mut cells = HashMap::new();
    for i in 0..6 {
        let origin = Point3::new(0.1 * f64::from(i), -0.05, 0.02);
        let cloud = random_cloud(&mut rng, 400, 1.2);
        t.insert_cloud(&cloud, &origin).unwrap();
        reference_insert(&mut cells, &t, &cloud, &origin);
    }
    assert!(cells.len() > 1000);
    for (key, value) in &cells {
        let (got, _) = t.search_key(*key).unwrap();
        assert_eq!(got, *value, "voxel {key:?}");
    }
    // No voxel outside the reference was touched: leaves cover exactly the reference voxels.
    let mut covered = 0usize;
    t.for_each_leaf(|leaf| covered += 1usize << (3 * (16 - leaf.depth)));
    assert_eq!(covered, cells.len());
}

#[test]
fn a_voxel_is_updated_once_per_cloud_and_hits_win() {
    let mut t = tree(0.1);
    let origin = Point3::new(0.05, 0.05, 0.05);
    // Two points in one voxel, and a third ray passing through that voxel.
    let cloud = [
        Point3::new(0.52, 0.05, 0.05),
        Point3::new(0.58, 0.06, 0.04),
        Point3::new(1.05, 0.05, 0.05),
    ];
    let stats = t.insert_cloud(&cloud, &origin).unwrap();
    assert_eq!(stats.hits, 3);
    assert_eq!(t.log_odds_at(&Point3::new(0.55, 0.05, 0.05)), Some(t.l_hit));
    assert_eq!(
        t.log_odds_at(&Point3::new(0.35, 0.05, 0.05)),
        Some(t.l_miss)
    );
    assert_eq!(t.log_odds_at(&origin), Some(t.l_miss));
    assert_eq!(
        t.occupancy_at(&Point3::new(1.05, 0.05, 0.05)),
        Occupancy::Occupied
    );
    assert_eq!(
        t.occupancy_at(&Point3::new(0.75, 0.05, 0.05)),
        Occupancy::Free
    );
    assert_eq!(
        t.occupancy_at(&Point3::new(0.05, 0.55, 0.05)),
        Occupancy::Unknown
    );
    for _ in 0..20 {
        t.insert_cloud(&cloud, &origin).unwrap();
    }
    let (l_min, l_max) = t.log_odds_limits();
    assert_eq!(t.log_odds_at(&Point3::new(0.55, 0.05, 0.05)), Some(l_max));
    assert_eq!(t.log_odds_at(&Point3::new(0.35, 0.05, 0.05)), Some(l_min));
}

#[test]
fn equal_siblings_are_pruned_and_expand_again() {
    let mut t = tree(0.1);
    // The 8 voxels of the cube [0, 0.2)^3 are hit from far below; rays through the cube's near
    // voxels are overridden by their hits.
    let cube: Vec<Point3<f64>> = (0..8)
        .map(|i| {
            let c = |b: i32| 0.05 + 0.1 * f64::from((i >> b) & 1);
            Point3::new(c(0), c(1), c(2))
        })
        .collect();
    let origin = Point3::new(-0.95, -0.95, -0.95);
    t.insert_cloud(&cube, &origin).unwrap();
    let key = t.key_at(&cube[0]).unwrap();
    assert_eq!(
        t.search_key(key),
        Some((t.l_hit, 15)),
        "pruned into one depth-15 leaf"
    );
    // One more hit on a single voxel expands the leaf again.
    t.insert_cloud(&cube[..1], &Point3::new(0.05, 0.05, -0.95))
        .unwrap();
    assert_eq!(t.search_key(key).map(|(_, d)| d), Some(16));
    let before = t.stats();
    assert!(before.nodes > 0 && before.occupied_leaves >= 8);
}

#[test]
fn bad_input_does_not_panic() {
    let mut t = tree(0.05);
    let origin = Point3::origin();
    let stats = t.insert_cloud(&[], &origin).unwrap();
    assert_eq!(stats, OctreeInsertStats::default());
    let cloud = [
        Point3::new(f64::NAN, 0.0, 1.0),
        Point3::new(f64::INFINITY, 0.0, 1.0),
        Point3::new(1e12, 0.0, 1.0),
        Point3::new(0.0, 0.0, 1.0),
        Point3::new(0.0, 0.0, 0.0), // same voxel as the origin
    ];
    let stats = t.insert_cloud(&cloud, &origin).unwrap();
    assert_eq!((stats.hits, stats.ignored), (2, 3));
    assert!(t
        .insert_cloud(&cloud, &Point3::new(f64::NAN, 0.0, 0.0))
        .is_err());
    assert_eq!(
        t.occupancy_at(&Point3::new(f64::NAN, 0.0, 0.0)),
        Occupancy::Unknown
    );
    let nan = Point3::new(f64::NAN, 0.0, 0.0);
    assert!(t.occupied_in_box(&nan, &Point3::origin()).is_empty());
    assert!(Octree::new(OctreeConfig {
        resolution_m: f64::NAN,
        ..OctreeConfig::default()
    })
    .is_err());
}

#[test]
fn max_range_clears_without_hits() {
    let mut t = Octree::new(OctreeConfig {
        resolution_m: 0.1,
        max_range_m: Some(1.0),
        ..OctreeConfig::default()
    })
    .unwrap();
    let stats = t
        .insert_cloud(
            &[Point3::new(3.05, 0.05, 0.05)],
            &Point3::new(0.05, 0.05, 0.05),
        )
        .unwrap();
    assert_eq!((stats.hits, stats.cleared), (0, 1));
    assert_eq!(
        t.occupancy_at(&Point3::new(0.55, 0.05, 0.05)),
        Occupancy::Free
    );
    assert_eq!(
        t.occupancy_at(&Point3::new(3.05, 0.05, 0.05)),
        Occupancy::Unknown
    );
}

#[test]
fn box_query_returns_the_occupied_voxels_inside() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut t = tree(0.1);
    let cloud = random_cloud(&mut rng, 300, 1.0);
    t.insert_cloud(&cloud, &Point3::origin()).unwrap();
    let (lo, hi) = (Point3::new(0.0, 0.0, -1.0), Point3::new(1.0, 1.0, 1.0));
    let found = t.occupied_in_box(&lo, &hi);
    assert!(!found.is_empty());
    let expected: HashSet<OctreeKey> = cloud
        .iter()
        .filter(|p| (0..3).all(|i| p[i] >= lo[i] && p[i] < hi[i]))
        .filter_map(|p| t.key_at(p))
        .filter(|k| t.occupancy_key(*k) == Occupancy::Occupied)
        .collect();
    let got: HashSet<OctreeKey> = found.iter().map(|l| l.min_key).collect();
    assert!(expected.is_subset(&got));
    for leaf in &found {
        assert!((0..3).all(|i| leaf.center_m[i] + leaf.size_m / 2.0 > lo[i]));
        assert!((0..3).all(|i| leaf.center_m[i] - leaf.size_m / 2.0 <= hi[i]));
    }
}

#[test]
fn bt_roundtrip_keeps_every_voxel_class() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut t = tree(0.05);
    for i in 0..3 {
        let cloud = random_cloud(&mut rng, 500, 1.5);
        t.insert_cloud(&cloud, &Point3::new(0.0, 0.0, 0.1 * f64::from(i)))
            .unwrap();
    }
    let bytes = bt_bytes(&t);
    assert!(bytes.starts_with(b"# Octomap OcTree binary file\n"));
    let back = parse_bt(&bytes, Path::new("test.bt"), t.config()).unwrap();
    let mut checked = 0;
    t.for_each_leaf(|leaf| {
        assert_eq!(back.occupancy_key(leaf.min_key), t.classify(leaf.log_odds));
        checked += 1;
    });
    assert!(checked > 100);
    // Writing the read tree gives the same bytes.
    assert_eq!(bt_bytes(&back), bytes);
    assert!(parse_bt(&bytes[..bytes.len() - 1], Path::new("cut.bt"), t.config()).is_err());
    assert!(parse_bt(b"garbage", Path::new("g.bt"), t.config()).is_err());
}
