//! Worlds described in TOML: a room (floor, ceiling, four walls) holding walls, boxes,
//! cylinders and ramps, each with a height range so a drone can fly over or under it.
//!
//! The world frame has its origin at a floor corner of the room, x and y along the walls and z
//! up; the room spans `[0, size_m\[0\]] × [0, size_m\[1\]] × \[0, height_m\]`. Every surface carries
//! a procedural [`Texture`] so that camera images have features to track. Each world also names
//! a default drone flight (waypoints `x y z yaw`), a ground-robot drive (`x y`) and a 2D
//! navigation goal.
//!
//! Three worlds are built in ([`World::builtin`]), after the seed's experiments:
//! `small` (5 × 5 × 1 m), `large` (10 × 10 × 2.4 m, with a ramp) and `office`
//! (12.9 × 7.7 × 2.5 m, desks, shelves and pillars).

use crate::texture::Texture;
use crate::SimError;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Names of the worlds shipped with the crate.
pub const BUILTIN_WORLDS: [&str; 3] = ["small", "large", "office"];

/// A world: the room, what stands in it, and its default paths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct World {
    /// Name shown in reports.
    pub name: String,
    /// Room extent along x and y \[m\].
    pub size_m: [f64; 2],
    /// Room height (floor to ceiling) \[m\].
    pub height_m: f64,
    /// Texture of the floor.
    #[serde(default = "Texture::floor")]
    pub floor_texture: Texture,
    /// Texture of the ceiling.
    #[serde(default = "Texture::ceiling")]
    pub ceiling_texture: Texture,
    /// Texture of the four room walls.
    #[serde(default = "Texture::room_wall")]
    pub wall_texture: Texture,
    /// Default drone flight: waypoints `\[x, y, z, yaw\]` \[m, m, m, rad\].
    pub flight_path: Vec<[f64; 4]>,
    /// Default ground-robot drive: waypoints `\[x, y\]` \[m\] (obstacle-free at floor level).
    pub drive_path: Vec<[f64; 2]>,
    /// A closed ground-robot drive for loop closing (`--path loopN`): waypoints `\[x, y\]`
    /// \[m\] driven in order and back to the first ([`World::drive_laps`]); empty when the
    /// world has none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drive_loop: Vec<[f64; 2]>,
    /// Default navigation goal `\[x, y\]` \[m\].
    pub nav_goal: [f64; 2],
    /// Walls inside the room.
    #[serde(default)]
    pub walls: Vec<Wall>,
    /// Boxes (desks, shelves, crates), possibly rotated about z.
    #[serde(default)]
    pub boxes: Vec<BoxObstacle>,
    /// Vertical cylinders (pillars, bins, table legs).
    #[serde(default)]
    pub cylinders: Vec<Cylinder>,
    /// Inclined ramps (wedges).
    #[serde(default)]
    pub ramps: Vec<Ramp>,
}

/// A straight wall from `from` to `to`, `thickness_m` thick, between two heights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wall {
    /// One end of the wall's centre line `\[x, y\]` \[m\].
    pub from: [f64; 2],
    /// The other end `\[x, y\]` \[m\].
    pub to: [f64; 2],
    /// Thickness \[m\].
    #[serde(default = "default_wall_thickness")]
    pub thickness_m: f64,
    /// Bottom and top heights `\[z_min, z_max\]` \[m\].
    pub z_m: [f64; 2],
    /// Surface texture (hash-noise blobs when omitted).
    #[serde(default)]
    pub texture: Option<Texture>,
}

/// A box standing upright, rotated by `yaw_rad` about its vertical axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxObstacle {
    /// Centre of the footprint `\[x, y\]` \[m\].
    pub center: [f64; 2],
    /// Footprint size `[length along its x, width along its y]` \[m\].
    pub size_m: [f64; 2],
    /// Rotation about z \[rad\].
    #[serde(default)]
    pub yaw_rad: f64,
    /// Bottom and top heights `\[z_min, z_max\]` \[m\] (a table top: `\[0.7, 0.75\]`).
    pub z_m: [f64; 2],
    /// Surface texture (hash-noise blobs when omitted).
    #[serde(default)]
    pub texture: Option<Texture>,
}

/// A vertical cylinder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cylinder {
    /// Axis position `\[x, y\]` \[m\].
    pub center: [f64; 2],
    /// Radius \[m\].
    pub radius_m: f64,
    /// Bottom and top heights `\[z_min, z_max\]` \[m\].
    pub z_m: [f64; 2],
    /// Surface texture (hash-noise blobs when omitted).
    #[serde(default)]
    pub texture: Option<Texture>,
}

/// A wedge whose top rises along its own x axis from `z_m\[0\]` at the low end to `z_m\[1\]` at
/// the high end; its bottom is flat at `z_m\[0\]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ramp {
    /// Centre of the footprint `\[x, y\]` \[m\].
    pub center: [f64; 2],
    /// Footprint `[length along the slope, width]` \[m\].
    pub size_m: [f64; 2],
    /// Direction of the rise, about z \[rad\].
    #[serde(default)]
    pub yaw_rad: f64,
    /// Bottom height and height of the high end `\[z_min, z_max\]` \[m\].
    pub z_m: [f64; 2],
    /// Surface texture (hash-noise blobs when omitted).
    #[serde(default)]
    pub texture: Option<Texture>,
}

