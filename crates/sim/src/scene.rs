//! The test field: a room corner (two walls and the floor, each slightly tilted and
//! bulged), retro-reflective targets printed on them, ping-pong balls on stems, and the
//! caliper distances; plus the ray casting that the renderer and the LRF share.
//!
//! World frame: origin at the corner's vertex (where the three planes meet), X along the
//! floor edge of wall 1, Y along the floor edge of wall 2, Z up; the room is x, y, z > 0.
//! Because the planes are tilted by a few tenths of a degree, the edges are only close to
//! the axes, and the planes are not exactly orthogonal.

use crate::coded_target;
use crate::config::{BallConfig, ConfigError, RoomConfig, SimConfig, TargetConfig};
use crate::head::CameraUnit;
use crate::{rng_for, SimError};
use nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_geometry::from_opk;
use pingcal_geometry::Rigid3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

type V3 = Vector3<f64>;

/// One of the three planes of the corner, as a bulged parallelogram:
/// `p(u, v) = origin + u·a + v·b + h(u, v)·n`, with `h` a pillow of height `bulge_mm`
/// that vanishes on the edges (so neighbouring planes meet exactly along their edges).
#[derive(Debug, Clone)]
pub struct Surface {
    /// `wall1`, `wall2` or `floor`.
    pub name: String,
    /// The corner point (u = v = 0).
    pub origin: V3,
    /// First edge direction (unit).
    pub a: V3,
    /// Second edge direction (unit, not necessarily orthogonal to `a`).
    pub b: V3,
    /// Unit normal of the base plane, pointing into the room.
    pub n: V3,
    /// Extent along `a`.
    pub u_max: f64,
    /// Extent along `b`.
    pub v_max: f64,
    /// Height of the bulge at the centre (signed, along `n`).
    pub bulge_mm: f64,
    /// Mean diffuse albedo.
    pub albedo: f64,
    /// Relative texture amplitude.
    pub texture: f64,
    /// Texture seed.
    pub texture_seed: u64,
    inv: Option<Matrix3<f64>>,
}

impl Surface {
    /// A surface from its corner, edge directions (normalised here), extents and normal
    /// (`n` is normalised and must not be parallel to the plane).
    // Every argument is one independent field of the surface (the constructor only
    // normalises and caches the inverse basis): grouping them would just rename them.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: &str,
        origin: V3,
        a: V3,
        b: V3,
        n: V3,
        u_max: f64,
        v_max: f64,
        bulge_mm: f64,
        albedo: f64,
        texture: f64,
        texture_seed: u64,
    ) -> Self {
        let mut s = Self {
            name: name.to_string(),
            origin,
            a: a.normalize(),
            b: b.normalize(),
            n: n.normalize(),
            u_max,
            v_max,
            bulge_mm,
            albedo,
            texture,
            texture_seed,
            inv: None,
        };
        s.inv = Matrix3::from_columns(&[s.a, s.b, s.n]).try_inverse();
        s
    }

    fn inv(&self) -> Matrix3<f64> {
        self.inv
            .or_else(|| Matrix3::from_columns(&[self.a, self.b, self.n]).try_inverse())
            .expect("surface basis is invertible")
    }

    /// Bulge height h(u, v) and its gradient.
    pub fn height(&self, u: f64, v: f64) -> (f64, f64, f64) {
        if self.bulge_mm == 0.0 || !(u > 0.0 && u < self.u_max && v > 0.0 && v < self.v_max) {
            return (0.0, 0.0, 0.0);
        }
        let (s, q) = (u / self.u_max, v / self.v_max);
        let (fs, fq) = (s * (1.0 - s), q * (1.0 - q));
        let h = 16.0 * self.bulge_mm * fs * fq;
        let hu = 16.0 * self.bulge_mm * (1.0 - 2.0 * s) / self.u_max * fq;
        let hv = 16.0 * self.bulge_mm * fs * (1.0 - 2.0 * q) / self.v_max;
        (h, hu, hv)
    }

    /// The surface point at (u, v).
    pub fn point(&self, u: f64, v: f64) -> V3 {
        self.origin + self.a * u + self.b * v + self.n * self.height(u, v).0
    }

    /// The unit surface normal at (u, v) (towards the room).
    pub fn normal(&self, u: f64, v: f64) -> V3 {
        let (_, hu, hv) = self.height(u, v);
        let tu = self.a + self.n * hu;
        let tv = self.b + self.n * hv;
        let m = tu.cross(&tv).normalize();
        if m.dot(&self.n) < 0.0 {
            -m
        } else {
            m
        }
    }

    /// (u, v, w): coordinates of `p` in the basis (a, b, n) from the origin.
    pub fn coords(&self, p: &V3) -> V3 {
        self.inv() * (p - self.origin)
    }

    /// Signed distance of `p` from the base plane (positive inside the room).
    pub fn plane_distance(&self, p: &V3) -> f64 {
        (p - self.origin).dot(&self.n)
    }

    /// Ray intersection: returns (t, u, v) of the nearest hit with t > `t_min`.
    pub fn intersect(&self, o: &V3, d: &V3, t_min: f64) -> Option<(f64, f64, f64)> {
        let dn = d.dot(&self.n);
        if dn.abs() < 1e-9 {
            return None;
        }
        let inv = self.inv();
        let mut t = (self.origin - o).dot(&self.n) / dn;
        // Fixed-point iteration on the height field: converges fast because |∇h| ≪ 1.
        let mut uvw = inv * (o + d * t - self.origin);
        // A bulge of b mm moves the hit by at most |b|/|cos i| along the plane: far outside
        // the extent, no hit is possible.
        let slack = 2.0 * self.bulge_mm.abs() / dn.abs() + 1.0;
        if !t.is_finite()
            || uvw.x < -slack
            || uvw.y < -slack
            || uvw.x > self.u_max + slack
            || uvw.y > self.v_max + slack
        {
            return None;
        }
        if self.bulge_mm != 0.0 {
            for _ in 0..20 {
                let h = self.height(uvw.x, uvw.y).0;
                let s = uvw.z - h;
                t -= s / dn;
                uvw = inv * (o + d * t - self.origin);
                if s.abs() < 1e-7 {
                    break;
                }
            }
        }
        if !t.is_finite()
            || t <= t_min
            || uvw.x < 0.0
            || uvw.y < 0.0
            || uvw.x > self.u_max
            || uvw.y > self.v_max
        {
            return None;
        }
        Some((t, uvw.x, uvw.y))
    }

    /// Albedo at (u, v): the mean albedo modulated by a procedural matt-paint texture.
    pub fn albedo_at(&self, u: f64, v: f64) -> f64 {
        if self.texture == 0.0 {
            return self.albedo;
        }
        let n = 0.5 * value_noise(u / 3.0, v / 3.0, self.texture_seed)
            + 0.3 * value_noise(u / 17.0, v / 17.0, self.texture_seed ^ 0x9e37)
            + 0.2 * value_noise(u / 90.0, v / 90.0, self.texture_seed ^ 0x7f4a);
        (self.albedo * (1.0 + self.texture * 2.0 * (n - 0.5))).clamp(0.0, 1.0)
    }
}

