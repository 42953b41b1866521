//! Test and benchmark support: simulated LRF scans of a scene of planes and balls. No
//! production module uses it; the sensor itself (rays, range noise, what a reading is) is
//! [`crate::sensor`], and `pingcal-sim` is the full simulator of the paper's test field.
//!
//! **Mixed pixels.** The beam has a finite footprint, half-width `a + b·r` (defaults 1 mm +
//! 0.2 % of the range: 3 mm at 1 m; an assumption, the datasheet gives no divergence). When
//! a ball's silhouette edge falls inside the footprint (ray passing the centre at a distance
//! `h` within `R ± half-width`), the sensor returns a blend `f·r_ball + (1 − f)·r_behind`,
//! `f` the covered fraction of the footprint `(R + w − h)/(2w)`: a range between ball and
//! wall (Kneip et al. 2009). The blended range is then read by the sensor
//! ([`LrfSensor::read`]: noise, rounding to whole mm, range limits).

use crate::scan::ScanLine;
use crate::sensor::{LrfSensor, RangeNoise};
use nalgebra::Vector3;
use rand::Rng;

/// The beam footprint of the mixed-pixel model: half-width `a_mm + b · r` (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Half-width at range 0, mm.
    pub a_mm: f64,
    /// Growth of the half-width with the range.
    pub b: f64,
}

/// The sensor as the test scene measures it: [`LrfSensor`] plus the footprint of its mixed
/// pixels (`None`: no mixed pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedLrf {
    /// Beams, mount, range noise and reading limits.
    pub sensor: LrfSensor,
    /// Footprint of the mixed-pixel model.
    pub footprint: Option<Footprint>,
}

impl Default for SimulatedLrf {
    /// The URG-04LX ([`LrfSensor::urg_04lx`]) with mixed pixels of a 1 mm + 0.2 % footprint.
    fn default() -> Self {
        SimulatedLrf {
            sensor: LrfSensor::urg_04lx(),
            footprint: Some(Footprint {
                a_mm: 1.0,
                b: 0.002,
            }),
        }
    }
}

impl SimulatedLrf {
    /// Exact ranges, not rounded, without mixed pixels (for exact-data tests).
    pub fn noiseless() -> Self {
        SimulatedLrf {
            sensor: LrfSensor {
                noise: RangeNoise::Noiseless,
                quantise: false,
                ..LrfSensor::urg_04lx()
            },
            footprint: None,
        }
    }

    /// Range σ at range `r` (mm).
    pub fn sigma(&self, r: f64) -> f64 {
        self.sensor.noise.sigma(r)
    }
}

/// A scene: planes `n·x = d` (n unit), balls of one radius and clutter, in the LRF frame, mm.
#[derive(Debug, Clone, Default)]
pub struct LrfScene {
    /// Planes as (unit normal, offset).
    pub planes: Vec<(Vector3<f64>, f64)>,
    /// Ball centres.
    pub balls: Vec<Vector3<f64>>,
    /// Ball radius, mm.
    pub radius: f64,
    /// What else stands in the room (no ball: a finder must not report any of it).
    pub clutter: Vec<Clutter>,
}

/// A solid that is not a ball, for clutter in a simulated room (mm, LRF frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Clutter {
    /// An axis-aligned box between two corners.
    Box {
        /// Lowest corner.
        min: Vector3<f64>,
        /// Highest corner.
        max: Vector3<f64>,
    },
    /// A vertical cylinder (a pole, a chair leg) with its caps.
    Cylinder {
        /// Centre of the bottom cap.
        base: Vector3<f64>,
        /// Radius.
        radius: f64,
        /// Height (along +Z).
        height: f64,
    },
    /// An axis-aligned ellipsoid (a person's body, a bag, an egg-shaped bump).
    Ellipsoid {
        /// Centre.
        centre: Vector3<f64>,
        /// Semi-axes along X, Y, Z.
        semi_axes: Vector3<f64>,
    },
}

