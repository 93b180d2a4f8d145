//! The world compiled for ray casting: every obstacle is a convex polyhedron (an intersection
//! of half-spaces: boxes, walls, ramps) or a vertical cylinder, behind an axis-aligned bounding
//! box test; the room is cast from the inside.
//!
//! Ray–polyhedron intersection is the Cyrus–Beck clipping of the ray against each face plane
//! (Cyrus & Beck, "Generalized two- and three-dimensional clipping", Computers & Graphics 3(1),
//! 1978); boxes use the slab test of Kay & Kajiya ("Ray tracing complex scenes", SIGGRAPH 1986).
//! Every sensor (lidar, range finder, depth and colour cameras) shares [`Scene::cast`].

use crate::texture::Texture;
use crate::world::World;
use nalgebra::{Point3, Vector2, Vector3};

/// Distances below this count as "at the ray origin" \[m\].
const EPS_M: f64 = 1e-9;

/// Where a ray meets the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray \[m\]; 0 when the ray starts inside an obstacle.
    pub distance_m: f64,
    /// The hit point in the world frame \[m\].
    pub point: Point3<f64>,
    /// Unit surface normal at the hit, pointing out of the surface towards free space.
    pub normal: Vector3<f64>,
    /// Index of the surface's texture in [`Scene::textures`].
    pub surface: usize,
}

/// A half-space `normal · p <= offset` (unit outward normal).
#[derive(Debug, Clone, Copy)]
struct Plane {
    normal: Vector3<f64>,
    offset: f64,
}

#[derive(Debug, Clone)]
enum Shape {
    Convex(Vec<Plane>),
    Cylinder {
        center: Vector2<f64>,
        radius_m: f64,
        z_m: [f64; 2],
    },
}

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy)]
struct Aabb {
    min: Vector3<f64>,
    max: Vector3<f64>,
}

#[derive(Debug, Clone)]
struct Solid {
    shape: Shape,
    bounds: Aabb,
    surface: usize,
}

/// Surface indices of the room; obstacles follow.
const FLOOR: usize = 0;
const CEILING: usize = 1;
const ROOM_WALLS: usize = 2;

/// Direction the light comes from, for Lambertian shading (up and slightly sideways).
const LIGHT: [f64; 3] = [0.3, 0.5, 0.81];

/// A world ready for ray casting.
#[derive(Debug, Clone)]
pub struct Scene {
    solids: Vec<Solid>,
    room: Aabb,
    /// Texture of each surface: floor, ceiling, room walls, then one per obstacle.
    pub textures: Vec<Texture>,
}

impl Scene {
    /// Compiles the world's primitives into polyhedra and cylinders.
    pub fn new(world: &World) -> Scene {
        let mut textures = vec![
            world.floor_texture.clone(),
            world.ceiling_texture.clone(),
            world.wall_texture.clone(),
        ];
        let mut solids = Vec::new();
        let mut add = |shape: Shape, bounds: Aabb, texture: &Option<Texture>| {
            let index = solids.len();
            textures.push(texture.clone().unwrap_or_else(|| Texture::obstacle(index)));
            solids.push(Solid {
                shape,
                bounds,
                surface: textures.len() - 1,
            });
        };
        for w in &world.walls {
            let from = Vector2::from(w.from);
            let along = Vector2::from(w.to) - from;
            let center = from + along * 0.5;
            let yaw = along.y.atan2(along.x);
            let half = [along.norm() / 2.0, w.thickness_m / 2.0];
            let (planes, bounds) = prism(center, half, yaw, w.z_m, false);
            add(Shape::Convex(planes), bounds, &w.texture);
        }
        for b in &world.boxes {
            let half = [b.size_m[0] / 2.0, b.size_m[1] / 2.0];
            let (planes, bounds) = prism(b.center.into(), half, b.yaw_rad, b.z_m, false);
            add(Shape::Convex(planes), bounds, &b.texture);
        }
        for r in &world.ramps {
            let half = [r.size_m[0] / 2.0, r.size_m[1] / 2.0];
            let (planes, bounds) = prism(r.center.into(), half, r.yaw_rad, r.z_m, true);
            add(Shape::Convex(planes), bounds, &r.texture);
        }
        for c in &world.cylinders {
            let (center, radius_m) = (Vector2::from(c.center), c.radius_m);
            let bounds = Aabb {
                min: Vector3::new(center.x - radius_m, center.y - radius_m, c.z_m[0]),
                max: Vector3::new(center.x + radius_m, center.y + radius_m, c.z_m[1]),
            };
            let shape = Shape::Cylinder {
                center,
                radius_m,
                z_m: c.z_m,
            };
            add(shape, bounds, &c.texture);
        }
        let room = Aabb {
            min: Vector3::zeros(),
            max: Vector3::new(world.size_m[0], world.size_m[1], world.height_m),
        };
        Scene {
            solids,
            room,
            textures,
        }
    }

