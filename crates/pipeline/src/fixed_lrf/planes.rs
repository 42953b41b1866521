//! The field's planes as the targets define them, and which beams lie on which plane or
//! ball.
//!
//! **Planes.** Sequential seeded RANSAC among the adjusted target centres (balls excluded):
//! a plane through three targets, its consensus within [`PLANE_TOL_MM`]; one with at least
//! [`MIN_PLANE_TARGETS`] targets spread over [`MIN_SPREAD_MM`] both ways is refitted by
//! least squares and its members are the targets within `max(PLANE_TOL_MM / 2, 3 × RMS)`;
//! then the next, among the targets left. The RMS of a plane's targets about it is its
//! flatness as the photographs measure it (a wall's bulge, a target off the wall): it is
//! reported, not assumed. Each plane is bounded by its targets' extent widened by a reach —
//! [`REACH_MM`] in the adjustment (a wall goes on past its last target), [`MARGIN_MM`] when
//! starts are ranked: a beam beyond it is not taken to be on it.
//!
//! **Beams.** Through an extrinsic, each beam's ray (its origin and direction in the object
//! frame) is decided first, its range only last, so that no reading's noise decides which
//! side of a cut a beam falls (the rotating LRF's room planes learnt it: such a cut biased
//! the range offset by 2σ). A ray that passes
//! within [`BALL_CLEARANCE_MM`] of a ball is on the ball if it meets its sphere, else on
//! nothing (the ball's rim and stem, mixed with the wall behind). Otherwise its surface is
//! the first plane it meets within that plane's reach (the room is convex where the beams
//! see it), unless another plane passes within [`EDGE_CLEARANCE_MM`] of that point (where
//! a wall meets the floor or another wall: the footprint mixes the two; on the simulator's
//! noiseless corner such beams were off by up to 43 mm, the rest within 2 mm). Last, the
//! measured range must be within the gate of the predicted one.

use crate::ids::PointId;
use crate::scene::{PointKind, Scene};
use nalgebra::Vector3;
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator};
use pingcal_geometry::{Plane, Rigid3};

type V3 = Vector3<f64>;

/// Consensus tolerance of a target on a plane (mm).
pub const PLANE_TOL_MM: f64 = 10.0;
/// Fewest targets that define a plane.
pub const MIN_PLANE_TARGETS: usize = 6;
/// Smallest spread of a plane's targets along each in-plane axis (RMS, mm).
pub const MIN_SPREAD_MM: f64 = 100.0;
/// How far beyond its targets' extent a plane reaches when the start is searched (mm): a
/// candidate extrinsic is ranked by the beams it puts near the targets.
pub const MARGIN_MM: f64 = 400.0;
/// How far beyond its targets' extent a plane reaches in the adjustment, where the start
/// is known (mm): a wall goes on past its last target and the floor's few targets sit near
/// the corner; with [`MARGIN_MM`] the simulator's floor kept a quarter of its beams, and
/// beams past one wall's targets went to the next plane they were near (the noiseless
/// simulation settled 6.4 mm and 0.32° off; with this reach, 0.3 mm and 0.01°).
pub const REACH_MM: f64 = 3000.0;
/// Beams within this of two planes (where walls and the floor meet) are on neither in the
/// adjustment: the beam's footprint spans both, and its range mixes them (mm; a far beam at
/// grazing incidence stretches its footprint over centimetres: with 40 mm the simulator's
/// noiseless extrinsic settled 1 mm off, with 100 mm 0.4 mm).
pub const EDGE_CLEARANCE_MM: f64 = 40.0;
/// The same clearance when starts are ranked by the beams they put on the planes (mm): a
/// count, not a measurement, to which the beams near an edge still testify; one station's
/// scan line reaches the floor near the corner only, and with [`EDGE_CLEARANCE_MM`] the
/// upside-down fit of it hit more planes than the true one.
pub const START_EDGE_MM: f64 = 10.0;
/// Beams within this of a ball's surface or its stem are not taken to be on a plane (mm).
pub const BALL_CLEARANCE_MM: f64 = 40.0;
/// A ball's stem stands off the nearest plane within this (mm); a ball farther from every
/// plane stands on something the targets do not show, and only the ball is cleared.
pub const MAX_STEM_MM: f64 = 600.0;
/// Most planes looked for.
const MAX_PLANES: usize = 8;

/// A plane of the field.
#[derive(Clone, Debug)]
pub struct FieldPlane {
    /// Unit normal.
    pub normal: V3,
    /// `normal · x = offset`.
    pub offset: f64,
    /// The targets on it.
    pub members: Vec<PointId>,
    /// RMS distance of its targets from it (mm): its flatness as the photographs measure it.
    pub rms_mm: f64,
    /// Centroid of its targets.
    pub centre: V3,
    /// RMS spread of its targets about the centroid (mm).
    pub spread: f64,
    /// In-plane axes and the targets' extent along them.
    bounds: (V3, V3, [f64; 4]),
}