fn hash2(ix: i64, iy: i64, seed: u64) -> f64 {
    let mut h = (ix as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ seed;
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h = h.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth 2D value noise in [0, 1].
fn value_noise(x: f64, y: f64, seed: u64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let (tx, ty) = (x - fx, y - fy);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let a = hash2(ix, iy, seed);
    let b = hash2(ix + 1, iy, seed);
    let c = hash2(ix, iy + 1, seed);
    let d = hash2(ix + 1, iy + 1, seed);
    (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy
}

/// A printed retro-reflective target (a flat sticker in the tangent plane of its surface).
#[derive(Debug, Clone)]
pub struct Target {
    /// Target number: the AICON number for coded targets, 1001, 1002, … for plain ones.
    pub id: u32,
    /// The ring code value (smallest rotation), for coded targets.
    pub code: Option<u32>,
    /// Index of the surface it is stuck on.
    pub surface: usize,
    /// Centre of the dot (world).
    pub centre: V3,
    /// Unit normal (towards the room).
    pub normal: V3,
    /// In-plane axes: `t1 × t2 = normal`.
    pub t1: V3,
    /// Second in-plane axis.
    pub t2: V3,
    /// Radius of the dot.
    pub dot_radius: f64,
    /// Inner radius of the code ring.
    pub ring_inner: f64,
    /// Outer radius of the code ring.
    pub ring_outer: f64,
    /// Radius of the black background disc.
    pub background: f64,
    /// Rotation of the printed code (ψ in `coded_target`), radians.
    pub code_rotation: f64,
    /// Number of ring sectors.
    pub bits: u32,
}

impl Target {
    /// Whether the point with in-plane coordinates (x, y) from the centre is retro-reflective.
    pub fn is_retro(&self, x: f64, y: f64) -> bool {
        let r2 = x * x + y * y;
        if r2 <= self.dot_radius * self.dot_radius {
            return true;
        }
        let Some(code) = self.code else { return false };
        if r2 < self.ring_inner * self.ring_inner || r2 > self.ring_outer * self.ring_outer {
            return false;
        }
        coded_target::ring_is_retro(code, self.bits, self.code_rotation, x, y)
    }
}

/// A ping-pong ball on a stem standing off a surface along its normal.
#[derive(Debug, Clone)]
pub struct Ball {
    /// Ball number (1-based; the paper's labels).
    pub id: u32,
    /// Centre (world).
    pub centre: V3,
    /// Radius.
    pub radius: f64,
    /// Foot of the stem on the surface.
    pub foot: V3,
    /// Unit stem axis (from the foot towards the ball).
    pub axis: V3,
    /// Stem length (foot to ball centre).
    pub stem_length: f64,
    /// Stem radius.
    pub stem_radius: f64,
    /// Surface it stands on.
    pub surface: usize,
}

/// A measured distance between two coded targets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Distance {
    /// Target number of one end.
    pub from: u32,
    /// Target number of the other end.
    pub to: u32,
    /// True distance.
    pub true_mm: f64,
    /// Caliper reading (true + noise).
    pub measured_mm: f64,
    /// Caliper σ.
    pub sigma_mm: f64,
}

/// What a ray hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HitKind {
    /// A wall or the floor, at surface coordinates (u, v).
    Surface {
        /// Index in [`TestField::surfaces`] (wall1, wall2, floor).
        index: usize,
        /// mm along the surface's first edge `a` from its corner.
        u: f64,
        /// mm along its second edge `b`.
        v: f64,
    },
    /// Retro-reflective material of a target.
    Retro {
        /// Index in [`TestField::targets`] (not the target number).
        target: usize,
    },
    /// The black print of a target.
    Black {
        /// Index in [`TestField::targets`] (not the target number).
        target: usize,
    },
    /// A ball.
    Ball {
        /// Index in [`TestField::balls`] (not the ball number).
        ball: usize,
    },
    /// A ball's stem.
    Stem {
        /// Index in [`TestField::balls`] of the ball it carries.
        ball: usize,
    },
}

/// A ray hit: distance along the (unit) ray, kind, unit normal at the hit (towards the ray).
#[derive(Debug, Clone, Copy)]
pub struct Hit {
    /// Ray parameter (mm along a unit direction).
    pub t: f64,
    /// What was hit.
    pub kind: HitKind,
    /// Unit surface normal at the hit.
    pub normal: V3,
}

/// An object index for culling: `Target(i)` or `Ball(i)` (a ball with its stem).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Object {
    /// A target.
    Target(u32),
    /// A ball and its stem.
    Ball(u32),
}