    /// The first surface hit by the ray `origin + t·direction`, `0 <= t <= max_m`.
    ///
    /// `direction` must be a unit vector. Rays leaving the room are stopped by its walls, floor
    /// or ceiling, so a ray from inside the room hits something unless `max_m` is short.
    pub fn cast(&self, origin: &Point3<f64>, direction: &Vector3<f64>, max_m: f64) -> Option<Hit> {
        self.cast_among(origin, direction, max_m, 0..self.solids.len())
    }

    /// [`Scene::cast`] testing only the obstacles numbered `candidates` (and the room), for
    /// callers that have culled the others, such as a camera that knows which obstacles can be
    /// in a pixel's view ([`Scene::obstacle_bounds`]).
    pub fn cast_among(
        &self,
        origin: &Point3<f64>,
        direction: &Vector3<f64>,
        max_m: f64,
        candidates: impl IntoIterator<Item = usize>,
    ) -> Option<Hit> {
        let o = origin.coords;
        let inv = direction.map(|d| 1.0 / d);
        let mut best: Option<(f64, Vector3<f64>, usize)> = room_exit(&self.room, &o, direction);
        let mut limit = best.map_or(max_m, |(t, _, _)| t.min(max_m));
        for solid in candidates.into_iter().filter_map(|i| self.solids.get(i)) {
            if !slab_overlaps(&solid.bounds, &o, &inv, limit) {
                continue;
            }
            let entry = match &solid.shape {
                Shape::Convex(planes) => convex_entry(planes, &o, direction),
                Shape::Cylinder {
                    center,
                    radius_m,
                    z_m,
                } => cylinder_entry(center, *radius_m, z_m, &o, direction),
            };
            if let Some((t, normal)) = entry {
                if t <= limit {
                    limit = t;
                    best = Some((t, normal, solid.surface));
                }
            }
        }
        let (t, normal, surface) = best?;
        (t <= max_m).then(|| Hit {
            distance_m: t,
            point: Point3::from(o + direction * t),
            normal,
            surface,
        })
    }

    /// The axis-aligned bounding box `(min, max)` of every obstacle, in the numbering of
    /// [`Scene::cast_among`] \[m\].
    pub fn obstacle_bounds(&self) -> impl Iterator<Item = (Point3<f64>, Point3<f64>)> + '_ {
        self.solids
            .iter()
            .map(|s| (Point3::from(s.bounds.min), Point3::from(s.bounds.max)))
    }

    /// True when a sphere of `radius_m` around `p` leaves the room or touches an obstacle
    /// (checked at its centre and its six axis extremes).
    pub fn collides(&self, p: &Point3<f64>, radius_m: f64) -> bool {
        let offsets = [Vector3::zeros()]
            .into_iter()
            .chain((0..3).flat_map(|a| [1.0, -1.0].map(|s| Vector3::ith(a, s * radius_m))));
        offsets.into_iter().any(|d| {
            let q = p.coords + d;
            let in_room = (0..3).all(|a| q[a] > self.room.min[a] && q[a] < self.room.max[a]);
            !in_room || self.solids.iter().any(|s| solid_contains(&s.shape, &q))
        })
    }

    /// Colour of the surface at a hit, each channel in `\[0, 1\]`: the texture's albedo with
    /// Lambertian shading (ambient 0.55, diffuse 0.45).
    pub fn shade(&self, hit: &Hit) -> [f32; 3] {
        let (u, v) = surface_uv(hit, &self.solids, &self.textures);
        let albedo = self
            .textures
            .get(hit.surface)
            .map_or([0.5; 3], |t| t.albedo(u, v));
        let light = Vector3::from(LIGHT).normalize();
        let lambert = (0.55 + 0.45 * hit.normal.dot(&light).max(0.0)) as f32;
        albedo.map(|a| a * lambert)
    }
}

