//! Telling a dataset folder's layout from its content, so that a user can point at a folder
//! without naming its format.

use crate::dataset::DatasetFormat;
use crate::error::IoError;
use std::path::Path;

/// The layout of the dataset folder `dir`, from the files each layout must hold (KITTI:
/// `image_0/` and `calib.txt`; TUM: `rgb.txt` and `depth.txt`; EuRoC: `cam0/` and `cam1/`;
/// Redwood: `color/` and `depth/`; 7-Scenes: `*.color.png` or `*.color.jpg` frames), checked
/// in that order after a bag ([`is_bag`]: a ROS 2 bag folder, or a bag file); `None` when it
/// matches none.
///
/// ```
/// use slamkit_io::layout::detect_layout;
/// use slamkit_io::DatasetFormat;
///
/// let dir = std::env::temp_dir().join(format!("slamkit_layout_doc_{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// assert_eq!(detect_layout(&dir)?, None);
/// std::fs::write(dir.join("rgb.txt"), "")?;
/// std::fs::write(dir.join("depth.txt"), "")?;
/// assert_eq!(detect_layout(&dir)?, Some(DatasetFormat::Tum));
/// std::fs::remove_dir_all(&dir)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn detect_layout(dir: &Path) -> Result<Option<DatasetFormat>, IoError> {
    if is_bag(dir) {
        return Ok(Some(DatasetFormat::RosBag));
    }
    let has = |p: &str| dir.join(p).exists();
    if has("image_0") && has("calib.txt") {
        return Ok(Some(DatasetFormat::Kitti));
    }
    if has("rgb.txt") && has("depth.txt") {
        return Ok(Some(DatasetFormat::Tum));
    }
    if has("cam0") && has("cam1") {
        return Ok(Some(DatasetFormat::Euroc));
    }
    if has("color") && has("depth") {
        return Ok(Some(DatasetFormat::Redwood));
    }
    let seven = std::fs::read_dir(dir)
        .map_err(|e| IoError::io(dir, e))?
        .filter_map(Result::ok)
        .any(|e| {
            let name = e.file_name();
            let name = name.to_string_lossy();
            name.ends_with(".color.jpg") || name.ends_with(".color.png")
        });
    Ok(seven.then_some(DatasetFormat::SevenScenes))
}

/// True when `path` is a ROS 2 bag folder (with `metadata.yaml`), or a file that starts like a
/// robot bag: a ROS 1 bag (`#ROSBAG V`), an MCAP
/// file or an SQLite database (ROS 2 `.db3`); the bag reader then says which it reads
/// ([`crate::bag`]). Anything else (a CARMEN log, plain or gzip; a missing file) is `false`.
///
/// ```
/// use slamkit_io::layout::is_bag;
///
/// let path = std::env::temp_dir().join(format!("slamkit_is_bag_{}.bag", std::process::id()));
/// std::fs::write(&path, b"#ROSBAG V2.0\n")?;
/// assert!(is_bag(&path));
/// std::fs::write(&path, b"RAWLASER1 0 -1.57")?;
/// assert!(!is_bag(&path));
/// std::fs::remove_file(&path)?;
/// # Ok::<(), std::io::Error>(())
/// ```
pub fn is_bag(path: &Path) -> bool {
    use std::io::Read;
    if path.is_dir() {
        // a ROS 2 bag folder
        return path.join("metadata.yaml").is_file();
    }
    let mut head = [0u8; 16];
    let Ok(file) = std::fs::File::open(path) else {
        return false;
    };
    let got = file.take(16).read(&mut head).unwrap_or(0);
    let head = &head[..got];
    head.starts_with(b"#ROSBAG V")
        || head.starts_with(b"\x89MCAP")
        || head.starts_with(b"SQLite format 3")
}