/// The whole test field.
#[derive(Debug, Clone)]
pub struct TestField {
    /// wall1, wall2, floor.
    pub surfaces: Vec<Surface>,
    /// All targets.
    pub targets: Vec<Target>,
    /// All balls.
    pub balls: Vec<Ball>,
    /// Caliper distances.
    pub distances: Vec<Distance>,
    /// Albedo of the black print.
    pub black_albedo: f64,
    /// Retro gain (see [`crate::config::TargetConfig::retro_gain`]).
    pub retro_gain: f64,
    /// Ball albedo.
    pub ball_albedo: f64,
    /// Stem albedo.
    pub stem_albedo: f64,
}

/// Ray–sphere: nearest t > t_min.
pub(crate) fn ray_sphere(o: &V3, d: &V3, c: &V3, r: f64, t_min: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(d);
    let cc = oc.norm_squared() - r * r;
    let disc = b * b - cc;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t0 = -b - s;
    if t0 > t_min {
        return Some(t0);
    }
    let t1 = -b + s;
    (t1 > t_min).then_some(t1)
}

/// Ray against a finite cylinder (no caps): nearest t > t_min with the axial coordinate
/// in [0, len].
fn ray_cylinder(o: &V3, d: &V3, foot: &V3, axis: &V3, len: f64, r: f64, t_min: f64) -> Option<f64> {
    let w = o - foot;
    let dp = d - axis * d.dot(axis);
    let wp = w - axis * w.dot(axis);
    let a = dp.norm_squared();
    if a < 1e-14 {
        return None;
    }
    let b = dp.dot(&wp);
    let c = wp.norm_squared() - r * r;
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    for t in [(-b - s) / a, (-b + s) / a] {
        if t > t_min {
            let h = (w + d * t).dot(axis);
            if (0.0..=len).contains(&h) {
                return Some(t);
            }
        }
    }
    None
}

/// The least ray parameter of a hit (mm): a ray starting on a surface does not hit it.
const CAST_T_MIN: f64 = 1e-6;