fn default_wall_thickness() -> f64 {
    0.1
}

impl World {
    /// One of the [`BUILTIN_WORLDS`], parsed from the TOML shipped in `crates/sim/worlds/`.
    pub fn builtin(name: &str) -> Result<World, SimError> {
        let text = match name {
            "small" => include_str!("../worlds/small.toml"),
            "large" => include_str!("../worlds/large.toml"),
            "office" => include_str!("../worlds/office.toml"),
            _ => {
                return Err(SimError::UnknownWorld {
                    name: name.to_string(),
                })
            }
        };
        World::from_toml(text, name)
    }

    /// A built-in world by name, or else a TOML world file at that path.
    pub fn by_name_or_file(name_or_path: &str) -> Result<World, SimError> {
        if BUILTIN_WORLDS.contains(&name_or_path) {
            return World::builtin(name_or_path);
        }
        let path = Path::new(name_or_path);
        // A name that looks like a file is a missing file, not an unknown built-in world.
        let looks_like_file = name_or_path.ends_with(".toml") || name_or_path.contains('/');
        let text = std::fs::read_to_string(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound if !looks_like_file => SimError::UnknownWorld {
                name: name_or_path.to_string(),
            },
            _ => SimError::Parse {
                world: name_or_path.to_string(),
                message: e.to_string(),
            },
        })?;
        World::from_toml(&text, name_or_path)
    }

    /// Parses and validates a world; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<World, SimError> {
        let world: World = toml::from_str(text).map_err(|e| {
            // one line: where and what, not the parser's multi-line excerpt
            let line = e.span().map_or(String::new(), |span| {
                let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}: ")
            });
            SimError::Parse {
                world: origin.to_string(),
                message: format!(
                    "{line}{}",
                    e.message().split_whitespace().collect::<Vec<_>>().join(" ")
                ),
            }
        })?;
        world.validate().map_err(|what| SimError::InvalidWorld {
            world: origin.to_string(),
            what,
        })?;
        Ok(world)
    }

    /// True when `(x, y, z)` is inside the room.
    pub fn contains(&self, x: f64, y: f64, z: f64) -> bool {
        (0.0..=self.size_m[0]).contains(&x)
            && (0.0..=self.size_m[1]).contains(&y)
            && (0.0..=self.height_m).contains(&z)
    }

    /// The waypoints of `laps` times round the world's `drive_loop`, starting and ending at its
    /// first point.
    ///
    /// ```
    /// let office = slamkit_sim::World::builtin("office")?;
    /// let path = office.drive_laps(3)?;
    /// assert_eq!(path.len(), 3 * office.drive_loop.len() + 1);
    /// assert_eq!((path[0], path[path.len() - 1]), (office.drive_loop[0], office.drive_loop[0]));
    /// # Ok::<(), slamkit_sim::SimError>(())
    /// ```
    ///
    /// # Errors
    /// [`SimError::InvalidConfig`] when `laps` is 0 or the world has no `drive_loop`.
    pub fn drive_laps(&self, laps: usize) -> Result<Vec<[f64; 2]>, SimError> {
        if laps == 0 {
            return Err(SimError::InvalidConfig(
                "a loop drive needs 1 lap or more".into(),
            ));
        }
        if self.drive_loop.is_empty() {
            return Err(SimError::InvalidConfig(format!(
                "world {} has no drive_loop",
                self.name
            )));
        }
        let mut path: Vec<[f64; 2]> = (0..laps)
            .flat_map(|_| self.drive_loop.iter().copied())
            .collect();
        path.push(self.drive_loop[0]);
        Ok(path)
    }

    /// Checks sizes, heights and that every path point and the goal lie in the room.
    fn validate(&self) -> Result<(), String> {
        if !(positive(self.size_m[0]) && positive(self.size_m[1]) && positive(self.height_m)) {
            return Err("size_m and height_m must be positive".into());
        }
        check_each("walls", &self.walls, |w| {
            check_range(&w.z_m)?;
            let len = ((w.to[0] - w.from[0]).powi(2) + (w.to[1] - w.from[1]).powi(2)).sqrt();
            require(
                positive(len) && positive(w.thickness_m),
                "zero length or thickness",
            )
        })?;
        check_each("boxes", &self.boxes, |b| {
            check_footprint(&b.z_m, b.size_m, b.yaw_rad)
        })?;
        check_each("cylinders", &self.cylinders, |c| {
            check_range(&c.z_m)?;
            require(positive(c.radius_m), "radius_m must be positive")
        })?;
        check_each("ramps", &self.ramps, |r| {
            check_footprint(&r.z_m, r.size_m, r.yaw_rad)
        })?;
        self.validate_paths()
    }

    fn validate_paths(&self) -> Result<(), String> {
        if self.flight_path.len() < 2 || self.drive_path.len() < 2 {
            return Err("flight_path and drive_path need at least 2 waypoints".into());
        }
        for (i, w) in self.flight_path.iter().enumerate() {
            if !self.contains(w[0], w[1], w[2]) || !w[3].is_finite() {
                return Err(format!("flight_path[{i}] {w:?} is outside the room"));
            }
        }
        for (name, path) in [
            ("drive_path", &self.drive_path),
            ("drive_loop", &self.drive_loop),
        ] {
            for (i, w) in path.iter().enumerate() {
                if !self.contains(w[0], w[1], 0.0) {
                    return Err(format!("{name}[{i}] {w:?} is outside the room"));
                }
            }
        }
        if (1..3).contains(&self.drive_loop.len()) {
            return Err("drive_loop needs at least 3 waypoints".into());
        }
        if !self.contains(self.nav_goal[0], self.nav_goal[1], 0.0) {
            return Err(format!("nav_goal {:?} is outside the room", self.nav_goal));
        }
        Ok(())
    }
}