impl Clutter {
    /// First intersection of the ray `o + t d` (t > 0) with the solid.
    pub fn hit(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        match *self {
            Clutter::Box { min, max } => {
                let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                for k in 0..3 {
                    if d[k].abs() < 1e-15 {
                        if o[k] < min[k] || o[k] > max[k] {
                            return None;
                        }
                        continue;
                    }
                    let (a, b) = ((min[k] - o[k]) / d[k], (max[k] - o[k]) / d[k]);
                    t0 = t0.max(a.min(b));
                    t1 = t1.min(a.max(b));
                }
                (t0 <= t1 && t0 > 0.0).then_some(t0)
            }
            Clutter::Cylinder {
                base,
                radius,
                height,
            } => {
                let w = o - base;
                let (a, b, c) = (
                    d.x * d.x + d.y * d.y,
                    2.0 * (w.x * d.x + w.y * d.y),
                    w.x * w.x + w.y * w.y - radius * radius,
                );
                let mut best = f64::INFINITY;
                if a > 1e-15 {
                    let disc = b * b - 4.0 * a * c;
                    if disc >= 0.0 {
                        let t = (-b - disc.sqrt()) / (2.0 * a);
                        let z = w.z + t * d.z;
                        if t > 0.0 && (0.0..=height).contains(&z) {
                            best = t;
                        }
                    }
                }
                if d.z.abs() > 1e-15 {
                    for zc in [0.0, height] {
                        let t = (zc - w.z) / d.z;
                        let (x, y) = (w.x + t * d.x, w.y + t * d.y);
                        if t > 0.0 && x * x + y * y <= radius * radius {
                            best = best.min(t);
                        }
                    }
                }
                best.is_finite().then_some(best)
            }
            Clutter::Ellipsoid { centre, semi_axes } => {
                let w = (o - centre).component_div(&semi_axes);
                let e = d.component_div(&semi_axes);
                let (a, b, c) = (e.norm_squared(), 2.0 * w.dot(&e), w.norm_squared() - 1.0);
                let disc = b * b - 4.0 * a * c;
                if disc < 0.0 {
                    return None;
                }
                let t = (-b - disc.sqrt()) / (2.0 * a);
                (t > 0.0).then_some(t)
            }
        }
    }
}

/// First intersection with a sphere: (range, closest-approach distance h, closest-approach range b).
fn sphere_hit(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    c: &Vector3<f64>,
    r: f64,
) -> (Option<f64>, f64, f64) {
    let w = c - o;
    let b = d.dot(&w);
    let h2 = (w.norm_squared() - b * b).max(0.0);
    let t = if h2 <= r * r && b > 0.0 {
        Some(b - (r * r - h2).sqrt())
    } else {
        None
    };
    (t, h2.sqrt(), b)
}

impl LrfScene {
    /// Nearest hit along a ray ignoring ball `skip`; `None` when nothing is hit.
    pub fn cast(&self, o: &Vector3<f64>, d: &Vector3<f64>, skip: Option<usize>) -> Option<f64> {
        let mut best = f64::INFINITY;
        for (n, off) in &self.planes {
            let den = n.dot(d);
            if den.abs() > 1e-12 {
                let t = (off - n.dot(o)) / den;
                if t > 0.0 && t < best {
                    best = t;
                }
            }
        }
        for (k, c) in self.balls.iter().enumerate() {
            if Some(k) == skip {
                continue;
            }
            if let (Some(t), _, _) = sphere_hit(o, d, c, self.radius) {
                best = best.min(t);
            }
        }
        for c in &self.clutter {
            if let Some(t) = c.hit(o, d) {
                best = best.min(t);
            }
        }
        best.is_finite().then_some(best)
    }

    /// The measured range of one beam: the nearest hit, blended at ball edges when the
    /// footprint is modelled, read by the sensor. `None`: no return.
    pub fn measure<R: Rng>(
        &self,
        o: &Vector3<f64>,
        d: &Vector3<f64>,
        lrf: &SimulatedLrf,
        rng: &mut R,
    ) -> Option<f64> {
        let truth = self.cast(o, d, None)?;
        let r = match lrf.footprint {
            Some(fp) => self.mixed_pixel(o, d, truth, fp.a_mm + fp.b * truth),
            None => truth,
        };
        lrf.sensor.read(r, rng)
    }

    /// The range of a beam of half-width `w` whose nearest hit is at `truth`: a blend of
    /// ball and background when a ball's silhouette edge falls inside the footprint.
    fn mixed_pixel(&self, o: &Vector3<f64>, d: &Vector3<f64>, truth: f64, w: f64) -> f64 {
        for (k, c) in self.balls.iter().enumerate() {
            let (_, h, b) = sphere_hit(o, d, c, self.radius);
            if b > 0.0 && (h - self.radius).abs() < w && b <= truth + self.radius {
                let f = ((self.radius + w - h) / (2.0 * w)).clamp(0.0, 1.0);
                let r_ball = b - (self.radius * self.radius - h * h).max(0.0).sqrt();
                let r_behind = self.cast(o, d, Some(k)).unwrap_or(r_ball);
                return f * r_ball + (1.0 - f) * r_behind;
            }
        }
        truth
    }

