//! The harder scene of the sphere-calib simulation ([`crate::sphere_calib`],
//! `SphereScene::Cluttered`): what makes real photographs of a calibration sphere hard.
//!
//! * **The sphere is shaded**: Lambertian under a light from above and to one side
//!   ([`LIGHT`]) with ambient light, and a specular highlight (Blinn–Phong), so its lower
//!   half is dark, the top bright and the outline's contrast changes sign around it.
//! * **A stand** under it: a seat (a vertical cylinder of 0.55 r, 60 mm thick) into which
//!   the sphere sinks by 8 % of its radius, covering the bottom of its outline, on a pole of
//!   25 mm radius down to the floor. The lidar sees both.
//! * **A textured background**: the wall of bricks (240 × 70 mm, 10 mm of bright mortar,
//!   each brick its own albedo), the floor of tiles (400 mm, 8 mm grout).
//! * **Bright distractors**: round bright plates and a bright window on the wall, a bright
//!   round marking on the floor (round outlines of about the sphere's size at the wall's
//!   distance).
//!
//! The albedos and places come from the seed ([`crate::rng_for`]); the same seed gives the
//! same scene.

use crate::rng_for;
use nalgebra::Vector3;
use rand::Rng;

type V3 = Vector3<f64>;

/// The light's direction (towards the light), lidar frame (x forward, y left, z up).
pub const LIGHT: [f64; 3] = [-0.35, 0.45, 1.0];

/// Radius of the seat under the sphere, in sphere radii.
pub const SEAT_RADIUS: f64 = 0.55;
/// How far the sphere sinks into the seat, in sphere radii.
pub const SEAT_SINK: f64 = 0.08;
/// The seat's thickness, mm.
pub const SEAT_THICKNESS_MM: f64 = 60.0;
/// The pole's radius, mm.
pub const POLE_RADIUS_MM: f64 = 25.0;

/// What a ray hits in the cluttered scene (beyond the sphere, floor and wall).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// The seat under the sphere.
    Seat,
    /// The pole.
    Pole,
}

/// A round bright plate on the wall or the floor: its centre and radius, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plate {
    /// Centre (on the wall: x = wall; on the floor: z = floor).
    pub centre: V3,
    /// Radius, mm.
    pub radius: f64,
    /// Its radiance.
    pub radiance: f64,
}

/// The clutter of one data set.
#[derive(Clone, Debug)]
pub struct Clutter {
    /// The wall's plates.
    pub plates: Vec<Plate>,
    /// The floor's round marking.
    pub marking: Plate,
    /// A bright window on the wall: (y0, y1, z0, z1), mm.
    pub window: [f64; 4],
    /// Seed of the texture's albedos.
    pub seed: u64,
}

impl Clutter {
    /// The clutter for `seed`, a wall at `wall_mm` and a floor at `floor_z` (lidar frame).
    pub fn new(seed: u64, wall_mm: f64, floor_z: f64, sphere_radius: f64) -> Self {
        let mut rng = rng_for(seed, "sphere-calib-clutter", 0);
        let plates: Vec<Plate> = (0..4)
            .map(|_| Plate {
                centre: V3::new(
                    wall_mm,
                    rng.random_range(-7000.0..7000.0),
                    rng.random_range(floor_z + 600.0..floor_z + 3200.0),
                ),
                radius: sphere_radius * rng.random_range(0.6..1.4),
                radiance: rng.random_range(0.85..1.0),
            })
            .collect();
        let marking = Plate {
            centre: V3::new(
                rng.random_range(2000.0..6000.0),
                rng.random_range(-2500.0..2500.0),
                floor_z,
            ),
            radius: sphere_radius * rng.random_range(1.0..1.8),
            radiance: 0.8,
        };
        let y0 = rng.random_range(-6000.0..4000.0);
        let z0 = floor_z + rng.random_range(400.0..1200.0);
        Clutter {
            plates,
            marking,
            window: [y0, y0 + 1500.0, z0, z0 + 1800.0],
            seed,
        }
    }
}

