//! Issue 25 (7): one image missing from a real dataset under `$SLAMKIT_DATA` (KITTI 06,
//! 7-Scenes RedKitchen, Redwood, EuRoC V1_01 micro; TUM fr3 images in a generated listing) is a
//! frame that fails to load at its own index, with the same timestamp as in the intact copy:
//! never a shift of the later frames, never fatal for the dataset. The copies are symbolic
//! links in a temporary folder, the one image left out.

use std::path::{Path, PathBuf};

use slamkit_io::{Dataset, DatasetFormat};

/// Links every file under `from` into `to` (same layout), except `omit` (relative path).
fn link_copy(from: &Path, to: &Path, omit: &str) {
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        let rel = path.strip_prefix(from).unwrap();
        if path.is_dir() {
            std::fs::create_dir_all(to.join(rel)).unwrap();
            let inner = omit
                .strip_prefix(&format!("{}/", rel.display()))
                .unwrap_or("");
            link_copy(&path, &to.join(rel), inner);
        } else if rel != Path::new(omit) {
            std::os::unix::fs::symlink(&path, to.join(rel)).unwrap();
        }
    }
}

/// Opens `root` intact and with `omit` left out; checks that frame `index` fails naming the
/// missing file and that every frame keeps its index, time and files.
fn check_missing(root: &Path, format: DatasetFormat, omit: &str, index: usize) {
    let intact = Dataset::open(root, format).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    link_copy(root, tmp.path(), omit);
    let damaged = Dataset::open(tmp.path(), format).unwrap();
    assert_eq!(damaged.len(), intact.len(), "{omit}");
    assert_eq!(damaged.timestamps(), intact.timestamps(), "{omit}");
    let err = damaged.observation(index).unwrap().unwrap_err().to_string();
    assert!(err.contains(omit), "{omit}: {err}");
    assert!(!err.contains('\n'), "{err}");
    for i in [index.saturating_sub(1), index + 1] {
        assert!(damaged.observation(i).unwrap().is_ok(), "{omit}: frame {i}");
    }
    assert_eq!(
        damaged.ground_truth().map(|g| g.len()),
        intact.ground_truth().map(|g| g.len())
    );
}

fn data(test: &str, rel: &str) -> Option<PathBuf> {
    slamkit_testdata::data(test, rel)
}

#[test]
fn kitti_missing_left_or_right_image_fails_at_its_own_index() {
    let test = "kitti_missing_left_or_right_image_fails_at_its_own_index";
    let Some(root) = data(test, "stereo/kitti_odometry_06_0000-0050") else {
        return;
    };
    check_missing(&root, DatasetFormat::Kitti, "image_0/000020.png", 20);
    check_missing(&root, DatasetFormat::Kitti, "image_1/000033.png", 33);
}

#[test]
fn seven_scenes_missing_colour_or_depth_fails_at_its_own_index() {
    let test = "seven_scenes_missing_colour_or_depth_fails_at_its_own_index";
    let Some(root) = data(test, "rgbd/7scenes_redkitchen_frames_0000-0599") else {
        return;
    };
    let format = DatasetFormat::SevenScenes;
    check_missing(&root, format, "frame-000100.color.jpg", 100);
    check_missing(&root, format, "frame-000200.depth.png", 200);
}

#[test]
fn redwood_missing_colour_fails_at_its_own_index() {
    let test = "redwood_missing_colour_fails_at_its_own_index";
    let Some(root) = data(test, "rgbd/open3d_testdata_redwood_5frames") else {
        return;
    };
    check_missing(&root, DatasetFormat::Redwood, "color/00002.jpg", 2);
}

#[test]
fn euroc_missing_left_image_fails_at_its_own_index() {
    let test = "euroc_missing_left_image_fails_at_its_own_index";
    let Some(root) = data(test, "stereo/euroc_v101_micro") else {
        return;
    };
    let intact = Dataset::open(&root, DatasetFormat::Euroc).unwrap();
    // the trimmed copy lists 95 rows and holds the first 20 images
    assert_eq!(intact.len(), 20);
    check_missing(
        &root,
        DatasetFormat::Euroc,
        "cam0/data/1403715273762142976.png",
        10,
    );
}

#[test]
fn tum_listed_image_missing_fails_at_its_own_index() {
    let test = "tum_listed_image_missing_fails_at_its_own_index";
    let Some(samples) = data(test, "rgbd/tum_fr3_long_office_household_samples") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    std::fs::create_dir_all(root.join("rgb")).unwrap();
    std::fs::create_dir_all(root.join("depth")).unwrap();
    let (mut rgb, mut depth) = (String::new(), String::new());
    for i in 0..5 {
        let t = 1.0 + f64::from(i) / 30.0;
        rgb.push_str(&format!("{t:.6} rgb/{i}.png\n"));
        depth.push_str(&format!("{:.6} depth/{i}.png\n", t + 0.005));
        for (kind, file) in [("rgb", "TUM_color.png"), ("depth", "TUM_depth.png")] {
            std::os::unix::fs::symlink(samples.join(file), root.join(format!("{kind}/{i}.png")))
                .unwrap();
        }
    }
    std::fs::write(root.join("rgb.txt"), rgb).unwrap();
    std::fs::write(root.join("depth.txt"), depth).unwrap();
    check_missing(root, DatasetFormat::Tum, "rgb/2.png", 2);
}