    /// Simulates a sweep: one scan per servo angle, every beam of `lrf.sensor` (its beam
    /// geometry and mount).
    pub fn scan<R: Rng>(
        &self,
        servo_deg: &[f64],
        lrf: &SimulatedLrf,
        rng: &mut R,
    ) -> Vec<ScanLine> {
        let sensor = &lrf.sensor;
        servo_deg
            .iter()
            .enumerate()
            .map(|(k, &b)| {
                let ranges_mm = (0..sensor.beams)
                    .map(|i| {
                        let (o, d) = sensor.ray(i, b);
                        self.measure(&o, &d, lrf, rng).unwrap_or(0.0)
                    })
                    .collect();
                ScanLine {
                    line: 0,
                    stamp_s: k as f64 * 0.1,
                    servo_deg: b,
                    servo_end_deg: None,
                    ranges_mm,
                    intensities: vec![],
                    geometry: None,
                }
            })
            .collect()
    }

    /// [`LrfScene::half_sweep`] as a cloud (URG-04LX beam geometry, eq. 2's mount).
    pub fn half_sweep_cloud<R: Rng>(
        &self,
        n_scans: usize,
        lrf: &SimulatedLrf,
        rng: &mut R,
    ) -> crate::cloud::Cloud {
        let scans = self.half_sweep(n_scans, lrf, rng);
        crate::cloud::Cloud::from_scans(
            &crate::scan::ScanHeader::URG_04LX,
            scans.into_iter().map(Ok),
            &crate::cloud::MountModel::default(),
        )
        .expect("simulated scans are well formed")
    }