impl TestField {
    /// The nearest of the surfaces' hits (the first of equal ones), its normal left zero:
    /// [`Self::cast`] computes it for the hit that wins only, since most surface hits near
    /// a target or a ball lose to it.
    fn nearest_surface(&self, o: &V3, d: &V3) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        for (i, s) in self.surfaces.iter().enumerate() {
            if let Some((t, u, v)) = s.intersect(o, d, CAST_T_MIN) {
                if best.is_none_or(|b| t < b.t) {
                    best = Some(Hit {
                        t,
                        kind: HitKind::Surface { index: i, u, v },
                        normal: V3::zeros(),
                    });
                }
            }
        }
        best
    }

    /// Casts a unit ray from `o` along `d` against the three surfaces and the given objects
    /// (all objects when `objects` is `None`). Targets are stickers: where a target and
    /// its own surface are within 0.5 mm of each other, the target wins.
    pub fn cast(&self, o: &V3, d: &V3, objects: Option<&[Object]>) -> Option<Hit> {
        let consider = |h: Hit, best: &mut Option<Hit>| {
            if best.is_none_or(|b| h.t < b.t) {
                *best = Some(h);
            }
        };
        let mut best = self.nearest_surface(o, d);
        let check_target = |i: usize, best: &mut Option<Hit>| {
            let tg = &self.targets[i];
            let dn = d.dot(&tg.normal);
            if dn >= 0.0 {
                return; // seen from behind
            }
            let t = (tg.centre - o).dot(&tg.normal) / dn;
            if t <= CAST_T_MIN {
                return;
            }
            let q = o + d * t - tg.centre;
            let (x, y) = (q.dot(&tg.t1), q.dot(&tg.t2));
            if x * x + y * y > tg.background * tg.background {
                return;
            }
            // Sticker priority over its own surface (0.5 mm).
            if best.is_none_or(|b| t < b.t + 0.5) {
                let kind = if tg.is_retro(x, y) {
                    HitKind::Retro { target: i }
                } else {
                    HitKind::Black { target: i }
                };
                *best = Some(Hit {
                    t: t.min(best.map_or(t, |b| b.t)),
                    kind,
                    normal: tg.normal,
                });
            }
        };
        let mut balls_to_check: Vec<usize> = Vec::new();
        match objects {
            None => {
                balls_to_check.extend(0..self.balls.len());
            }
            Some(objs) => {
                for o in objs {
                    if let Object::Ball(i) = o {
                        balls_to_check.push(*i as usize);
                    }
                }
            }
        }
        // Balls and stems first (opaque solids), then targets (which only win against their
        // own surface, never against a ball in front of them).
        for &i in &balls_to_check {
            let bl = &self.balls[i];
            if let Some(t) = ray_sphere(o, d, &bl.centre, bl.radius, CAST_T_MIN) {
                let p = o + d * t;
                consider(
                    Hit {
                        t,
                        kind: HitKind::Ball { ball: i },
                        normal: (p - bl.centre) / bl.radius,
                    },
                    &mut best,
                );
            }
            if let Some(t) = ray_cylinder(
                o,
                d,
                &bl.foot,
                &bl.axis,
                bl.stem_length,
                bl.stem_radius,
                CAST_T_MIN,
            ) {
                let p = o + d * t;
                let w = p - bl.foot;
                let radial = (w - bl.axis * w.dot(&bl.axis)).normalize();
                consider(
                    Hit {
                        t,
                        kind: HitKind::Stem { ball: i },
                        normal: radial,
                    },
                    &mut best,
                );
            }
        }
        match objects {
            None => {
                for i in 0..self.targets.len() {
                    check_target(i, &mut best);
                }
            }
            Some(objs) => {
                for o in objs {
                    if let Object::Target(i) = o {
                        check_target(*i as usize, &mut best);
                    }
                }
            }
        }
        if let Some(Hit {
            kind: HitKind::Surface { index, u, v },
            normal,
            ..
        }) = &mut best
        {
            *normal = self.surfaces[*index].normal(*u, *v);
        }
        best
    }

    /// The diffuse reflectivity of what a hit landed on (as the LRF sees it).
    pub fn reflectivity(&self, hit: &Hit) -> f64 {
        match hit.kind {
            HitKind::Surface { index, u, v } => self.surfaces[index].albedo_at(u, v),
            HitKind::Retro { .. } => 0.9,
            HitKind::Black { .. } => self.black_albedo,
            HitKind::Ball { .. } => self.ball_albedo,
            HitKind::Stem { .. } => self.stem_albedo,
        }
    }

    /// Builds the paper's test field from the configuration: the corner, the targets and
    /// balls spread over what the main station sees, and the caliper distances.
    ///
    /// The `room` random stream is drawn in a fixed order: the corner's tilts and bulges,
    /// then the targets' jitter, code numbers and code rotations, then the balls'
    /// stand-offs; the distances have their own stream.
    pub fn build(cfg: &SimConfig, seed: u64) -> Result<Self, SimError> {
        cfg.validate()?;
        let mut rng = rng_for(seed, "room", 0);
        let surfaces = corner_surfaces(&cfg.room, seed, &mut rng);
        let view = MainView::new(cfg, &surfaces)?;
        let targets = place_targets(&cfg.targets, &surfaces, &view, &mut rng)?;
        let feet = ball_feet(cfg, &surfaces, &targets, &view, &mut rng)?;
        let mut balls = mount_balls(&cfg.balls, &surfaces, &feet)?;
        if cfg.balls.placements.is_none() {
            sort_as_read(&mut balls, &view);
        }
        for (i, b) in balls.iter_mut().enumerate() {
            b.id = i as u32 + 1;
        }
        let distances = choose_distances(cfg, &targets, &mut rng_for(seed, "distances", 0))?;
        Ok(TestField {
            surfaces,
            targets,
            balls,
            distances,
            black_albedo: cfg.targets.black_albedo,
            retro_gain: cfg.targets.retro_gain,
            ball_albedo: cfg.balls.albedo,
            stem_albedo: cfg.balls.stem_albedo,
        })
    }
    /// Moves everything by a rigid transform `x' = pose(x)` (e.g. into a camera frame).
    pub fn transformed(&self, pose: &Rigid3) -> TestField {
        let r = pose.rotation;
        let mut s = self.clone();
        for sf in &mut s.surfaces {
            *sf = Surface::new(
                &sf.name,
                pose.transform(&sf.origin),
                r * sf.a,
                r * sf.b,
                r * sf.n,
                sf.u_max,
                sf.v_max,
                sf.bulge_mm,
                sf.albedo,
                sf.texture,
                sf.texture_seed,
            );
        }
        for t in &mut s.targets {
            t.centre = pose.transform(&t.centre);
            t.normal = r * t.normal;
            t.t1 = r * t.t1;
            t.t2 = r * t.t2;
        }
        for b in &mut s.balls {
            b.centre = pose.transform(&b.centre);
            b.foot = pose.transform(&b.foot);
            b.axis = r * b.axis;
        }
        s
    }
}

