//! Occupancy grids as ROS `map_server` maps (PGM + YAML) and PNG images, written and read.
//!
//! Format (ROS `map_server` documentation, "YAML format" and "Value interpretation"): the YAML
//! file names the image and gives `resolution` \[m/pixel\], `origin` `[x, y, yaw]` (the world pose
//! of the lower-left pixel), `negate`, `occupied_thresh` and `free_thresh`. A pixel of value `v`
//! has occupancy `p = (255 - v) / 255` (`v / 255` when negated); `p > occupied_thresh` is occupied,
//! `p < free_thresh` free, anything else unknown. Images are written trinary as `map_saver` does:
//! occupied 0, free 254, unknown 205, with the grid's tri-state ([`Occupancy`]) deciding.
//!
//! Image row 0 is the top of the map (largest y). The YAML reader is a small `key: value` parser
//! for the seven keys `map_server` reads; unknown keys are ignored, as `map_server` does.

use crate::error::MapFileError;
use crate::occupancy_grid::{CellBounds, CellIndex, Occupancy, OccupancyGrid, OccupancyGridConfig};
use crate::tri_grid::TriGrid;
use nalgebra::Point2;
use std::path::{Path, PathBuf};

/// Pixel value of an occupied cell.
pub const OCCUPIED_PIXEL: u8 = 0;
/// Pixel value of a free cell.
pub const FREE_PIXEL: u8 = 254;
/// Pixel value of an unknown cell.
pub const UNKNOWN_PIXEL: u8 = 205;

/// The contents of a `map_server` YAML file.
#[derive(Debug, Clone, PartialEq)]
pub struct MapYaml {
    /// Image file, relative to the YAML file unless absolute.
    pub image: PathBuf,
    /// Side of a pixel \[m\].
    pub resolution_m: f64,
    /// World pose of the lower-left pixel's corner: x \[m\], y \[m\], yaw \[rad\].
    pub origin: [f64; 3],
    /// Whether white means occupied.
    pub negate: bool,
    /// Pixels with occupancy above this are occupied \[0..1\].
    pub occupied_thresh: f64,
    /// Pixels with occupancy below this are free \[0..1\].
    pub free_thresh: f64,
}

impl MapYaml {
    /// The YAML text, one `key: value` line per field.
    pub fn to_yaml_string(&self) -> String {
        let [x, y, yaw] = self.origin;
        format!(
            "image: {}\nresolution: {}\norigin: [{x}, {y}, {yaw}]\nnegate: {}\n\
             occupied_thresh: {}\nfree_thresh: {}\n",
            self.image.display(),
            self.resolution_m,
            u8::from(self.negate),
            self.occupied_thresh,
            self.free_thresh
        )
    }
}

/// A grid rendered as a trinary 8-bit image.
#[derive(Debug, Clone, PartialEq)]
pub struct TrinaryImage {
    /// Width \[pixels\].
    pub width: u32,
    /// Height \[pixels\].
    pub height: u32,
    /// Row-major pixels, top row first.
    pub pixels: Vec<u8>,
    /// World position of the lower-left pixel's corner \[m\].
    pub origin_m: Point2<f64>,
}

/// Renders the known part of `grid` as a trinary image (a single unknown pixel for an empty grid).
pub fn trinary_image(grid: &OccupancyGrid) -> TrinaryImage {
    let origin = CellIndex { x: 0, y: 0 };
    let bounds = grid.known_bounds().unwrap_or(CellBounds {
        min: origin,
        max: origin,
    });
    let (width, height) = (bounds.width(), bounds.height());
    let mut pixels = Vec::with_capacity(width * height);
    for y in (bounds.min.y..=bounds.max.y).rev() {
        pixels.extend((bounds.min.x..=bounds.max.x).map(
            |x| match grid.occupancy(CellIndex { x, y }) {
                Some(Occupancy::Occupied) => OCCUPIED_PIXEL,
                Some(Occupancy::Free) => FREE_PIXEL,
                _ => UNKNOWN_PIXEL,
            },
        ));
    }
    let corner =
        grid.cell_center_m(bounds.min) - nalgebra::Vector2::repeat(grid.resolution_m() / 2.0);
    TrinaryImage {
        width: width as u32,
        height: height as u32,
        pixels,
        origin_m: corner,
    }
}

