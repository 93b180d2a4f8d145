//! Procedural surface textures, so that simulated camera images have corners and blobs for
//! feature trackers: checkerboards and hash-noise blobs (value noise, Perlin, "An image
//! synthesizer", SIGGRAPH 1985, with a lattice hash instead of a permutation table).
//!
//! A texture is a pure function of the surface coordinates `(u, v)` in metres, fixed to the
//! world, so the same surface point has the same colour from every viewpoint (brightness
//! constancy, as direct and KLT trackers assume).

use serde::{Deserialize, Serialize};

/// The pattern of a [`Texture`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Pattern {
    /// One colour, `colors\[0\]`.
    Solid,
    /// Squares of side `scale_m` alternating between the two colours.
    Checker,
    /// Irregular blobs of about `scale_m` of one colour on the other, with finer speckle.
    Blobs,
}

/// Colour pattern of a surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Texture {
    /// Pattern kind.
    pub pattern: Pattern,
    /// Feature size: checker square side or blob diameter \[m\].
    pub scale_m: f64,
    /// The two colours (sRGB 8 bit).
    pub colors: [[u8; 3]; 2],
    /// Seed of the blob noise; surfaces with different seeds look different.
    pub seed: u64,
}

impl Default for Texture {
    fn default() -> Self {
        Self {
            pattern: Pattern::Blobs,
            scale_m: 0.15,
            colors: [[60, 70, 90], [225, 215, 190]],
            seed: 0,
        }
    }
}

/// Colours given in turn to obstacles whose texture is not stated.
const PALETTE: [[[u8; 3]; 2]; 5] = [
    [[150, 40, 30], [235, 225, 200]],
    [[30, 90, 140], [230, 230, 220]],
    [[40, 110, 50], [220, 230, 180]],
    [[120, 80, 40], [240, 210, 150]],
    [[80, 40, 110], [210, 200, 235]],
];

impl Texture {
    /// Default floor: grey-brown blobs.
    pub fn floor() -> Self {
        Self {
            scale_m: 0.2,
            colors: [[90, 80, 70], [185, 175, 160]],
            seed: 1,
            ..Self::default()
        }
    }

    /// Default ceiling: pale, with faint blobs.
    pub fn ceiling() -> Self {
        Self {
            scale_m: 0.3,
            colors: [[170, 170, 175], [235, 235, 240]],
            seed: 2,
            ..Self::default()
        }
    }

    /// Default room walls: blue-grey blobs on cream.
    pub fn room_wall() -> Self {
        Self {
            seed: 3,
            ..Self::default()
        }
    }

    /// Default texture of obstacle number `index`: blobs in a palette colour.
    pub fn obstacle(index: usize) -> Self {
        Self {
            scale_m: 0.1,
            colors: PALETTE[index % PALETTE.len()],
            seed: 100 + index as u64,
            ..Self::default()
        }
    }

    /// Albedo at surface coordinates `(u, v)` \[m\], each channel in `\[0, 1\]`.
    pub fn albedo(&self, u: f64, v: f64) -> [f32; 3] {
        let scale = if self.scale_m > 0.0 {
            self.scale_m
        } else {
            1.0
        };
        let mix = match self.pattern {
            Pattern::Solid => 0.0,
            Pattern::Checker => {
                let parity = (u / scale).floor() as i64 + (v / scale).floor() as i64;
                (parity & 1) as f64
            }
            Pattern::Blobs => blobs(u / scale, v / scale, self.seed),
        };
        let [a, b] = self.colors;
        std::array::from_fn(|c| {
            let value = f64::from(a[c]) + mix * (f64::from(b[c]) - f64::from(a[c]));
            (value / 255.0) as f32
        })
    }
}

/// Blob mask in `\[0, 1\]`: thresholded two-octave value noise, plus a faint fine speckle.
fn blobs(u: f64, v: f64, seed: u64) -> f64 {
    let coarse = value_noise(u, v, seed) * 0.7 + value_noise(2.3 * u, 2.3 * v, seed ^ 0x9e37) * 0.3;
    let edge = ((coarse - 0.5) * 12.0).clamp(-1.0, 1.0) * 0.5 + 0.5;
    let speckle = value_noise(9.0 * u, 9.0 * v, seed ^ 0x51ed) - 0.5;
    (edge + 0.15 * speckle).clamp(0.0, 1.0)
}

/// Smoothly interpolated lattice noise in `\[0, 1\]`.
fn value_noise(u: f64, v: f64, seed: u64) -> f64 {
    let (fu, fv) = (u.floor(), v.floor());
    let (iu, iv) = (fu as i64, fv as i64);
    let smooth = |t: f64| t * t * (3.0 - 2.0 * t);
    let (su, sv) = (smooth(u - fu), smooth(v - fv));
    let corner = |du: i64, dv: i64| lattice(iu + du, iv + dv, seed);
    let top = corner(0, 0) + su * (corner(1, 0) - corner(0, 0));
    let bottom = corner(0, 1) + su * (corner(1, 1) - corner(0, 1));
    top + sv * (bottom - top)
}

/// Hash of a lattice point to `[0, 1)` (SplitMix64 finaliser).
fn lattice(i: i64, j: i64, seed: u64) -> f64 {
    let mut z = seed
        .wrapping_add((i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
        .wrapping_add((j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f));
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checker_alternates_and_blobs_have_both_colours() {
        let t = Texture {
            pattern: Pattern::Checker,
            scale_m: 0.5,
            colors: [[0, 0, 0], [255, 255, 255]],
            seed: 0,
        };
        assert_eq!(t.albedo(0.1, 0.1), [0.0; 3]);
        assert_eq!(t.albedo(0.6, 0.1), [1.0; 3]);
        assert_eq!(t.albedo(-0.1, 0.1), [1.0; 3]);
        let b = Texture {
            pattern: Pattern::Blobs,
            ..t
        };
        let values: Vec<f32> = (0..400)
            .map(|i| b.albedo(f64::from(i % 20) * 0.07, f64::from(i / 20) * 0.07)[0])
            .collect();
        let dark = values.iter().filter(|v| **v < 0.25).count();
        let light = values.iter().filter(|v| **v > 0.75).count();
        assert!(dark > 50 && light > 50, "dark {dark}, light {light}");
        assert_eq!(b.albedo(0.3, 0.7), b.albedo(0.3, 0.7));
    }
}