/// A place on the field: a surface (index into [`TestField::surfaces`]) and coordinates on it.
#[derive(Debug, Clone, Copy)]
struct Spot {
    surface: usize,
    u: f64,
    v: f64,
}

/// A small random rotation: omega, phi and kappa each uniform in ±`tilt_deg` (three draws,
/// none when `tilt_deg` is 0).
fn small_rotation(tilt_deg: f64, rng: &mut ChaCha8Rng) -> Matrix3<f64> {
    let mut a = [0.0; 3];
    for x in a.iter_mut() {
        *x = if tilt_deg > 0.0 {
            rng.random_range(-tilt_deg..=tilt_deg)
        } else {
            0.0
        };
    }
    from_opk(a[0].to_radians(), a[1].to_radians(), a[2].to_radians())
}

/// A random bulge height: 30 to 100 % of `max_mm`, either sign (two draws, none when
/// `max_mm` is 0).
fn random_bulge(max_mm: f64, rng: &mut ChaCha8Rng) -> f64 {
    if max_mm > 0.0 {
        let m: f64 = rng.random_range(0.3..=1.0) * max_mm;
        if rng.random_bool(0.5) {
            m
        } else {
            -m
        }
    } else {
        0.0
    }
}

/// The room corner: wall1, wall2 and the floor, each tilted by a small random rotation and
/// bulged at random, meeting along their common edges at the origin.
fn corner_surfaces(rc: &RoomConfig, seed: u64, rng: &mut ChaCha8Rng) -> Vec<Surface> {
    let n_floor = small_rotation(rc.max_tilt_deg, rng) * V3::z();
    let n_w1 = small_rotation(rc.max_tilt_deg, rng) * V3::y();
    let n_w2 = small_rotation(rc.max_tilt_deg, rng) * V3::x();
    let orient = |v: V3, along: V3| if v.dot(&along) < 0.0 { -v } else { v };
    let ex = orient(n_floor.cross(&n_w1).normalize(), V3::x());
    let ey = orient(n_w2.cross(&n_floor).normalize(), V3::y());
    let ez = orient(n_w1.cross(&n_w2).normalize(), V3::z());
    let (l, h) = (rc.wall_length_mm, rc.wall_height_mm);
    let b1 = random_bulge(rc.max_bulge_mm, rng);
    let b2 = random_bulge(rc.max_bulge_mm, rng);
    let b3 = random_bulge(rc.max_bulge_mm, rng);
    vec![
        Surface::new(
            "wall1",
            V3::zeros(),
            ex,
            ez,
            n_w1,
            l,
            h,
            b1,
            rc.wall_albedo,
            rc.texture_amplitude,
            seed ^ 0x11,
        ),
        Surface::new(
            "wall2",
            V3::zeros(),
            ey,
            ez,
            n_w2,
            l,
            h,
            b2,
            rc.wall_albedo,
            rc.texture_amplitude,
            seed ^ 0x22,
        ),
        Surface::new(
            "floor",
            V3::zeros(),
            ex,
            ey,
            n_floor,
            l,
            l,
            b3,
            rc.floor_albedo,
            rc.texture_amplitude,
            seed ^ 0x33,
        ),
    ]
}

/// The main station's left camera, over whose image the targets and balls are spread.
struct MainView {
    /// World → camera.
    pose: Rigid3,
    /// The left camera of the head.
    camera: CameraUnit,
    /// Its largest ideal image radius (see [`CameraUnit::max_ideal_radius_mm`]).
    r_max: f64,
}

impl MainView {
    /// The main left camera of the configuration, refused when it stands outside the room
    /// (or too close to a wall).
    fn new(cfg: &SimConfig, surfaces: &[Surface]) -> Result<Self, SimError> {
        let pose = crate::head::main_left_pose(&cfg.stations);
        check_inside(
            surfaces,
            &pose.centre(),
            "stations.main_centre_mm",
            "S00",
            "left",
            cfg.stations.min_wall_clearance_mm,
        )?;
        let camera = crate::head::StereoRig::from_config(cfg)
            .cameras
            .swap_remove(0);
        let r_max = camera.max_ideal_radius_mm();
        Ok(Self {
            pose,
            camera,
            r_max,
        })
    }