impl FieldPlane {
    /// Whether `x`'s foot on the plane lies within its targets' extent widened by `reach`
    /// (mm).
    pub fn contains(&self, x: &V3, reach: f64) -> bool {
        let (e1, e2, b) = &self.bounds;
        let d = x - self.centre;
        let (u, v) = (e1.dot(&d), e2.dot(&d));
        u >= b[0] - reach && u <= b[1] + reach && v >= b[2] - reach && v <= b[3] + reach
    }

    /// The plane `n · x = d` bounded to ±`half` (mm) about its foot of the origin (for
    /// tests of the steps that use planes).
    #[cfg(test)]
    pub(super) fn square(n: V3, d: f64, half: f64) -> Self {
        let n = n.normalize();
        let axis = if n.x.abs() < 0.6 { V3::x() } else { V3::y() };
        let e1 = n.cross(&axis).normalize();
        FieldPlane {
            normal: n,
            offset: d,
            members: Vec::new(),
            rms_mm: 1.0,
            centre: n * d,
            spread: half,
            bounds: (e1, n.cross(&e1), [-half, half, -half, half]),
        }
    }

    /// Signed distance of `x` (mm).
    pub fn distance(&self, x: &V3) -> f64 {
        self.normal.dot(x) - self.offset
    }
}

/// Planes through three targets.
struct ThreeTargets<'a>(&'a [V3]);

impl Estimator for ThreeTargets<'_> {
    type Model = (V3, f64);
    fn len(&self) -> usize {
        self.0.len()
    }
    fn sample_size(&self) -> usize {
        3
    }
    fn fit(&self, s: &[usize], models: &mut Vec<(V3, f64)>) {
        let (a, b, c) = (self.0[s[0]], self.0[s[1]], self.0[s[2]]);
        let n = (b - a).cross(&(c - a));
        if n.norm() < 1e-3 * (b - a).norm() * (c - a).norm() + 1e-9 {
            return;
        }
        let n = n.normalize();
        models.push((n, n.dot(&a)));
    }
    fn residual(&self, (n, d): &(V3, f64), i: usize) -> f64 {
        (n.dot(&self.0[i]) - d).abs()
    }
}

/// The field's planes among the targets of `scene` (see the module doc), largest first.
pub fn planes_of_targets(scene: &Scene, seed: u64) -> Vec<FieldPlane> {
    let mut left: Vec<(PointId, V3)> = (scene.points.iter_enumerated())
        .filter(|(_, p)| p.kind != PointKind::Ball)
        .map(|(j, p)| (j, p.position))
        .collect();
    let mut planes = Vec::new();
    let mut rng = consensus::rng_stream(seed, 0x6669_7865_645f_706c);
    while planes.len() < MAX_PLANES && left.len() >= MIN_PLANE_TARGETS {
        let pts: Vec<V3> = left.iter().map(|(_, x)| *x).collect();
        let opts = ConsensusOptions::msac(PLANE_TOL_MM, 2000);
        let Some(found) = consensus::find(&ThreeTargets(&pts), &opts, &mut rng) else {
            break;
        };
        let Some(plane) = refined(&pts, &found.inliers) else {
            break;
        };
        let tol = (0.5 * PLANE_TOL_MM).max(3.0 * plane.spreads()[0]);
        let on: Vec<usize> = (0..pts.len())
            .filter(|&i| plane.distance(&pts[i]).abs() <= tol)
            .collect();
        let Some(fp) = field_plane(&left, &on) else {
            break;
        };
        left = (left.iter().enumerate())
            .filter(|(i, _)| !on.contains(i))
            .map(|(_, x)| *x)
            .collect();
        planes.push(fp);
    }
    planes
}

/// The least-squares plane of `pts[inliers]` when they are enough and spread both ways.
fn refined(pts: &[V3], inliers: &[usize]) -> Option<Plane> {
    if inliers.len() < MIN_PLANE_TARGETS {
        return None;
    }
    let on: Vec<V3> = inliers.iter().map(|&i| pts[i]).collect();
    let plane = Plane::fit(&on)?;
    (plane.spreads()[1] >= MIN_SPREAD_MM).then_some(plane)
}

