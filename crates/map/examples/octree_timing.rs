//! Times slamkit's octree insertion on a file of scans and prints one JSON object with the
//! median milliseconds of inserting every scan into a new tree, the tree's size and bytes (used
//! by `scripts/bench_octree_vs_octomap.py`). Times are the calling thread's CPU time, as the
//! script measures OctoMap's, so that other processes on a shared machine do not inflate
//! either side.
//!
//! Usage: `octree_timing \[--reps N\] \[--max-range M\] \[--bt OUT.bt\] RESOLUTION SCANS.bin`
//!
//! `SCANS.bin` (little endian): `u32` scan count, then per scan the sensor origin as three
//! `f64` \[m\], a `u32` point count and the points as `f32` triples \[m\], all in the world frame.

use std::path::Path;

use cpu_time::ThreadTime;
use nalgebra::Point3;

use slamkit_map::octree::bt::write_bt;
use slamkit_map::{Octree, OctreeConfig};

/// One scan: sensor origin and end points, world frame \[m\].
struct Scan {
    origin: Point3<f64>,
    points: Vec<Point3<f64>>,
}

/// Reads little-endian values from a byte slice, naming the file in errors.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    path: &'a str,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let chunk = self
            .bytes
            .get(self.at..self.at + N)
            .and_then(|b| <[u8; N]>::try_from(b).ok())
            .ok_or_else(|| format!("{}: truncated at byte {}", self.path, self.at))?;
        self.at += N;
        Ok(chunk)
    }

    fn u32(&mut self) -> Result<usize, String> {
        Ok(u32::from_le_bytes(self.take()?) as usize)
    }

    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.take()?))
    }

    fn f32(&mut self) -> Result<f64, String> {
        Ok(f64::from(f32::from_le_bytes(self.take()?)))
    }
}

fn read_scans(path: &str) -> Result<Vec<Scan>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
    let mut r = Reader {
        bytes: &bytes,
        at: 0,
        path,
    };
    let n_scans = r.u32()?;
    let mut scans = Vec::new();
    for _ in 0..n_scans {
        let origin = Point3::new(r.f64()?, r.f64()?, r.f64()?);
        let n = r.u32()?;
        if n.saturating_mul(12) > bytes.len().saturating_sub(r.at) {
            return Err(format!(
                "{path}: scan of {n} points is longer than the file"
            ));
        }
        let points = (0..n)
            .map(|_| Ok(Point3::new(r.f32()?, r.f32()?, r.f32()?)))
            .collect::<Result<_, String>>()?;
        scans.push(Scan { origin, points });
    }
    if r.at != bytes.len() {
        return Err(format!("{path}: {} trailing bytes", bytes.len() - r.at));
    }
    Ok(scans)
}

fn build(config: &OctreeConfig, scans: &[Scan]) -> Result<Octree, Box<dyn std::error::Error>> {
    let mut tree = Octree::new(config.clone())?;
    for scan in scans {
        tree.insert_cloud(&scan.points, &scan.origin)?;
    }
    Ok(tree)
}

/// Removes `--name VALUE` from `args` and parses the value.
fn flag<T: std::str::FromStr>(args: &mut Vec<String>, name: &str) -> Result<Option<T>, String> {
    let Some(i) = args.iter().position(|a| a == name) else {
        return Ok(None);
    };
    let value = args
        .get(i + 1)
        .ok_or(format!("{name} needs a value"))?
        .parse()
        .map_err(|_| format!("{name}: not a valid value"))?;
    args.drain(i..i + 2);
    Ok(Some(value))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let reps: usize = flag(&mut args, "--reps")?.unwrap_or(5);
    let max_range_m: Option<f64> = flag(&mut args, "--max-range")?;
    let bt: Option<String> = flag(&mut args, "--bt")?;
    let [resolution, path] = args.as_slice() else {
        return Err(
            "usage: octree_timing [--reps N] [--max-range M] [--bt OUT.bt] \
                    RESOLUTION SCANS.bin"
                .into(),
        );
    };
    let config = OctreeConfig {
        resolution_m: resolution.parse()?,
        max_range_m,
        ..OctreeConfig::default()
    };
    let scans = read_scans(path)?;
    let mut times = Vec::new();
    for _ in 0..reps.max(1) {
        let start = ThreadTime::now();
        std::hint::black_box(build(&config, &scans)?);
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let tree = build(&config, &scans)?;
    if let Some(out) = &bt {
        write_bt(&tree, Path::new(out))?;
    }
    let stats = tree.stats();
    let out = serde_json::json!({
        "scans": scans.len(),
        "points": scans.iter().map(|s| s.points.len()).sum::<usize>(),
        "ms": times.get(times.len() / 2),
        "ms_all": times,
        "nodes": stats.nodes,
        "leaves": stats.leaves,
        "occupied_leaves": stats.occupied_leaves,
        "bytes": stats.bytes,
    });
    println!("{out}");
    Ok(())
}