    /// The image point of `p` (on a surface of normal `n`) when the camera sees it at less
    /// than ~75° incidence and more than `margin` pixels inside the image border.
    fn sees(&self, p: &V3, n: &V3, margin: f64) -> Option<Vector2<f64>> {
        let xc = self.pose.transform(p);
        let to_cam = self.pose.centre() - p;
        if n.dot(&to_cam) < 0.25 * to_cam.norm() {
            return None; // seen at more than ~75° incidence
        }
        let uv = self.camera.project_in_view(&xc, self.r_max)?;
        let (w, h) = (self.camera.model.width, self.camera.model.height);
        (uv.x > margin
            && uv.y > margin
            && uv.x < w as f64 - 1.0 - margin
            && uv.y < h as f64 - 1.0 - margin)
            .then_some(uv)
    }

    /// The image point of `p`, or (0, 0) when it is out of view.
    fn image_point(&self, p: &V3) -> Vector2<f64> {
        self.camera
            .project_in_view(&self.pose.transform(p), self.r_max)
            .unwrap_or_default()
    }
}

/// The (u, v) of a square grid of `step` on surface `s`, `margin` inside its edges, in rows
/// of constant u.
fn grid(s: &Surface, margin: f64, step: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut u = margin;
    while u <= s.u_max - margin {
        let mut v = margin;
        while v <= s.v_max - margin {
            out.push((u, v));
            v += step;
        }
        u += step;
    }
    out
}