/// The plane of the targets `left[on]`, with its bounds.
fn field_plane(left: &[(PointId, V3)], on: &[usize]) -> Option<FieldPlane> {
    let pts: Vec<V3> = on.iter().map(|&i| left[i].1).collect();
    let plane = refined(&pts, &(0..pts.len()).collect::<Vec<_>>())?;
    let n = plane.normal;
    let axis = if n.x.abs() < 0.6 { V3::x() } else { V3::y() };
    let e1 = n.cross(&axis).normalize();
    let e2 = n.cross(&e1);
    let mut b = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for x in &pts {
        let d = x - plane.centroid;
        let (u, v) = (e1.dot(&d), e2.dot(&d));
        b = [b[0].min(u), b[1].max(u), b[2].min(v), b[3].max(v)];
    }
    let spread = (pts.iter())
        .map(|x| (x - plane.centroid).norm_squared())
        .sum::<f64>()
        / pts.len() as f64;
    Some(FieldPlane {
        normal: n,
        offset: plane.offset,
        members: on.iter().map(|&i| left[i].0).collect(),
        rms_mm: plane.spreads()[0],
        centre: plane.centroid,
        spread: spread.sqrt(),
        bounds: (e1, e2, b),
    })
}

/// What a beam is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum On {
    /// Plane `k` of the field.
    Plane(usize),
    /// Ball `k` of the balls given.
    Ball(usize),
}

/// A beam in the object frame: its ray's origin and unit direction, and its measured range
/// (mm, the range model taken out).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamRay {
    /// The ray's origin (the scanner's centre).
    pub origin: V3,
    /// Its unit direction.
    pub dir: V3,
    /// The measured range.
    pub range: f64,
}

impl BeamRay {
    /// The beam of unit direction `dir` (LRF frame) and range `range` of a scanner at the
    /// extrinsic `e` on a head at `object_from_camera`.
    pub fn of(object_from_camera: &Rigid3, e: &Rigid3, dir: &V3, range: f64) -> Self {
        BeamRay {
            origin: object_from_camera.transform(&e.translation),
            dir: object_from_camera.rotation * (e.rotation * dir),
            range,
        }
    }

    /// The measured point.
    pub fn point(&self) -> V3 {
        self.origin + self.dir * self.range
    }
}

/// A ball of the field on its stem: the stem stands off the nearest plane along its
/// normal, as the field guide builds them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallOnStem {
    /// The ball's centre.
    pub centre: V3,
    /// Its radius (mm).
    pub radius: f64,
    /// The stem's foot: the centre's foot on the nearest plane within [`MAX_STEM_MM`], or
    /// the centre itself.
    pub foot: V3,
}

impl BallOnStem {
    /// The ball of `centre` and `radius` on its stem off the nearest of `planes`.
    pub fn new(centre: V3, radius: f64, planes: &[FieldPlane]) -> Self {
        let foot = (planes.iter())
            .map(|p| (p.distance(&centre), p))
            .filter(|(d, p)| d.abs() <= MAX_STEM_MM && p.contains(&centre, MARGIN_MM))
            .min_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
            .map_or(centre, |(d, p)| centre - p.normal * d);
        BallOnStem {
            centre,
            radius,
            foot,
        }
    }

    /// The closest the ray `(o, u)` (u unit, ahead of o) comes to the ball's stem, the
    /// segment from its centre to its foot (mm).
    fn stem_distance(&self, o: &V3, u: &V3) -> f64 {
        let d = self.foot - self.centre;
        let w = o - self.centre;
        let (b, dd, e, cc) = (u.dot(&d), u.dot(&w), d.dot(&w), d.norm_squared());
        if cc < 1e-9 {
            let t = (-dd).max(0.0);
            return (w + u * t).norm();
        }
        let denom = cc - b * b;
        let mut s = if denom > 1e-9 {
            ((e - b * dd) / denom).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut t = b * s - dd;
        if t < 0.0 {
            t = 0.0;
            s = (e / cc).clamp(0.0, 1.0);
        }
        (w + u * t - d * s).norm()
    }
}

/// How far a beam may be from a surface and still be on it: the gate on its range, how far
/// past its targets a plane reaches, and the clearance of an edge (all mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reach {
    /// The gate on the range.
    pub gate: f64,
    /// How far beyond its targets' extent a plane reaches.
    pub reach: f64,
    /// The clearance of an edge where two planes meet.
    pub edge: f64,
}

/// The [`Reach`] of the adjustment, where the start is known: `gate`, [`REACH_MM`],
/// [`EDGE_CLEARANCE_MM`].
pub fn adjustment_reach(gate: f64) -> Reach {
    Reach {
        gate,
        reach: REACH_MM,
        edge: EDGE_CLEARANCE_MM,
    }
}

/// The [`Reach`] of the starts' ranking: `gate`, [`MARGIN_MM`], [`START_EDGE_MM`].
pub fn start_reach(gate: f64) -> Reach {
    Reach {
        gate,
        reach: MARGIN_MM,
        edge: START_EDGE_MM,
    }
}

