//! The field's planes as the targets define them, and which beams lie on which plane or
//! ball.
//!
//! **Planes.** Sequential seeded RANSAC among the adjusted target centres (balls excluded):
//! a plane through three targets, its consensus within [`PLANE_TOL_MM`]; one with at least
//! [`MIN_PLANE_TARGETS`] targets spread over [`MIN_SPREAD_MM`] both ways is refitted by
//! least squares and its members are the targets within `max(PLANE_TOL_MM / 2, 3 × RMS)`;
//! then the next, among the targets left. The RMS of a plane's targets about it is its
//! flatness as the photographs measure it (a wall's bulge, a target off the wall): it is
//! reported, not assumed. Each plane is bounded by its targets' extent and [`MARGIN_MM`]:
//! a beam beyond it (past a wall's end, through a door) is not taken to be on it.
//!
//! **Beams.** Through an extrinsic, each beam's point is on the nearest plane within the
//! gate, unless it is within [`BALL_CLEARANCE_MM`] of a ball's surface (the ball, its stem):
//! then it is on the ball if within the gate of its sphere, else on neither; and a beam
//! within [`EDGE_CLEARANCE_MM`] of two planes (where a wall meets the floor or another wall)
//! is on neither: its footprint mixes them (on the simulator's noiseless corner, such
//! beams were off by up to 43 mm, the rest within 2 mm).

use crate::ids::PointId;
use crate::scene::{PointKind, Scene};
use nalgebra::Vector3;
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator};
use pingcal_geometry::Plane;

type V3 = Vector3<f64>;

/// Consensus tolerance of a target on a plane (mm).
pub const PLANE_TOL_MM: f64 = 10.0;
/// Fewest targets that define a plane.
pub const MIN_PLANE_TARGETS: usize = 6;
/// Smallest spread of a plane's targets along each in-plane axis (RMS, mm).
pub const MIN_SPREAD_MM: f64 = 100.0;
/// How far beyond its targets' extent a plane reaches (mm).
pub const MARGIN_MM: f64 = 400.0;
/// Beams within this of two planes (where walls and the floor meet) are on neither: the
/// beam's footprint spans both, and its range mixes them (mm).
pub const EDGE_CLEARANCE_MM: f64 = 40.0;
/// Beams within this of a ball's surface are not taken to be on a plane (mm).
pub const BALL_CLEARANCE_MM: f64 = 40.0;
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
    /// In-plane axes and the targets' extent along them, widened by [`MARGIN_MM`].
    bounds: (V3, V3, [f64; 4]),
}

impl FieldPlane {
    /// Whether `x`'s foot on the plane lies within its bounds.
    pub fn contains(&self, x: &V3) -> bool {
        let (e1, e2, b) = &self.bounds;
        let d = x - self.centre;
        let (u, v) = (e1.dot(&d), e2.dot(&d));
        u >= b[0] && u <= b[1] && v >= b[2] && v <= b[3]
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
    let b = [
        b[0] - MARGIN_MM,
        b[1] + MARGIN_MM,
        b[2] - MARGIN_MM,
        b[3] + MARGIN_MM,
    ];
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

/// What the point `x` (object frame) is on, within `gate` (mm) of the surface: a ball of
/// `balls` (centre, radius; within the smaller of the gate and [`BALL_CLEARANCE_MM`]) or,
/// clear of every ball, the nearest plane of `planes`.
pub fn on_what(x: &V3, planes: &[FieldPlane], balls: &[(V3, f64)], gate: f64) -> Option<On> {
    for (k, (c, r)) in balls.iter().enumerate() {
        let d = (x - c).norm() - r;
        if d.abs() <= gate.min(BALL_CLEARANCE_MM) {
            return Some(On::Ball(k));
        }
        if d < BALL_CLEARANCE_MM {
            return None;
        }
    }
    let mut near: Vec<(usize, f64)> = (planes.iter().enumerate())
        .filter(|(_, p)| p.contains(x))
        .map(|(k, p)| (k, p.distance(x).abs()))
        .filter(|(_, d)| *d <= gate.max(EDGE_CLEARANCE_MM))
        .collect();
    near.sort_by(|a, b| a.1.total_cmp(&b.1));
    match near.as_slice() {
        // where two planes meet, a beam's footprint spans both: a mixed range, on neither
        [_, second, ..] if second.1 <= EDGE_CLEARANCE_MM => None,
        [(k, d), ..] if *d <= gate => Some(On::Plane(*k)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane_of(n: V3, d: f64) -> FieldPlane {
        FieldPlane::square(n, d, 1000.0)
    }

    /// A point near a ball is the ball's, or nobody's (its stem, the ball's rim); else the
    /// nearest plane's within the gate and the plane's bounds.
    #[test]
    fn a_point_is_on_the_nearest_surface_within_the_gate() {
        let planes = [plane_of(V3::x(), 0.0), plane_of(V3::z(), 0.0)];
        let balls = [(V3::new(60.0, 500.0, 400.0), 19.0)];
        let gate = 30.0;
        assert_eq!(
            on_what(&V3::new(5.0, 300.0, 600.0), &planes, &balls, gate),
            Some(On::Plane(0))
        );
        assert_eq!(
            on_what(&V3::new(300.0, 300.0, -8.0), &planes, &balls, gate),
            Some(On::Plane(1))
        );
        assert_eq!(
            on_what(&V3::new(41.0, 500.0, 400.0), &planes, &balls, gate),
            Some(On::Ball(0))
        );
        // the stem between the ball and the wall
        assert_eq!(
            on_what(&V3::new(20.0, 500.0, 370.0), &planes, &balls, gate),
            None
        );
        // where the wall meets the floor
        assert_eq!(
            on_what(&V3::new(12.0, 300.0, 25.0), &planes, &balls, gate),
            None
        );
        // beyond the wall's end
        assert_eq!(
            on_what(&V3::new(5.0, 3000.0, 600.0), &planes, &balls, gate),
            None
        );
        assert_eq!(
            on_what(&V3::new(200.0, 300.0, 600.0), &planes, &balls, gate),
            None
        );
    }
}