/// Where the targets go: `tc.count` places of the target grid that the main view sees,
/// spread by farthest-point sampling, each jittered by up to 15 % of the grid spacing (two
/// draws per target).
fn target_spots(
    tc: &TargetConfig,
    surfaces: &[Surface],
    view: &MainView,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Spot>, SimError> {
    let sp = tc.grid_spacing_mm;
    let mut cands: Vec<(Spot, V3)> = Vec::new();
    for (si, s) in surfaces.iter().enumerate() {
        for (u, v) in grid(s, tc.edge_margin_mm, sp) {
            let p = s.point(u, v);
            if view.sees(&p, &s.normal(u, v), 30.0).is_some() {
                cands.push((Spot { surface: si, u, v }, p));
            }
        }
    }
    if cands.len() < tc.count {
        return Err(ConfigError::new(
            "targets.count",
            tc.count,
            format!("only {} grid places of targets.grid_spacing_mm = {sp} are in the main station's view", cands.len()),
        )
        .into());
    }
    let pts: Vec<V3> = cands.iter().map(|c| c.1).collect();
    let j = 0.15 * sp;
    Ok(farthest_point_sampling(&pts, tc.count)
        .into_iter()
        .map(|ci| {
            let spot = cands[ci].0;
            let (du, dv): (f64, f64) = (rng.random_range(-j..=j), rng.random_range(-j..=j));
            Spot {
                u: spot.u + du,
                v: spot.v + dv,
                ..spot
            }
        })
        .collect())
}

/// The numbers of the coded targets: `coded` distinct numbers out of 1..=`table_len`,
/// drawn at random (a partial Fisher–Yates shuffle).
fn coded_numbers(coded: usize, table_len: usize, rng: &mut ChaCha8Rng) -> Vec<u32> {
    let mut numbers: Vec<u32> = (1..=table_len as u32).collect();
    for i in 0..coded.min(numbers.len()) {
        let j = rng.random_range(i..numbers.len());
        numbers.swap(i, j);
    }
    numbers.truncate(coded);
    numbers
}

/// The targets at [`target_spots`]: the `tc.coded` most spread of them coded with random
/// numbers, the others plain and numbered 1001, 1002, … in placing order; each printed with
/// a random code rotation.
fn place_targets(
    tc: &TargetConfig,
    surfaces: &[Surface],
    view: &MainView,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<Target>, SimError> {
    let spots = target_spots(tc, surfaces, view, rng)?;
    let pts: Vec<V3> = spots
        .iter()
        .map(|s| surfaces[s.surface].point(s.u, s.v))
        .collect();
    let coded_idx = farthest_point_sampling(&pts, tc.coded);
    let table = coded_target::code_table(tc.code_bits);
    let numbers = coded_numbers(tc.coded, table.codes.len(), rng);
    let mut targets = Vec::with_capacity(tc.count);
    let mut next_plain = 1001;
    for (k, &spot) in spots.iter().enumerate() {
        let (id, code) = match coded_idx.iter().position(|&c| c == k) {
            Some(p) => (numbers[p], table.code(numbers[p])),
            None => {
                next_plain += 1;
                (next_plain - 1, None)
            }
        };
        let code_rotation = rng.random_range(0.0..std::f64::consts::TAU);
        targets.push(sticker(tc, surfaces, spot, id, code, code_rotation));
    }
    Ok(targets)
}

/// The target sticker number `id` (with ring `code` when coded) at `spot`, lying in the
/// tangent plane of its surface, `t1` along the surface's first edge.
fn sticker(
    tc: &TargetConfig,
    surfaces: &[Surface],
    spot: Spot,
    id: u32,
    code: Option<u32>,
    code_rotation: f64,
) -> Target {
    let s = &surfaces[spot.surface];
    let normal = s.normal(spot.u, spot.v);
    // t1 along the plane's first edge, made orthogonal to the normal.
    let t1 = (s.a - normal * s.a.dot(&normal)).normalize();
    let t2 = normal.cross(&t1);
    let rr = tc.dot_radius_mm;
    let bg = if code.is_some() {
        tc.background
    } else {
        tc.plain_background
    };
    Target {
        id,
        code,
        surface: spot.surface,
        centre: s.point(spot.u, spot.v),
        normal,
        t1,
        t2,
        dot_radius: rr,
        ring_inner: tc.ring_inner * rr,
        ring_outer: tc.ring_outer * rr,
        background: bg * rr,
        code_rotation,
        bits: tc.code_bits,
    }
}

/// Where the balls' stems stand and their stand-off: the configured placements, or
/// `balls.count` of [`ball_candidates`] spread by farthest-point sampling, each with a
/// random stand-off (one draw per ball).
fn ball_feet(
    cfg: &SimConfig,
    surfaces: &[Surface],
    targets: &[Target],
    view: &MainView,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<(Spot, f64)>, SimError> {
    let bc = &cfg.balls;
    if let Some(ps) = &bc.placements {
        return Ok(ps
            .iter()
            .map(|p| {
                // The configuration's validation has checked the surface names.
                let si = ["wall1", "wall2", "floor"]
                    .iter()
                    .position(|n| *n == p.surface)
                    .unwrap();
                (
                    Spot {
                        surface: si,
                        u: p.u_mm,
                        v: p.v_mm,
                    },
                    p.standoff_mm,
                )
            })
            .collect());
    }
    let cands = ball_candidates(cfg, surfaces, targets, view);
    if cands.len() < bc.count {
        return Err(ConfigError::new(
            "balls.count",
            bc.count,
            format!(
                "only {} places for balls in the main station's view",
                cands.len()
            ),
        )
        .into());
    }
    let pts: Vec<V3> = cands.iter().map(|c| c.1).collect();
    Ok(farthest_point_sampling(&pts, bc.count)
        .into_iter()
        .map(|ci| {
            let st = rng.random_range(bc.standoff_range_mm[0]..=bc.standoff_range_mm[1]);
            (cands[ci].0, st)
        })
        .collect())
}

/// The places a ball could stand, with its centre at mid-range stand-off: a grid of half
/// the target spacing, clear of the targets, where the main view sees the ball well inside
/// the image.
fn ball_candidates(
    cfg: &SimConfig,
    surfaces: &[Surface],
    targets: &[Target],
    view: &MainView,
) -> Vec<(Spot, V3)> {
    let (bc, tc) = (&cfg.balls, &cfg.targets);
    let sp = tc.grid_spacing_mm;
    let mut cands = Vec::new();
    for (si, s) in surfaces.iter().enumerate() {
        for (u, v) in grid(s, tc.edge_margin_mm + 0.5 * sp, 0.5 * sp) {
            let foot = s.point(u, v);
            let c =
                foot + s.normal(u, v) * 0.5 * (bc.standoff_range_mm[0] + bc.standoff_range_mm[1]);
            let clear = targets
                .iter()
                .all(|t| (t.centre - foot).norm() > bc.clearance_mm + t.background);
            if clear && view.sees(&c, &s.normal(u, v), 60.0).is_some() {
                cands.push((Spot { surface: si, u, v }, c));
            }
        }
    }
    cands
}

/// The balls on their stems at `feet` (unnumbered: `id` 0), refused when a configured foot
/// is off its surface or a ball would cut into a wall.
fn mount_balls(
    bc: &BallConfig,
    surfaces: &[Surface],
    feet: &[(Spot, f64)],
) -> Result<Vec<Ball>, SimError> {
    let radius = 0.5 * bc.diameter_mm;
    let mut balls = Vec::with_capacity(feet.len());
    for (k, &(Spot { surface: si, u, v }, st)) in feet.iter().enumerate() {
        let s = &surfaces[si];
        let key = |f: &str| format!("balls.placements[{k}].{f}");
        if bc.placements.is_some() && !(u >= 0.0 && u <= s.u_max && v >= 0.0 && v <= s.v_max) {
            return Err(ConfigError::new(
                key("u_mm"),
                format!("{u}, v_mm = {v}"),
                format!("outside {} ({} × {} mm)", s.name, s.u_max, s.v_max),
            )
            .into());
        }
        let foot = s.point(u, v);
        let axis = s.normal(u, v);
        let centre = foot + axis * st;
        for other in surfaces {
            let dist = other.plane_distance(&centre) - other.bulge_mm.max(0.0);
            if dist < radius {
                return Err(ConfigError::new(
                    if bc.placements.is_some() { key("standoff_mm") } else { "balls.standoff_range_mm".to_string() },
                    st,
                    format!("ball {} would be {dist:.1} mm from {}, less than its radius {radius} mm: a ball inside a wall", k + 1, other.name),
                )
                .into());
            }
        }
        balls.push(Ball {
            id: 0,
            centre,
            radius,
            foot,
            axis,
            stem_length: st,
            stem_radius: bc.stem_radius_mm,
            surface: si,
        });
    }
    Ok(balls)
}

/// Orders the balls as a reader of the main image would number them: in rows of ~100 px,
/// left to right.
fn sort_as_read(balls: &mut [Ball], view: &MainView) {
    let key = |b: &Ball| {
        let uv = view.image_point(&b.centre);
        ((uv.y / 100.0).floor() as i64, uv.x)
    };
    balls.sort_by(|a, b| {
        let (ka, kb) = (key(a), key(b));
        ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    });
}

/// Picks `k` of `pts`, spread evenly: start nearest the centroid, then repeatedly the point
/// farthest from those chosen (ties to the lower index). Deterministic.
pub fn farthest_point_sampling(pts: &[V3], k: usize) -> Vec<usize> {
    if pts.is_empty() || k == 0 {
        return Vec::new();
    }
    let centroid = pts.iter().fold(V3::zeros(), |a, p| a + p) / pts.len() as f64;
    let first = (0..pts.len())
        .min_by(|&a, &b| {
            (pts[a] - centroid)
                .norm()
                .total_cmp(&(pts[b] - centroid).norm())
        })
        .unwrap();
    let mut chosen = vec![first];
    let mut dmin: Vec<f64> = pts.iter().map(|p| (p - pts[first]).norm()).collect();
    while chosen.len() < k.min(pts.len()) {
        let next = (0..pts.len())
            .max_by(|&a, &b| dmin[a].total_cmp(&dmin[b]).then(b.cmp(&a)))
            .unwrap();
        chosen.push(next);
        for (i, p) in pts.iter().enumerate() {
            dmin[i] = dmin[i].min((p - pts[next]).norm());
        }
    }
    chosen
}

/// Five (or `count`) distances between coded targets, in directions as different as
/// possible, each target used once, lengths within the configured range.
fn choose_distances(
    cfg: &SimConfig,
    targets: &[Target],
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Result<Vec<Distance>, SimError> {
    let dc = &cfg.distances;
    let coded: Vec<&Target> = targets.iter().filter(|t| t.code.is_some()).collect();
    let mut pairs: Vec<(usize, usize, f64)> = Vec::new();
    for i in 0..coded.len() {
        for j in i + 1..coded.len() {
            let d = (coded[i].centre - coded[j].centre).norm();
            if d >= dc.length_range_mm[0] && d <= dc.length_range_mm[1] {
                pairs.push((i, j, d));
            }
        }
    }
    let mut chosen: Vec<(usize, usize, f64)> = Vec::new();
    let mut used = vec![false; coded.len()];
    while chosen.len() < dc.count {
        let best = pairs
            .iter()
            .filter(|p| !used[p.0] && !used[p.1])
            .map(|p| {
                let dir = (coded[p.1].centre - coded[p.0].centre).normalize();
                let worst = chosen
                    .iter()
                    .map(|q| {
                        dir.dot(&(coded[q.1].centre - coded[q.0].centre).normalize())
                            .abs()
                    })
                    .fold(0.0, f64::max);
                // Prefer directions unlike those chosen, then longer distances.
                (p, worst - 1e-4 * p.2 / dc.length_range_mm[1])
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((p, _)) = best else {
            return Err(ConfigError::new(
                "distances.count",
                dc.count,
                format!(
                    "only {} pairs of coded targets {:?} mm apart are available",
                    chosen.len(),
                    dc.length_range_mm
                ),
            )
            .into());
        };
        used[p.0] = true;
        used[p.1] = true;
        chosen.push(*p);
    }
    let normal = rand_distr::Normal::new(0.0, dc.sigma_mm.max(0.0)).unwrap();
    Ok(chosen
        .into_iter()
        .map(|(i, j, d)| {
            let e: f64 = if dc.sigma_mm > 0.0 {
                rng.sample(normal)
            } else {
                0.0
            };
            Distance {
                from: coded[i].id,
                to: coded[j].id,
                true_mm: d,
                measured_mm: d + e,
                sigma_mm: dc.sigma_mm,
            }
        })
        .collect())
}

/// Refuses a camera centre `c` less than `clearance` inside any of the room's planes.
pub fn check_inside(
    surfaces: &[Surface],
    c: &V3,
    key: &str,
    station: &str,
    camera: &str,
    clearance: f64,
) -> Result<(), ConfigError> {
    for s in surfaces {
        let d = s.plane_distance(c);
        if d < clearance {
            return Err(ConfigError::new(
                key,
                format!("[{:.0}, {:.0}, {:.0}]", c.x, c.y, c.z),
                format!(
                    "station {station} puts the {camera} camera {:.0} mm {} {} (needs {clearance} mm inside the room): a camera behind a wall",
                    d.abs(),
                    if d < 0.0 { "behind" } else { "in front of" },
                    s.name,
                ),
            ));
        }
    }
    Ok(())
}