/// What the beam `ray` is on (see the module doc): a ball of `balls` whose sphere it meets
/// within the smaller of `gate` and [`BALL_CLEARANCE_MM`] (a ray within that of the ball or
/// its stem that does not: nothing), or, clear of every ball, the first plane of `planes` it meets within the plane's bounds widened by
/// `reach`, if its range is within `gate` of that plane's and no other plane passes within
/// `edge` of the point; with the range the surface predicts.
pub fn on_what(
    ray: &BeamRay,
    planes: &[FieldPlane],
    balls: &[BallOnStem],
    lim: Reach,
) -> Option<(On, f64)> {
    let Reach { gate, reach, edge } = lim;
    let (o, u) = (&ray.origin, &ray.dir);
    for (k, ball) in balls.iter().enumerate() {
        let r = ball.radius;
        if ball.stem_distance(o, u) > r + BALL_CLEARANCE_MM {
            continue;
        }
        // near the ball or its stem: on the ball if the ray meets its sphere within the
        // gate, else on nothing (the rim, the stem: mixed with what is behind)
        let w = o - ball.centre;
        let along = -u.dot(&w);
        let miss2 = w.norm_squared() - along * along;
        let t = along - (r * r - miss2).max(0.0).sqrt();
        return (along > 0.0
            && miss2 < r * r
            && (ray.range - t).abs() <= gate.min(BALL_CLEARANCE_MM))
        .then_some((On::Ball(k), t));
    }
    let (k, t) = (planes.iter().enumerate())
        .filter_map(|(k, p)| {
            let s = p.normal.dot(u);
            let t = (p.offset - p.normal.dot(o)) / s;
            (s.abs() > 1e-9 && t > 0.0 && p.contains(&(o + u * t), reach)).then_some((k, t))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let x = o + u * t;
    // where two planes meet, a beam's footprint spans both: a mixed range, on neither
    let edge = (planes.iter().enumerate())
        .any(|(j, p)| j != k && p.distance(&x).abs() <= edge && p.contains(&x, reach));
    (!edge && (ray.range - t).abs() <= gate).then_some((On::Plane(k), t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_of(n: V3, d: f64) -> FieldPlane {
        FieldPlane::square(n, d, 1000.0)
    }

    /// A ray near a ball is the ball's, or nobody's (its stem, the ball's rim); else the
    /// first plane's it meets within the plane's bounds, if its range is within the gate.
    #[test]
    fn a_beam_is_on_the_first_surface_its_ray_meets() {
        let planes = [plane_of(V3::x(), 0.0), plane_of(V3::z(), 0.0)];
        let balls = [BallOnStem::new(V3::new(60.0, 500.0, 400.0), 19.0, &planes)];
        assert_eq!(
            balls[0].foot,
            V3::new(0.0, 500.0, 400.0),
            "on a stem off the wall"
        );
        let gate = Reach {
            gate: 30.0,
            reach: MARGIN_MM,
            edge: EDGE_CLEARANCE_MM,
        };
        // a ray from inside the corner towards the point `to`, its range `extra` past it
        let beam = |to: V3, extra: f64| {
            let origin = V3::new(800.0, 300.0, 500.0);
            let dir = (to - origin).normalize();
            BeamRay {
                origin,
                dir,
                range: (to - origin).norm() + extra,
            }
        };
        let on = |to: V3, extra: f64| on_what(&beam(to, extra), &planes, &balls, gate).map(|o| o.0);
        assert_eq!(on(V3::new(0.0, 300.0, 600.0), 5.0), Some(On::Plane(0)));
        assert_eq!(on(V3::new(300.0, 300.0, 0.0), -8.0), Some(On::Plane(1)));
        // the range decides only last: too far from the plane the ray meets
        assert_eq!(on(V3::new(0.0, 300.0, 600.0), 45.0), None);
        // the ball, whose sphere the ray meets 19 mm before its centre
        assert_eq!(on(V3::new(60.0, 500.0, 400.0), -19.0), Some(On::Ball(0)));
        // the ray passes 30 mm from the ball's centre: its rim, nobody's
        assert_eq!(on(V3::new(60.0, 500.0, 430.0), 0.0), None);
        // the wall just beside the stem's foot, and 100 mm from it
        assert_eq!(on(V3::new(0.0, 530.0, 400.0), 0.0), None);
        assert_eq!(on(V3::new(0.0, 600.0, 400.0), 0.0), Some(On::Plane(0)));
        // where the wall meets the floor
        assert_eq!(on(V3::new(0.0, 300.0, 25.0), 0.0), None);
        // beyond the wall's end
        assert_eq!(on(V3::new(0.0, 3000.0, 600.0), 0.0), None);
    }
}
