//! The demo's `report.html`: one self-contained page (every image embedded as a base64 data
//! URI, no script, no network) with the error table, the error plots and the maps.

use anyhow::Context;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A height layer's map image.
pub struct LayerImage {
    /// Layer index.
    pub layer: i64,
    /// Bottom and top of the layer \[m\].
    pub z_range_m: [f64; 2],
    /// Scans inserted into the map.
    pub scans: usize,
    /// The PNG file.
    pub png: PathBuf,
}

/// What the page shows.
pub struct Page<'a> {
    /// World name.
    pub world: &'a str,
    /// Simulation seed.
    pub seed: u64,
    /// Flight duration \[s\].
    pub duration_s: f64,
    /// Length of the true path \[m\].
    pub path_length_m: f64,
    /// Per method: name, mean and max position error \[m\], error plot PNG.
    pub methods: Vec<(&'a str, f64, f64, PathBuf)>,
    /// Whole-flight maps: title and PNG (every layer together, the particle filter's map).
    pub maps: Vec<(&'a str, PathBuf)>,
    /// One map per layer, lowest first.
    pub layers: Vec<LayerImage>,
    /// The kidnapped-drone layer choice, one line of plain text.
    pub layer_choice: String,
}

/// Writes the page to `path`.
pub fn write(path: &Path, page: &Page) -> anyhow::Result<()> {
    let mut h = String::new();
    let title = format!("slamkit demo: {} world", page.world);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>{title}</title>\n<style>\n\
         body {{ font-family: sans-serif; margin: 2em; color: #222; }}\n\
         table {{ border-collapse: collapse; }}\n\
         td, th {{ border: 1px solid #aaa; padding: 0.3em 0.8em; text-align: right; }}\n\
         img {{ border: 1px solid #ccc; image-rendering: pixelated; }}\n\
         .plot {{ max-width: 100%; }}\n\
         .layers {{ display: flex; flex-wrap: wrap; gap: 1em; }}\n\
         figure {{ margin: 0; }} figure img {{ width: 240px; }}\n\
         </style>\n</head>\n<body>\n<h1>{title}</h1>\n\
         <p>Simulated drone flight of {:.0} s ({:.1} m, seed {}): layered ICP-SLAM (one 2D map per \
         height layer) and particle-filter SLAM (one 2D map).</p>\n",
        page.duration_s, page.path_length_m, page.seed
    );
    h.push_str(
        "<h2>Position error against ground truth</h2>\n<table>\n\
         <tr><th>method</th><th>mean [m]</th><th>max [m]</th></tr>\n",
    );
    for (name, mean, max, _) in &page.methods {
        let _ = writeln!(
            h,
            "<tr><td>{name}</td><td>{mean:.3}</td><td>{max:.3}</td></tr>"
        );
    }
    h.push_str("</table>\n");
    let _ = writeln!(h, "<p>Kidnapped drone, {}</p>", page.layer_choice);
    for (name, _, _, png) in &page.methods {
        let _ = writeln!(
            h,
            "<h3>{name}</h3>\n<img class=\"plot\" alt=\"{name} errors\" src=\"{}\">",
            data_uri(png)?
        );
    }
    for (title, png) in &page.maps {
        let _ = writeln!(
            h,
            "<h2>{title}</h2>\n<img alt=\"{title}\" src=\"{}\">",
            data_uri(png)?
        );
    }
    let _ = writeln!(
        h,
        "<h2>Maps per height layer ({})</h2>\n<div class=\"layers\">",
        page.layers.len()
    );
    for l in &page.layers {
        let _ = writeln!(
            h,
            "<figure><img alt=\"layer {}\" src=\"{}\"><figcaption>layer {}: {:.2}–{:.2} m, \
             {} scans</figcaption></figure>",
            l.layer,
            data_uri(&l.png)?,
            l.layer,
            l.z_range_m[0],
            l.z_range_m[1],
            l.scans
        );
    }
    h.push_str("</div>\n</body>\n</html>\n");
    std::fs::write(path, h).with_context(|| format!("writing {}", path.display()))
}

/// A PNG file as a `data:` URI.
fn data_uri(png: &Path) -> anyhow::Result<String> {
    let bytes = std::fs::read(png).with_context(|| format!("reading {}", png.display()))?;
    Ok(format!("data:image/png;base64,{}", base64(&bytes)))
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc_4648_vectors() {
        let cases = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
    }
}
