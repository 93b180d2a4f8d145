//! Times slamkit's front-end kernels on the given images and prints one JSON object with the
//! median milliseconds per kernel (used by `scripts/bench_vision_vs_opencv.py`). Times are the
//! calling thread's CPU time, as the script measures OpenCV's, so that other processes on a
//! shared machine do not inflate either side.
//!
//! Usage: `kernel_timing \[--reps N\] IMAGE...` — images in sequence order; KLT tracks each
//! image's Shi–Tomasi corners into the next image, forward and backward.

use std::path::Path;

use cpu_time::ThreadTime;

use slamkit_vision::clahe::{Clahe, ClaheConfig};
use slamkit_vision::color::rgb_to_gray;
use slamkit_vision::corners::{shi_tomasi, ShiTomasiConfig};
use slamkit_vision::klt::{track, KltConfig, KltPyramid};
use slamkit_vision::orb::{Orb, OrbConfig};
use slamkit_vision::{GrayImage, RgbImage};

/// Median thread CPU time of `reps` runs of `f` \[ms\].
fn median_ms<T>(reps: usize, mut f: impl FnMut() -> T) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = ThreadTime::now();
            std::hint::black_box(f());
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t.get(t.len() / 2).copied().unwrap_or(f64::NAN)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut reps = 15;
    if let Some(i) = args.iter().position(|a| a == "--reps") {
        reps = args.get(i + 1).ok_or("--reps needs a value")?.parse()?;
        args.drain(i..i + 2);
    }
    if args.is_empty() {
        return Err("usage: kernel_timing [--reps N] IMAGE...".into());
    }
    let rgbs: Vec<RgbImage> = args
        .iter()
        .map(|p| slamkit_io::image_io::load_rgb(Path::new(p)))
        .collect::<Result<_, _>>()?;
    let grays: Vec<GrayImage> = rgbs.iter().map(rgb_to_gray).collect();
    let mut clahe = Clahe::new(ClaheConfig::default())?;
    let st = ShiTomasiConfig {
        max_corners: 500,
        max_per_cell: 0,
        ..ShiTomasiConfig::default()
    };
    let klt = KltConfig::default();
    let orb = Orb::new(OrbConfig::default())?;
    let (mut t_gray, mut t_clahe_g, mut t_clahe_rgb, mut t_st, mut t_klt, mut t_orb) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let (mut n_corners, mut n_tracked, mut n_orb) = (vec![], vec![], vec![]);
    for (i, (rgb, gray)) in rgbs.iter().zip(&grays).enumerate() {
        t_gray.push(median_ms(reps, || rgb_to_gray(rgb)));
        t_clahe_g.push(median_ms(reps, || clahe.apply_gray(gray)));
        t_clahe_rgb.push(median_ms(reps, || clahe.apply_rgb(rgb)));
        t_st.push(median_ms(reps, || shi_tomasi(gray, &st)));
        let corners = shi_tomasi(gray, &st)?;
        n_corners.push(corners.len() as f64);
        t_orb.push(median_ms(reps, || orb.detect_and_compute(gray)));
        n_orb.push(orb.detect_and_compute(gray).keypoints.len() as f64);
        if let Some(next) = grays.get(i + 1) {
            let pts: Vec<(f32, f32)> = corners.iter().map(|c| (c.x, c.y)).collect();
            let run = || -> Result<usize, slamkit_vision::VisionError> {
                let (a, b) = (
                    KltPyramid::new(gray, klt.max_level),
                    KltPyramid::new(next, klt.max_level),
                );
                Ok(track(&a, &b, &pts, &klt)?.iter().filter(|t| t.ok).count())
            };
            t_klt.push(median_ms(reps, run));
            n_tracked.push(run()? as f64);
        }
    }
    let out = serde_json::json!({
        "images": args.len(),
        "width": grays.first().map(|g| g.width()),
        "height": grays.first().map(|g| g.height()),
        "ms": {
            "rgb_to_gray": median(t_gray),
            "clahe_gray": median(t_clahe_g),
            "clahe_rgb": median(t_clahe_rgb),
            "shi_tomasi": median(t_st),
            "klt_fb": median(t_klt),
            "orb": median(t_orb),
        },
        "counts": {
            "shi_tomasi_corners": median(n_corners),
            "klt_tracked": median(n_tracked),
            "orb_keypoints": median(n_orb),
        }
    });
    println!("{out}");
    Ok(())
}