    /// The ball nearest to `p`: its index and distance (`None` without balls).
    pub fn nearest_ball(&self, p: &Vector3<f64>) -> Option<(usize, f64)> {
        self.balls
            .iter()
            .enumerate()
            .map(|(k, c)| (k, (c - p).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// A half sweep: `n_scans` scans at servo angles −90° + k·180°/`n_scans` (with the
    /// URG-04LX of [`SimulatedLrf::default`]: 682 beams each, eq. 2's mount).
    pub fn half_sweep<R: Rng>(
        &self,
        n_scans: usize,
        lrf: &SimulatedLrf,
        rng: &mut R,
    ) -> Vec<ScanLine> {
        let servo: Vec<f64> = (0..n_scans)
            .map(|k| -90.0 + k as f64 * 180.0 / n_scans as f64)
            .collect();
        self.scan(&servo, lrf, rng)
    }
}

/// The paper-like test field: a room corner (two walls and the floor) seen from the LRF,
/// with `n_balls` 38 mm balls on stems 60–120 mm out from the walls and the floor, every ball
/// 0.85–1.35 m from the LRF as in the paper, clear of the other two surfaces by at least
/// 40 mm and 150 mm from every other ball, and where a half sweep (servo −90…90°) sees it.
/// Wall 1 is the plane x = −450, wall 2 the plane y = 1200 (in front of the sensor: +Y is
/// the servo shaft, the beam α = 90°), the floor z = −600.
pub fn room_corner_scene<R: Rng>(n_balls: usize, rng: &mut R) -> LrfScene {
    let (x0, y0, z0) = (450.0, 1200.0, 600.0);
    let planes = vec![
        (Vector3::new(1.0, 0.0, 0.0), -x0),
        (Vector3::new(0.0, 1.0, 0.0), y0),
        (Vector3::new(0.0, 0.0, 1.0), -z0),
    ];
    let radius = 19.0;
    let clear = radius + 40.0;
    let mut balls: Vec<Vector3<f64>> = Vec::new();
    while balls.len() < n_balls {
        let stem = rng.random_range(60.0..120.0);
        let c = match rng.random_range(0..3) {
            0 => Vector3::new(
                -x0 + stem + radius,
                rng.random_range(300.0..y0 - clear),
                rng.random_range(-z0 + clear..600.0),
            ),
            1 => Vector3::new(
                rng.random_range(-x0 + clear..700.0),
                y0 - stem - radius,
                rng.random_range(-z0 + clear..600.0),
            ),
            _ => Vector3::new(
                rng.random_range(-x0 + clear..700.0),
                rng.random_range(300.0..y0 - clear),
                -z0 + stem + radius,
            ),
        };
        let range = c.norm();
        // seen by a half sweep (servo −90…90°, beams −120…120°): x ≥ 0, or within 30° of +Y
        let seen = c.x >= 0.0 || c.y >= 0.87 * range;
        if seen && (850.0..=1350.0).contains(&range) && balls.iter().all(|b| (b - c).norm() > 150.0)
        {
            balls.push(c);
        }
    }
    LrfScene {
        planes,
        balls,
        radius,
        clutter: Vec::new(),
    }
}

/// [`room_corner_scene`] with a furnished room beside the balls, at x 0.9–1.9 m and y < 0
/// (where the half sweep sees it and no beam to a ball passes): poles of the balls' radius
/// and larger, boxes, a chair (seat, four legs, back), a standing person (an ellipsoid body
/// and a head of radius 100 mm) and an egg-shaped bump of a ball's size. None is a ball.
pub fn cluttered_room_scene<R: Rng>(n_balls: usize, rng: &mut R) -> LrfScene {
    let mut scene = room_corner_scene(n_balls, rng);
    let floor = -600.0;
    let v = Vector3::new;
    let mut c = vec![
        // poles: one of exactly the balls' radius, the classic false ball of a 2D scanner
        Clutter::Cylinder {
            base: v(950.0, -350.0, floor),
            radius: 19.0,
            height: 1500.0,
        },
        Clutter::Cylinder {
            base: v(1250.0, -450.0, floor),
            radius: 25.0,
            height: 1500.0,
        },
        Clutter::Cylinder {
            base: v(1700.0, -300.0, floor),
            radius: 60.0,
            height: 1500.0,
        },
        // boxes
        Clutter::Box {
            min: v(1000.0, -1300.0, floor),
            max: v(1300.0, -1000.0, floor + 400.0),
        },
        Clutter::Box {
            min: v(1400.0, -1000.0, floor),
            max: v(2000.0, -600.0, floor + 150.0),
        },
        // a person: body and head
        Clutter::Ellipsoid {
            centre: v(1500.0, -1500.0, floor + 750.0),
            semi_axes: v(180.0, 120.0, 750.0),
        },
        Clutter::Ellipsoid {
            centre: v(1500.0, -1500.0, floor + 1600.0),
            semi_axes: v(100.0, 100.0, 100.0),
        },
        // an egg of a ball's size on a box
        Clutter::Ellipsoid {
            centre: v(1150.0, -1150.0, floor + 425.0),
            semi_axes: v(30.0, 30.0, 25.0),
        },
    ];
    // a chair: seat at 450 mm, four legs, a back
    let (cx, cy) = (1000.0, -700.0);
    c.push(Clutter::Box {
        min: v(cx, cy, floor + 420.0),
        max: v(cx + 450.0, cy + 450.0, floor + 460.0),
    });
    for (dx, dy) in [(20.0, 20.0), (430.0, 20.0), (20.0, 430.0), (430.0, 430.0)] {
        c.push(Clutter::Cylinder {
            base: v(cx + dx, cy + dy, floor),
            radius: 12.0,
            height: 420.0,
        });
    }
    c.push(Clutter::Box {
        min: v(cx + 420.0, cy, floor + 460.0),
        max: v(cx + 450.0, cy + 450.0, floor + 900.0),
    });
    scene.clutter = c;
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noiseless_scan_hits_the_surfaces() {
        let scene = LrfScene {
            planes: vec![(Vector3::new(0.0, 1.0, 0.0), 2000.0)],
            balls: vec![Vector3::new(0.0, 1000.0, 0.0)],
            radius: 19.0,
            clutter: Vec::new(),
        };
        let mut rng = pingcal_geometry::consensus::rng(1);
        let d = Vector3::new(0.0, 1.0, 0.0);
        let r = scene
            .measure(&Vector3::zeros(), &d, &SimulatedLrf::noiseless(), &mut rng)
            .unwrap();
        assert!((r - 981.0).abs() < 1e-9);
        let d = Vector3::new(0.1, 1.0, 0.0).normalize();
        let r = scene
            .measure(&Vector3::zeros(), &d, &SimulatedLrf::noiseless(), &mut rng)
            .unwrap();
        assert!((r - 2000.0 / d.y).abs() < 1e-9);
    }

    #[test]
    fn mixed_pixel_lies_between_ball_and_wall() {
        let scene = LrfScene {
            planes: vec![(Vector3::new(0.0, 1.0, 0.0), 1200.0)],
            balls: vec![Vector3::new(0.0, 1000.0, 0.0)],
            radius: 19.0,
            clutter: Vec::new(),
        };
        let noise = SimulatedLrf {
            footprint: SimulatedLrf::default().footprint,
            ..SimulatedLrf::noiseless()
        };
        let mut rng = pingcal_geometry::consensus::rng(1);
        // a ray passing 19 mm from the centre: right on the silhouette
        let d = Vector3::new(19.0, 1000.0, 0.0).normalize();
        let r = scene
            .measure(&Vector3::zeros(), &d, &noise, &mut rng)
            .unwrap();
        assert!(r > 1001.0 && r < 1199.0, "{r}");
    }
}