/// A hash of integers to [0, 1) (for the textures' albedos).
fn hash01(seed: u64, a: i64, b: i64) -> f64 {
    let mut z = seed
        ^ (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// The nearest hit (t, part) of the ray `o + t·d` with the stand of a sphere at `c` of
/// radius `r` over a floor at `floor_z`.
pub fn hit_stand(o: &V3, d: &V3, c: &V3, r: f64, floor_z: f64) -> Option<(f64, Part)> {
    let top = c.z - r * (1.0 - SEAT_SINK);
    let seat = hit_cylinder(o, d, c, SEAT_RADIUS * r, top - SEAT_THICKNESS_MM, top)
        .map(|t| (t, Part::Seat));
    let pole = hit_cylinder(o, d, c, POLE_RADIUS_MM, floor_z, top - SEAT_THICKNESS_MM)
        .map(|t| (t, Part::Pole));
    match (seat, pole) {
        (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
        (a, b) => a.or(b),
    }
}

/// The nearest hit of the ray with the closed vertical cylinder of axis through `c`
/// (x, y), radius `rad`, between heights `z0` and `z1`.
fn hit_cylinder(o: &V3, d: &V3, c: &V3, rad: f64, z0: f64, z1: f64) -> Option<f64> {
    let (ox, oy) = (o.x - c.x, o.y - c.y);
    let a = d.x * d.x + d.y * d.y;
    let mut best: Option<f64> = None;
    let mut take = |t: f64| {
        if t > 1e-6 && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    };
    if a > 1e-12 {
        let b = ox * d.x + oy * d.y;
        let disc = b * b - a * (ox * ox + oy * oy - rad * rad);
        if disc >= 0.0 {
            for t in [(-b - disc.sqrt()) / a, (-b + disc.sqrt()) / a] {
                let z = o.z + t * d.z;
                if z >= z0 && z <= z1 {
                    take(t);
                }
            }
        }
    }
    if d.z.abs() > 1e-12 {
        for zc in [z0, z1] {
            let t = (zc - o.z) / d.z;
            let (x, y) = (ox + t * d.x, oy + t * d.y);
            if x * x + y * y <= rad * rad {
                take(t);
            }
        }
    }
    best
}

/// The radiance of the shaded sphere (centre `c`) at surface point `p`, seen from `eye`.
pub fn sphere_radiance(p: &V3, c: &V3, eye: &V3) -> f64 {
    let n = (p - c).normalize();
    let l = V3::from(LIGHT).normalize();
    let v = (eye - p).normalize();
    let h = (l + v).normalize();
    let diffuse = n.dot(&l).max(0.0);
    let spec = n.dot(&h).max(0.0).powi(60);
    0.7 * (0.22 + 0.78 * diffuse) + 0.5 * spec
}

/// The radiance of the stand's `part` (dark fabric and a black pole).
pub fn stand_radiance(part: Part) -> f64 {
    match part {
        Part::Seat => 0.09,
        Part::Pole => 0.04,
    }
}

/// The radiance of the wall (plane x = wall) at `p` under the scene's light: bricks with
/// bright mortar, the plates and the window.
pub fn wall_radiance(cl: &Clutter, p: &V3, lit: f64) -> f64 {
    for pl in &cl.plates {
        if (p - pl.centre).norm() <= pl.radius {
            return pl.radiance;
        }
    }
    let [y0, y1, z0, z1] = cl.window;
    if p.y >= y0 && p.y <= y1 && p.z >= z0 && p.z <= z1 {
        return 0.95;
    }
    let (bw, bh, m) = (250.0, 80.0, 10.0);
    let row = (p.z / bh).floor();
    let shift = if (row as i64).rem_euclid(2) == 0 {
        0.0
    } else {
        bw / 2.0
    };
    let col = ((p.y + shift) / bw).floor();
    let (u, v) = ((p.y + shift) - col * bw, p.z - row * bh);
    let albedo = if u < m || v < m {
        0.62
    } else {
        0.22 + 0.2 * hash01(cl.seed, col as i64, row as i64)
    };
    albedo * lit
}

/// The radiance of the floor (plane z = floor) at `p`: tiles with grout, the marking.
pub fn floor_radiance(cl: &Clutter, p: &V3, lit: f64) -> f64 {
    let m = &cl.marking;
    if (p.x - m.centre.x).hypot(p.y - m.centre.y) <= m.radius {
        return m.radiance * lit.max(0.6);
    }
    let t = 400.0;
    let (i, j) = ((p.x / t).floor(), (p.y / t).floor());
    let (u, v) = (p.x - i * t, p.y - j * t);
    let albedo = if u < 8.0 || v < 8.0 {
        0.5
    } else {
        0.26 + 0.1 * hash01(cl.seed ^ 0x5555, i as i64, j as i64)
    };
    albedo * lit
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stand_is_under_the_sphere_and_hides_its_lowest_part() {
        let (c, r, floor) = (V3::new(3000.0, 0.0, 0.0), 300.0, -1100.0);
        // a ray straight down the axis meets the seat's top within the sphere's bottom cap
        let o = V3::new(3000.0, 0.0, -250.0);
        let (t, part) = hit_stand(&o, &-V3::z(), &c, r, floor).unwrap();
        assert_eq!(part, Part::Seat);
        assert!((o.z - t - (c.z - r * (1.0 - SEAT_SINK))).abs() < 1e-9);
        // a horizontal ray at the pole's height meets the pole at its radius
        let o = V3::new(0.0, 0.0, -800.0);
        let (t, part) = hit_stand(&o, &V3::x(), &c, r, floor).unwrap();
        assert_eq!(part, Part::Pole);
        assert!((t - (3000.0 - POLE_RADIUS_MM)).abs() < 1e-9);
        // beside the stand: nothing
        assert!(hit_stand(&V3::new(0.0, 500.0, -800.0), &V3::x(), &c, r, floor).is_none());
    }
}