/// Renders a whole tri-state grid as a trinary image.
///
/// ```
/// use nalgebra::Point2;
/// use slamkit_map::grid_io::tri_grid_image;
/// use slamkit_map::{Occupancy, TriGrid};
/// let mut grid = TriGrid::new(2, 2, 0.1, Point2::new(1.0, 2.0), Occupancy::Free).unwrap();
/// grid.set(0, 1, Occupancy::Occupied); // the top-left pixel: images start at the top row
/// let image = tri_grid_image(&grid);
/// assert_eq!(image.pixels, [0, 254, 254, 254]);
/// assert_eq!(image.origin_m, Point2::new(1.0, 2.0));
/// ```
pub fn tri_grid_image(grid: &TriGrid) -> TrinaryImage {
    let width = grid.width();
    let mut pixels = Vec::with_capacity(grid.cells().len());
    for row in grid.cells().chunks(width.max(1)).rev() {
        pixels.extend(row.iter().map(|cell| match cell {
            Occupancy::Occupied => OCCUPIED_PIXEL,
            Occupancy::Free => FREE_PIXEL,
            Occupancy::Unknown => UNKNOWN_PIXEL,
        }));
    }
    TrinaryImage {
        width: width as u32,
        height: grid.height() as u32,
        pixels,
        origin_m: grid.origin_m(),
    }
}

/// Writes `grid` as `map_server` YAML at `yaml_path` plus a PGM image beside it with the same
/// stem (`map.yaml` → `map.pgm`).
pub fn save_map_yaml(grid: &OccupancyGrid, yaml_path: &Path) -> Result<(), MapFileError> {
    save_image_yaml(&trinary_image(grid), grid.resolution_m(), yaml_path)
}

/// Writes a trinary image of cells of `resolution_m` as `map_server` YAML at `yaml_path` plus
/// the PGM image beside it with the same stem.
pub fn save_image_yaml(
    image: &TrinaryImage,
    resolution_m: f64,
    yaml_path: &Path,
) -> Result<(), MapFileError> {
    let pgm_path = yaml_path.with_extension("pgm");
    write_file(&pgm_path, &pgm_bytes(image))?;
    let yaml = MapYaml {
        image: PathBuf::from(pgm_path.file_name().unwrap_or_default()),
        resolution_m,
        origin: [image.origin_m.x, image.origin_m.y, 0.0],
        negate: false,
        occupied_thresh: 0.65,
        free_thresh: 0.196,
    };
    write_file(yaml_path, yaml.to_yaml_string().as_bytes())
}

/// Writes `grid` as the three files people and tools open: `STEM.pgm` + `STEM.yaml` (ROS
/// `map_server`) and `STEM.png` (any image viewer); `stem` has no extension.
pub fn save_grid_files(grid: &OccupancyGrid, stem: &Path) -> Result<(), MapFileError> {
    save_map_yaml(grid, &stem.with_extension("yaml"))?;
    save_png(grid, &stem.with_extension("png"))
}

/// Writes `grid` as a trinary PNG image.
pub fn save_png(grid: &OccupancyGrid, png_path: &Path) -> Result<(), MapFileError> {
    save_image_png(trinary_image(grid), png_path)
}

/// Writes a trinary image as a PNG image.
pub fn save_image_png(image: TrinaryImage, png_path: &Path) -> Result<(), MapFileError> {
    let img_err = |source| MapFileError::Image {
        path: png_path.to_path_buf(),
        source,
    };
    let gray =
        image::GrayImage::from_raw(image.width, image.height, image.pixels).ok_or_else(|| {
            img_err(image::ImageError::Parameter(
                image::error::ParameterError::from_kind(
                    image::error::ParameterErrorKind::DimensionMismatch,
                ),
            ))
        })?;
    gray.save_with_format(png_path, image::ImageFormat::Png)
        .map_err(img_err)
}