/// A vertical prism over a rotated rectangle (`half` sizes along its own x and y); with
/// `sloped`, the top face slopes up along x from `z_m\[0\]` to `z_m\[1\]` instead of being flat.
fn prism(
    center: Vector2<f64>,
    half: [f64; 2],
    yaw_rad: f64,
    z_m: [f64; 2],
    sloped: bool,
) -> (Vec<Plane>, Aabb) {
    let (s, c) = yaw_rad.sin_cos();
    let ex = Vector3::new(c, s, 0.0);
    let ey = Vector3::new(-s, c, 0.0);
    let c3 = Vector3::new(center.x, center.y, 0.0);
    let mut planes = Vec::with_capacity(6);
    for (axis, h) in [(ex, half[0]), (ey, half[1])] {
        planes.push(Plane {
            normal: axis,
            offset: axis.dot(&c3) + h,
        });
        planes.push(Plane {
            normal: -axis,
            offset: -axis.dot(&c3) + h,
        });
    }
    planes.push(Plane {
        normal: -Vector3::z(),
        offset: -z_m[0],
    });
    let top = if !sloped {
        Plane {
            normal: Vector3::z(),
            offset: z_m[1],
        }
    } else {
        // z <= z0 + k (x_local + L/2), x_local = ex · (p - c)
        let k = (z_m[1] - z_m[0]) / (2.0 * half[0]);
        let n = Vector3::z() - ex * k;
        let offset = z_m[0] + k * half[0] - k * ex.dot(&c3);
        let norm = n.norm();
        Plane {
            normal: n / norm,
            offset: offset / norm,
        }
    };
    planes.push(top);
    let reach_x = half[0] * c.abs() + half[1] * s.abs();
    let reach_y = half[0] * s.abs() + half[1] * c.abs();
    let bounds = Aabb {
        min: Vector3::new(center.x - reach_x, center.y - reach_y, z_m[0]),
        max: Vector3::new(center.x + reach_x, center.y + reach_y, z_m[1]),
    };
    (planes, bounds)
}

/// Where a ray from inside the room leaves it: distance and inward normal.
fn room_exit(
    room: &Aabb,
    o: &Vector3<f64>,
    d: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>, usize)> {
    let mut best: Option<(f64, Vector3<f64>, usize)> = None;
    for axis in 0..3 {
        let (t, sign) = if d[axis] > 0.0 {
            ((room.max[axis] - o[axis]) / d[axis], -1.0)
        } else if d[axis] < 0.0 {
            ((room.min[axis] - o[axis]) / d[axis], 1.0)
        } else {
            continue;
        };
        if best.map_or(true, |(b, _, _)| t < b) {
            let surface = match (axis, sign > 0.0) {
                (2, true) => FLOOR,
                (2, false) => CEILING,
                _ => ROOM_WALLS,
            };
            best = Some((t.max(0.0), Vector3::ith(axis, sign), surface));
        }
    }
    best
}

