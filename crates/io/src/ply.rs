//! PLY point clouds (ASCII), the format every point-cloud viewer opens (MeshLab, CloudCompare,
//! Open3D, Blender).

use crate::IoError;
use nalgebra::Point3;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `points` as an ASCII PLY file with `comment` in its header.
pub fn write_ply(path: &Path, points: &[Point3<f64>], comment: &str) -> Result<(), IoError> {
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment {}\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nend_header\n",
        comment.replace('\n', " "),
        points.len()
    );
    for p in points {
        let _ = writeln!(text, "{:.4} {:.4} {:.4}", p.x, p.y, p.z);
    }
    std::fs::write(path, text).map_err(|e| IoError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_counts_the_vertices() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.ply");
        write_ply(&path, &[Point3::new(1.0, 2.0, 3.0)], "test").unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("element vertex 1\n"));
        assert!(text.ends_with("1.0000 2.0000 3.0000\n"));
    }
}