/// Binary PGM (P5) encoding of a trinary image.
fn pgm_bytes(image: &TrinaryImage) -> Vec<u8> {
    let mut bytes = format!(
        "P5\n# slamkit occupancy grid\n{} {}\n255\n",
        image.width, image.height
    )
    .into_bytes();
    bytes.extend_from_slice(&image.pixels);
    bytes
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), MapFileError> {
    std::fs::write(path, bytes).map_err(|source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a `map_server` YAML file and the image it names (PGM, or PNG through the `image`
/// crate) into a grid whose cells are clamped occupied, clamped free or unknown.
pub fn load_map_yaml(yaml_path: &Path) -> Result<OccupancyGrid, MapFileError> {
    let text = std::fs::read_to_string(yaml_path).map_err(|source| MapFileError::Io {
        path: yaml_path.to_path_buf(),
        source,
    })?;
    let meta = parse_map_yaml(&text, yaml_path)?;
    if meta.origin[2] != 0.0 {
        return Err(MapFileError::Unsupported {
            path: yaml_path.to_path_buf(),
            message: format!("rotated map origin (yaw {} rad)", meta.origin[2]),
        });
    }
    let image_path = yaml_path
        .parent()
        .unwrap_or(Path::new(""))
        .join(&meta.image);
    let (width, height, pixels) = read_gray_image(&image_path)?;
    let config = OccupancyGridConfig {
        resolution_m: meta.resolution_m,
        ..OccupancyGridConfig::default()
    };
    let origin = Point2::new(meta.origin[0], meta.origin[1]);
    let mut grid =
        OccupancyGrid::with_origin(config, origin).map_err(|source| MapFileError::Map {
            path: yaml_path.to_path_buf(),
            source,
        })?;
    let (l_min, l_max) = grid.log_odds_limits();
    for (i, &v) in pixels.iter().enumerate() {
        let value = f64::from(v) / 255.0;
        let p = if meta.negate { value } else { 1.0 - value };
        let log_odds = if p > meta.occupied_thresh {
            l_max
        } else if p < meta.free_thresh {
            l_min
        } else {
            continue;
        };
        let cell = CellIndex {
            x: (i % width) as i32,
            y: (height - 1 - i / width) as i32,
        };
        grid.set_log_odds(cell, log_odds)
            .map_err(|source| MapFileError::Map {
                path: yaml_path.to_path_buf(),
                source,
            })?;
    }
    Ok(grid)
}

/// Parses the text of a `map_server` YAML file; `path` names it in errors.
pub fn parse_map_yaml(text: &str, path: &Path) -> Result<MapYaml, MapFileError> {
    let mut fields: [Option<(usize, &str)>; 6] = [None; 6];
    const KEYS: [&str; 6] = [
        "image",
        "resolution",
        "origin",
        "negate",
        "occupied_thresh",
        "free_thresh",
    ];
    let bad = |line: usize, message: String| MapFileError::Yaml {
        path: path.to_path_buf(),
        line,
        message,
    };
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or_default().trim();
        if line.is_empty() {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(bad(n + 1, format!("expected `key: value`, found `{line}`")));
        };
        let Some(slot) = KEYS.iter().position(|k| *k == key.trim()) else {
            continue; // mode, cost_translation_table, ... : not used here
        };
        if fields[slot].is_some() {
            return Err(bad(n + 1, format!("duplicate key `{}`", KEYS[slot])));
        }
        fields[slot] = Some((n + 1, value.trim().trim_matches(|c| c == '"' || c == '\'')));
    }
    let get = |slot: usize| {
        fields[slot].ok_or(MapFileError::MissingKey {
            path: path.to_path_buf(),
            key: KEYS[slot],
        })
    };
    let number = |slot: usize| -> Result<f64, MapFileError> {
        let (line, value) = get(slot)?;
        parse_finite(value).ok_or_else(|| bad(line, format!("`{}` is not a number", KEYS[slot])))
    };
    let (image_line, image) = get(0)?;
    if image.is_empty() {
        return Err(bad(image_line, "empty image file name".into()));
    }
    let (origin_line, origin_text) = get(2)?;
    let origin = parse_origin(origin_text).ok_or_else(|| {
        bad(
            origin_line,
            format!("origin must be `[x, y, yaw]`, found `{origin_text}`"),
        )
    })?;
    let negate = match get(3)? {
        (_, "0") => false,
        (_, "1") => true,
        (line, v) => return Err(bad(line, format!("negate must be 0 or 1, found `{v}`"))),
    };
    let resolution_m = number(1)?;
    if resolution_m <= 0.0 {
        let line = get(1)?.0;
        return Err(bad(
            line,
            format!("resolution must be positive, found {resolution_m}"),
        ));
    }
    let (occupied_thresh, free_thresh) = (number(4)?, number(5)?);
    if !(0.0..=1.0).contains(&free_thresh)
        || !(0.0..=1.0).contains(&occupied_thresh)
        || free_thresh > occupied_thresh
    {
        let message = format!(
            "need 0 <= free_thresh ({free_thresh}) <= occupied_thresh ({occupied_thresh}) <= 1"
        );
        return Err(bad(get(5)?.0, message));
    }
    Ok(MapYaml {
        image: PathBuf::from(image),
        resolution_m,
        origin,
        negate,
        occupied_thresh,
        free_thresh,
    })
}

fn parse_finite(value: &str) -> Option<f64> {
    value.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

fn parse_origin(value: &str) -> Option<[f64; 3]> {
    let inner = value.strip_prefix('[')?.strip_suffix(']')?;
    let parts: Vec<f64> = inner.split(',').map(parse_finite).collect::<Option<_>>()?;
    parts.try_into().ok()
}

/// Reads an 8-bit grey image: PGM by our own parser, anything else through the `image` crate.
fn read_gray_image(path: &Path) -> Result<(usize, usize, Vec<u8>), MapFileError> {
    let is_pgm = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pgm"));
    if is_pgm {
        let bytes = std::fs::read(path).map_err(|source| MapFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        return parse_pgm(&bytes).map_err(|message| MapFileError::Pgm {
            path: path.to_path_buf(),
            message,
        });
    }
    let image = image::open(path).map_err(|source| MapFileError::Image {
        path: path.to_path_buf(),
        source,
    })?;
    let gray = image.to_luma8();
    Ok((
        gray.width() as usize,
        gray.height() as usize,
        gray.into_raw(),
    ))
}

/// Parses a binary 8-bit PGM (P5): `(width, height, pixels)`.
pub fn parse_pgm(bytes: &[u8]) -> Result<(usize, usize, Vec<u8>), String> {
    let mut pos = 0;
    let mut header = [0usize; 3];
    if bytes.get(..2) != Some(b"P5".as_slice()) {
        return Err("not a binary PGM (magic number `P5` missing)".into());
    }
    pos += 2;
    for (field, name) in header.iter_mut().zip(["width", "height", "maxval"]) {
        *field = next_header_number(bytes, &mut pos).ok_or(format!("bad or missing {name}"))?;
    }
    let [width, height, maxval] = header;
    if width == 0 || height == 0 || width.saturating_mul(height) > 1 << 30 {
        return Err(format!("bad size {width} x {height}"));
    }
    if maxval == 0 || maxval > 255 {
        return Err(format!("maxval {maxval}: only 8-bit images are supported"));
    }
    // Exactly one whitespace byte separates the header from the pixels.
    if !bytes.get(pos).is_some_and(u8::is_ascii_whitespace) {
        return Err("no whitespace after maxval".into());
    }
    let start = pos + 1;
    let n = width * height;
    let data = bytes.get(start..).unwrap_or_default();
    if data.len() < n {
        return Err(format!(
            "truncated: {n} pixels expected, {} found",
            data.len()
        ));
    }
    let scale = |v: u8| ((u32::from(v) * 255 + maxval as u32 / 2) / maxval as u32).min(255) as u8;
    Ok((width, height, data[..n].iter().map(|&v| scale(v)).collect()))
}

/// Next decimal header field, skipping whitespace and `#` comments; leaves `pos` on the byte
/// after the number.
fn next_header_number(bytes: &[u8], pos: &mut usize) -> Option<usize> {
    loop {
        match bytes.get(*pos)? {
            b'#' => {
                while bytes.get(*pos).is_some_and(|&b| b != b'\n') {
                    *pos += 1;
                }
            }
            b if b.is_ascii_whitespace() => *pos += 1,
            _ => break,
        }
    }
    let start = *pos;
    while bytes.get(*pos).is_some_and(u8::is_ascii_digit) {
        *pos += 1;
    }
    std::str::from_utf8(bytes.get(start..*pos)?)
        .ok()?
        .parse()
        .ok()
}

#[cfg(test)]
#[path = "grid_io_tests.rs"]
mod tests;