/// Finite and above zero.
fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// Runs `check` on every item of a list of obstacles, naming a failing one `list[i]`.
fn check_each<T>(
    list: &str,
    items: &[T],
    check: impl Fn(&T) -> Result<(), String>,
) -> Result<(), String> {
    for (i, item) in items.iter().enumerate() {
        check(item).map_err(|e| format!("{list}[{i}]: {e}"))?;
    }
    Ok(())
}

/// A height range must be finite and increasing.
fn check_range(z: &[f64; 2]) -> Result<(), String> {
    if z[0].is_finite() && z[1].is_finite() && z[0] < z[1] {
        Ok(())
    } else {
        Err(format!("z_m {z:?} must be finite with z_min < z_max"))
    }
}

/// What boxes and ramps (both rotated rectangles standing on a height range) must satisfy.
fn check_footprint(z_m: &[f64; 2], size_m: [f64; 2], yaw_rad: f64) -> Result<(), String> {
    check_range(z_m)?;
    let ok = positive(size_m[0]) && positive(size_m[1]) && yaw_rad.is_finite();
    require(ok, "size_m must be positive")
}

/// `Err(what)` unless `ok`.
fn require(ok: bool, what: &str) -> Result<(), String> {
    if ok {
        Ok(())
    } else {
        Err(what.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_world_parses() {
        for name in BUILTIN_WORLDS {
            let w = World::builtin(name).unwrap();
            assert_eq!(w.name, name);
            assert!(w.boxes.len() + w.cylinders.len() >= 4, "{name}");
        }
        let large = World::builtin("large").unwrap();
        assert_eq!((large.size_m, large.height_m), ([10.0, 10.0], 2.4));
        assert!(!large.ramps.is_empty());
        let office = World::builtin("office").unwrap();
        assert_eq!((office.size_m, office.height_m), ([12.9, 7.7], 2.5));
        let small = World::builtin("small").unwrap();
        assert_eq!((small.size_m, small.height_m), ([5.0, 5.0], 1.0));
    }

    const MINIMAL: &str = r#"
        name = "t"
        size_m = [4.0, 3.0]
        height_m = 2.0
        flight_path = [[1.0, 1.0, 0.5, 0.0], [2.0, 1.0, 0.5, 0.0]]
        drive_path = [[1.0, 1.0], [2.0, 1.0]]
        nav_goal = [3.0, 2.0]
    "#;

    #[test]
    fn unknown_fields_and_bad_geometry_are_errors() {
        assert!(World::from_toml(MINIMAL, "t").is_ok());
        let typo = format!("{MINIMAL}\nheigth_m = 2.0");
        let err = World::from_toml(&typo, "t").unwrap_err();
        assert!(err.to_string().contains("heigth_m"), "{err}");
        let bad_box =
            format!("{MINIMAL}\n[[boxes]]\ncenter = [1, 1]\nsize_m = [1, 1]\nz_m = [1, 0.5]");
        let err = World::from_toml(&bad_box, "t").unwrap_err();
        assert!(matches!(err, SimError::InvalidWorld { .. }));
        assert!(
            err.to_string().contains("boxes[0]: z_m [1.0, 0.5]"),
            "{err}"
        );
        let outside = MINIMAL.replace("[3.0, 2.0]", "[5.0, 2.0]");
        assert!(World::from_toml(&outside, "t").is_err());
        let err = World::from_toml("garbage = [", "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 1") && !err.contains('\n'), "{err}");
        let err = World::by_name_or_file("/nonexistent/world.toml").unwrap_err();
        assert!(
            err.to_string().contains("/nonexistent/world.toml")
                && err.to_string().contains("No such file"),
            "{err}"
        );
        assert!(matches!(
            World::by_name_or_file("nowhere"),
            Err(SimError::UnknownWorld { .. })
        ));
    }
}