/// Slab test: does the ray meet the box for some `t` in `\[0, limit\]`?
fn slab_overlaps(b: &Aabb, o: &Vector3<f64>, inv: &Vector3<f64>, limit: f64) -> bool {
    let (mut t0, mut t1) = (0.0f64, limit);
    for a in 0..3 {
        let ta = (b.min[a] - o[a]) * inv[a];
        let tb = (b.max[a] - o[a]) * inv[a];
        // NaN (0 · ∞, ray in the slab's plane) compares false and leaves the interval as is.
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// Cyrus–Beck: entry distance and face normal of the ray into a convex polyhedron.
fn convex_entry(
    planes: &[Plane],
    o: &Vector3<f64>,
    d: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>)> {
    let (mut enter, mut exit) = (f64::NEG_INFINITY, f64::INFINITY);
    let mut normal = -d;
    for p in planes {
        let denom = p.normal.dot(d);
        let dist = p.offset - p.normal.dot(o);
        if denom.abs() < 1e-15 {
            if dist < 0.0 {
                return None;
            }
            continue;
        }
        let t = dist / denom;
        if denom < 0.0 {
            if t > enter {
                enter = t;
                normal = p.normal;
            }
        } else {
            exit = exit.min(t);
        }
        if enter > exit {
            return None;
        }
    }
    entry_of(enter, exit, normal, d)
}

/// Entry distance and normal of a ray into a vertical cylinder with flat caps.
fn cylinder_entry(
    center: &Vector2<f64>,
    radius_m: f64,
    z_m: &[f64; 2],
    o: &Vector3<f64>,
    d: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>)> {
    let (ox, oy) = (o.x - center.x, o.y - center.y);
    let a = d.x * d.x + d.y * d.y;
    let c = ox * ox + oy * oy - radius_m * radius_m;
    let (side0, side1) = if a < 1e-18 {
        if c > 0.0 {
            return None;
        }
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        let b = ox * d.x + oy * d.y;
        let disc = b * b - a * c;
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        ((-b - sq) / a, (-b + sq) / a)
    };
    let (cap0, cap1) = if d.z.abs() < 1e-15 {
        if o.z < z_m[0] || o.z > z_m[1] {
            return None;
        }
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        let ta = (z_m[0] - o.z) / d.z;
        let tb = (z_m[1] - o.z) / d.z;
        (ta.min(tb), ta.max(tb))
    };
    let enter = side0.max(cap0);
    let exit = side1.min(cap1);
    if enter > exit {
        return None;
    }
    let normal = if side0 >= cap0 {
        let p = o + d * enter;
        Vector3::new(p.x - center.x, p.y - center.y, 0.0) / radius_m
    } else {
        Vector3::new(0.0, 0.0, -d.z.signum())
    };
    entry_of(enter, exit, normal, d)
}

/// Turns an entry/exit interval into a hit: at the entry when ahead, at 0 when the origin is
/// inside, none when the solid is behind.
fn entry_of(
    enter: f64,
    exit: f64,
    normal: Vector3<f64>,
    d: &Vector3<f64>,
) -> Option<(f64, Vector3<f64>)> {
    if exit < EPS_M {
        None
    } else if enter > EPS_M {
        Some((enter, normal))
    } else {
        Some((0.0, -d))
    }
}

fn solid_contains(shape: &Shape, q: &Vector3<f64>) -> bool {
    match shape {
        Shape::Convex(planes) => planes.iter().all(|p| p.normal.dot(q) <= p.offset),
        Shape::Cylinder {
            center,
            radius_m,
            z_m,
        } => {
            (q.x - center.x).powi(2) + (q.y - center.y).powi(2) <= radius_m * radius_m
                && q.z >= z_m[0]
                && q.z <= z_m[1]
        }
    }
}

/// Texture coordinates of a hit \[m\]: arc length and height on cylinder sides, else the
/// world coordinates across the dominant axis of the normal.
fn surface_uv(hit: &Hit, solids: &[Solid], textures: &[Texture]) -> (f64, f64) {
    let p = hit.point;
    let first_obstacle = textures.len() - solids.len();
    let solid = hit
        .surface
        .checked_sub(first_obstacle)
        .and_then(|i| solids.get(i));
    if let Some(Solid {
        shape: Shape::Cylinder {
            center, radius_m, ..
        },
        ..
    }) = solid
    {
        if hit.normal.z.abs() < 0.5 {
            let angle = (p.y - center.y).atan2(p.x - center.x);
            return (angle * radius_m, p.z);
        }
    }
    let n = hit.normal.abs();
    if n.z >= n.x && n.z >= n.y {
        (p.x, p.y)
    } else if n.x >= n.y {
        (p.y, p.z)
    } else {
        (p.x, p.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn world(extra: &str) -> World {
        let text = format!(
            "name = \"t\"\nsize_m = [10.0, 8.0]\nheight_m = 3.0\n\
             flight_path = [[1, 1, 1, 0], [2, 1, 1, 0]]\ndrive_path = [[1, 1], [2, 1]]\n\
             nav_goal = [2, 2]\n{extra}"
        );
        World::from_toml(&text, "t").unwrap()
    }

    #[test]
    fn room_wall_at_known_angle() {
        let scene = Scene::new(&world(""));
        let o = Point3::new(2.0, 3.0, 1.0);
        // wall x = 10 seen at 30 degrees: distance 8 / cos 30
        let a = 30f64.to_radians();
        let hit = scene
            .cast(&o, &Vector3::new(a.cos(), a.sin(), 0.0), 20.0)
            .unwrap();
        assert!((hit.distance_m - 8.0 / a.cos()).abs() < 1e-12, "{hit:?}");
        assert_eq!(hit.normal, Vector3::new(-1.0, 0.0, 0.0));
        let down = scene.cast(&o, &-Vector3::z(), 20.0).unwrap();
        assert_eq!((down.distance_m, down.surface), (1.0, FLOOR));
        let up = scene.cast(&o, &Vector3::z(), 20.0).unwrap();
        assert_eq!((up.distance_m, up.surface), (2.0, CEILING));
        assert!(scene.cast(&o, &Vector3::z(), 1.5).is_none());
    }

    #[test]
    fn rotated_box_cylinder_and_ramp() {
        let scene = Scene::new(&world(
            "[[boxes]]\ncenter = [5, 4]\nsize_m = [2, 2]\nyaw_rad = 0.7853981633974483\nz_m = [0, 1]\n\
             [[cylinders]]\ncenter = [5, 1]\nradius_m = 0.5\nz_m = [0, 2]\n\
             [[ramps]]\ncenter = [8, 4]\nsize_m = [2, 1]\nz_m = [0, 1]\n",
        ));
        // box rotated 45 degrees: its corner points at -x, at 5 - sqrt(2)
        let o = Point3::new(1.0, 4.0, 0.5);
        let hit = scene.cast(&o, &Vector3::x(), 20.0).unwrap();
        assert!(
            (hit.distance_m - (4.0 - 2f64.sqrt())).abs() < 1e-9,
            "{hit:?}"
        );
        // at z = 1.5 the ray clears the box and the ramp (both 1 m high) and meets the wall
        let high = scene
            .cast(&Point3::new(1.0, 4.0, 1.5), &Vector3::x(), 20.0)
            .unwrap();
        assert!((high.distance_m - 9.0).abs() < 1e-9);
        // cylinder side
        let c = scene
            .cast(&Point3::new(1.0, 1.0, 1.0), &Vector3::x(), 20.0)
            .unwrap();
        assert!((c.distance_m - 3.5).abs() < 1e-9);
        assert!((c.normal - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-9);
        // cylinder top seen from above
        let top = scene
            .cast(&Point3::new(5.2, 1.0, 2.9), &-Vector3::z(), 20.0)
            .unwrap();
        assert!((top.distance_m - 0.9).abs() < 1e-9 && top.normal.z == 1.0);
        // ramp rises from z 0 at x = 7 to z 1 at x = 9: above x = 8.5 the top is at 0.75
        let r = scene
            .cast(&Point3::new(8.5, 4.0, 2.0), &-Vector3::z(), 20.0)
            .unwrap();
        assert!((r.distance_m - 1.25).abs() < 1e-9, "{r:?}");
        assert!(r.normal.x < 0.0 && r.normal.z > 0.0);
        // inside an obstacle: distance 0
        let inside = scene
            .cast(&Point3::new(5.0, 4.0, 0.5), &Vector3::x(), 20.0)
            .unwrap();
        assert_eq!(inside.distance_m, 0.0);
        assert!(scene.collides(&Point3::new(5.0, 1.6, 1.0), 0.2));
        assert!(!scene.collides(&Point3::new(5.0, 1.8, 1.0), 0.2));
    }

    #[test]
    fn shading_is_in_unit_range() {
        let scene = Scene::new(&world(""));
        let hit = scene
            .cast(&Point3::new(2.0, 2.0, 1.0), &-Vector3::z(), 5.0)
            .unwrap();
        let rgb = scene.shade(&hit);
        assert!(rgb.iter().all(|c| (0.0..=1.0).contains(c)));
    }
}
