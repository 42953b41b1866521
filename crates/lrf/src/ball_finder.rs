//! Automatic ball finding in a room-sized cloud.
//!
//! 1. **Planes out.** Sequential RANSAC of large planes (walls, floor) on a seeded sub-sample,
//!    refined by least squares; every point within `plane_k_sigma · σ(range)` of a plane is
//!    removed. A plane must be large (second principal spread over 2·D), so a ball cap is
//!    never taken for a plane.
//! 2. **Clusters.** Euclidean clustering of what is left (link distance
//!    `max(D/2, 2.5 σ(range))`, so noisy far balls stay in one piece); clusters with fewer
//!    than `min_points` points or larger than `max_cluster_extent_d · D` are dropped.
//! 3. **RANSAC** in each cluster: spheres through 4 points, kept only with a radius within
//!    `radius_bounds` of the nominal one and the centre behind the sampled surface; the
//!    hypothesis with the most points within `2σ` of the nominal sphere wins.
//! 4. **Fit** with [`crate::sphere_fit::fit_along_ray`] at the nominal radius, which rejects
//!    mixed pixels (beams grazing the silhouette, returning a range between ball and wall)
//!    and stem points. Each ball carries its covariance and inlier count; a ball with fewer
//!    than `min_inliers` rays, or a fit whose σ₀ shows it is not a sphere of that size, is
//!    reported in [`FindResult::rejected`], not used.

use crate::cloud::Cloud;
use crate::sensor::RangeNoise;
use crate::sphere_fit::{self, FitOptions, Ray};
use nalgebra::{Matrix3, Vector3};
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator, Sampling, SeededRng};
use pingcal_geometry::Plane;
use rand::Rng;
use rayon::prelude::*;
use std::collections::HashMap;

/// Options of [`find_balls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinderOptions {
    /// Ball diameter, mm (38 for a ping-pong ball).
    pub diameter_mm: f64,
    /// Range noise model (σ of each range).
    pub noise: RangeNoise,
    /// Options of the along-ray fit.
    pub fit: FitOptions,
    /// Remove large planes first.
    pub remove_planes: bool,
    /// At most this many planes.
    pub max_planes: usize,
    /// A plane must hold at least this fraction of the points.
    pub plane_min_fraction: f64,
    /// Points within this many σ of a plane are removed.
    pub plane_k_sigma: f64,
    /// Clusters with fewer points are ignored.
    pub min_points: usize,
    /// Clusters larger than this many diameters (largest distance from their centroid) are ignored.
    pub max_cluster_extent_d: f64,
    /// RANSAC hypotheses per cluster.
    pub ransac_iters: usize,
    /// Accepted radius of a 4-point hypothesis, as fractions of the nominal radius.
    pub radius_bounds: (f64, f64),
    /// A ball needs at least this many rays after mixed-pixel rejection.
    pub min_inliers: usize,
    /// A fit with σ₀ above this is not a sphere of the nominal size.
    pub max_sigma0: f64,
    /// A centre whose largest standard deviation exceeds this (mm) is not determined by its rays.
    pub max_centre_sigma_mm: f64,
    /// A wall is a plane whose second principal spread (σ of its points across the plane's
    /// shorter side) is at least this (mm) *and* larger than the ball's radius, which no
    /// visible cap of a ball can be.
    pub min_wall_spread_mm: f64,
    /// The fraction of the beams that must meet a real ball (those inside its incidence and
    /// footprint gate) that may still pass through it (range beyond its surface by more than
    /// `outlier_k` σ: gross range errors). A sphere is rejected when its count of such beams
    /// is improbable (p < [`THROUGH_SIGNIFICANCE`], binomial) under this rate. The eight real
    /// VLP-16 frames show 6 in about 870 (0.7 %).
    pub through_rate: f64,
    /// Keep a ball seen twice (see [`Support::seen_twice`]) instead of rejecting it: for a
    /// calibration that estimates the LRF's mount, whose beams will put the two copies
    /// together (the ball's other tests still apply).
    pub keep_seen_twice: bool,
    /// A sphere is rejected when fewer than this fraction of its cluster's points lie on it.
    pub min_cluster_fraction: f64,
    /// Accepted difference between the free-radius fit and the nominal radius beyond its
    /// 3σ, as a fraction of the nominal radius (the tolerance of the ball's making).
    pub radius_tolerance: f64,
    /// A sphere is rejected when its inliers, seen from the sensor, cover fewer than this
    /// many of the 8 sectors around its centre (see [`Support::coverage`]).
    pub min_sectors: usize,
    /// Seed of every random choice.
    pub seed: u64,
}

impl Default for FinderOptions {
    fn default() -> Self {
        FinderOptions {
            diameter_mm: 38.0,
            noise: RangeNoise::urg_04lx(),
            fit: FitOptions::default(),
            remove_planes: true,
            max_planes: 6,
            plane_min_fraction: 0.03,
            plane_k_sigma: 2.5,
            min_points: 6,
            max_cluster_extent_d: 6.0,
            ransac_iters: 200,
            radius_bounds: (0.5, 1.5),
            min_inliers: 6,
            max_sigma0: 2.5,
            max_centre_sigma_mm: 10.0,
            min_wall_spread_mm: 250.0,
            through_rate: 0.01,
            keep_seen_twice: false,
            min_cluster_fraction: 0.3,
            radius_tolerance: 0.05,
            min_sectors: 4,
            seed: 1,
        }
    }
}

/// A ball found in the cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct Ball {
    /// Centre in the LRF frame, mm.
    pub centre: Vector3<f64>,
    /// Covariance of the centre, mm².
    pub cov: Matrix3<f64>,
    /// Cloud indices of the rays used by the fit.
    pub inliers: Vec<usize>,
    /// Points in the cluster the ball came from.
    pub cluster_points: usize,
    /// Cluster points not used (mixed pixels, stem, outliers).
    pub rejected_points: usize,
    /// σ₀ of the fit.
    pub sigma0: f64,
    /// Range of the centre from the origin, mm.
    pub range_mm: f64,
    /// What else the cloud says about this sphere (the acceptance tests' figures).
    pub support: Support,
}

/// The evidence for a sphere beyond its own fit: every beam of the cloud (walls included)
/// that should have met it, and a free-radius fit of its inliers.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Support {
    /// Beams meeting the sphere within [`THROUGH_MAX_INCIDENCE_DEG`] (and clear of the rim by
    /// their footprint) whose range is on its surface (within `outlier_k` σ).
    pub on_surface: usize,
    /// Beams inside that cone whose range is beyond the surface by more than `outlier_k` σ:
    /// they passed through where the sphere is said to be, which a solid ball forbids.
    pub through: usize,
    /// Fraction of the cluster's points used by the fit.
    pub cluster_fraction: f64,
    /// Radius of a free-radius fit of the inliers, mm…
    pub free_radius_mm: f64,
    /// …and its σ (a-priori σ scaled by the fit's σ₀ when that is above 1), mm.
    pub sigma_free_radius_mm: f64,
    /// Range σ of the sensor at the centre's range, mm.
    pub range_sigma_mm: f64,
    /// Too many beams pass through it, about as many as meet it: one ball whose points
    /// from different sweeps do not coincide (seen twice), as under a wrong mount model.
    pub seen_twice: bool,
    /// The sectors (bit k: sector k of 8 around the centre, seen along the mean beam) of the
    /// annulus just outside the rim ([`BESIDE_WIDTH`] radii wide) where at least
    /// [`BESIDE_MIN_BEAMS`] beams stop at the depth of the ball's front (within R/2 behind
    /// it): a stem or a hand holding the ball fills one side, the floor under it a half
    /// ring, a pole or an edge that the "ball" is a piece of two opposite sides apart.
    pub beside: u8,
    /// Of 8 equal sectors around the centre, as seen along the mean beam, how many hold an
    /// inlier at least R/4 off the centre line: 8 for a well covered ball, few for a patch
    /// of something else that happens to curve like it.
    pub coverage: usize,
}

impl Support {
    /// Whether the free-radius fit determined a radius for a ball of nominal `radius`: it
    /// neither failed nor ran off (outside R/3…3R), as it does where the range σ is a fair
    /// part of the radius and the cap's curvature is barely above the noise.
    pub fn free_radius_determined(&self, radius: f64) -> bool {
        self.free_radius_mm.is_finite()
            && self.sigma_free_radius_mm.is_finite()
            && (radius / 3.0..=3.0 * radius).contains(&self.free_radius_mm)
    }
}

/// The annulus tested for a surface going on beside a ball is this many radii wide.
pub const BESIDE_WIDTH: f64 = 0.6;
/// A sector of that annulus is occupied with this many beams at the ball's depth.
pub const BESIDE_MIN_BEAMS: usize = 2;

/// Significance of the test for beams through a sphere (see [`FinderOptions::through_rate`]).
pub const THROUGH_SIGNIFICANCE: f64 = 1e-3;

/// The largest count of beams through a real ball that is not improbable: the largest `x`
/// with P(X ≥ x) ≥ [`THROUGH_SIGNIFICANCE`] for X ~ Binomial(`n`, `p`) (normal approximation
/// past n·p = 30).
pub fn through_allowed(n: usize, p: f64) -> usize {
    let p = p.clamp(1e-9, 0.5);
    let mean = n as f64 * p;
    if mean > 30.0 {
        return (mean + 3.09 * (mean * (1.0 - p)).sqrt()).floor() as usize;
    }
    // P(X ≥ x) = 1 − Σ_{i<x} pmf(i), pmf(i+1) = pmf(i)·(n−i)/(i+1)·p/(1−p)
    let mut pmf = (1.0 - p).powi(n as i32);
    let mut below = 0.0;
    for x in 0..=n {
        // here below = P(X < x)
        if 1.0 - below < THROUGH_SIGNIFICANCE {
            return x.saturating_sub(1);
        }
        below += pmf;
        pmf *= (n - x) as f64 / (x + 1) as f64 * p / (1.0 - p);
    }
    n
}

/// A candidate that was not accepted as a ball.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejected {
    /// Best estimate of where it is, mm.
    pub centre: Vector3<f64>,
    /// Points in its cluster.
    pub cluster_points: usize,
    /// Why it was not used.
    pub reason: String,
    /// As many beams pass through it as meet it (at least half as many): one ball whose
    /// points from different sweeps do not coincide — seen twice, as under a wrong mount
    /// model — rather than clutter.
    pub seen_twice: bool,
}

/// What [`find_balls`] found.
#[derive(Debug, Clone, Default)]
pub struct FindResult {
    /// Accepted balls, sorted by range.
    pub balls: Vec<Ball>,
    /// Candidates not used, with the reason.
    pub rejected: Vec<Rejected>,
    /// Planes removed (unit normal, offset: n·x = d).
    pub planes: Vec<(Vector3<f64>, f64)>,
    /// Clusters examined.
    pub clusters: usize,
}

impl FindResult {
    /// Candidates rejected because as many beams pass through them as meet them
    /// ([`Rejected::seen_twice`]).
    pub fn seen_twice_rejected(&self) -> usize {
        self.rejected.iter().filter(|r| r.seen_twice).count()
    }

    /// Accepted balls that were seen twice ([`Support::seen_twice`], kept under
    /// [`FinderOptions::keep_seen_twice`]).
    pub fn seen_twice_kept(&self) -> usize {
        self.balls.iter().filter(|b| b.support.seen_twice).count()
    }
}

fn point_sigma(cloud: &Cloud, noise: &RangeNoise, i: usize) -> f64 {
    noise
        .sigma((cloud.points[i] - cloud.origin(i)).norm())
        .max(0.5)
}

/// Planes through three points of a sub-sample of the cloud, for [`consensus::find`]; the
/// residual is the distance in units of `k_sigma` × the point's range σ. Three independent
/// draws may repeat a point: no plane then. The sub-sample's points and σ's are copied out
/// of the cloud in its order (each hypothesis visits them all: in place they would be
/// random reads over the whole cloud).
struct WallSamples {
    points: Vec<Vector3<f64>>,
    sigma: Vec<f64>,
    k_sigma: f64,
}

impl WallSamples {
    /// The points `sample` (cloud indices) of `cloud` with their σ's.
    fn gather(cloud: &Cloud, sample: &[usize], sigma: &[f64], k_sigma: f64) -> Self {
        WallSamples {
            points: sample.iter().map(|&i| cloud.points[i]).collect(),
            sigma: sample.iter().map(|&i| sigma[i]).collect(),
            k_sigma,
        }
    }
}

impl Estimator for WallSamples {
    type Model = (Vector3<f64>, f64);
    fn len(&self) -> usize {
        self.points.len()
    }
    fn sample_size(&self) -> usize {
        3
    }
    fn fit(&self, s: &[usize], planes: &mut Vec<(Vector3<f64>, f64)>) {
        let [a, b, c] = [0, 1, 2].map(|k| self.points[s[k]]);
        let nrm = (b - a).cross(&(c - a));
        if nrm.norm() < 1e-9 {
            return;
        }
        let nrm = nrm.normalize();
        planes.push((nrm, nrm.dot(&a)));
    }
    fn residual(&self, (nrm, d): &(Vector3<f64>, f64), k: usize) -> f64 {
        (nrm.dot(&self.points[k]) - d).abs() / (self.k_sigma * self.sigma[k])
    }
}

/// Of a wall's points within the plane gate, at least this fraction lie within 1 σ of it
/// (0.69 for Gaussian range noise at a 2.5 σ gate, 0.4 for points spread evenly).
pub const WALL_CORE_FRACTION: f64 = 0.55;

/// The large planes of `cloud` (walls, floor, ceiling) as step 1 of [`find_balls`] finds
/// them with the same options and seed: unit normal and offset, `n·x = d`.
pub fn find_walls(cloud: &Cloud, opt: &FinderOptions) -> Vec<(Vector3<f64>, f64)> {
    find_walls_explained(cloud, opt).0
}

/// A plane the wall search found and did not take for a wall ([`find_walls_explained`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefusedPlane {
    /// Points of the search's sub-sample within its gate.
    pub points: usize,
    /// Of those, the fraction within 1σ of it (a wall's scatter: at least
    /// [`WALL_CORE_FRACTION`]).
    pub core_fraction: f64,
    /// Its points' smaller in-plane spread (mm).
    pub spread_mm: f64,
    /// The smallest spread a wall needs (mm).
    pub min_spread_mm: f64,
}

impl RefusedPlane {
    /// Why it is not a wall, in words.
    pub fn reason(&self) -> String {
        if self.core_fraction < WALL_CORE_FRACTION {
            format!(
                "{} points scattered about it unlike range noise ({:.0} % within 1σ, {:.0} % needed)",
                self.points,
                100.0 * self.core_fraction,
                100.0 * WALL_CORE_FRACTION
            )
        } else {
            format!(
                "{} points {:.0} mm across, under the {:.0} mm a wall needs",
                self.points, self.spread_mm, self.min_spread_mm
            )
        }
    }
}

/// [`find_walls`], with the planes it found and did not take for walls (too narrow, or
/// scattered unlike range noise), in the order found.
pub fn find_walls_explained(
    cloud: &Cloud,
    opt: &FinderOptions,
) -> (Vec<(Vector3<f64>, f64)>, Vec<RefusedPlane>) {
    let mut rng = pingcal_geometry::consensus::rng(opt.seed);
    let mut refused = Vec::new();
    let planes = remove_planes(cloud, opt, &mut rng, &mut refused).0;
    (planes, refused)
}

/// Removes large planes; returns the planes and a mask of the points kept.
fn remove_planes(
    cloud: &Cloud,
    opt: &FinderOptions,
    rng: &mut SeededRng,
    refused: &mut Vec<RefusedPlane>,
) -> (Vec<(Vector3<f64>, f64)>, Vec<bool>) {
    let n = cloud.len();
    let mut keep = vec![true; n];
    let mut planes = Vec::new();
    let sigma: Vec<f64> = (0..n).map(|i| point_sigma(cloud, &opt.noise, i)).collect();
    let sub_n = n.min(40_000);
    let mut sample: Vec<usize> = if sub_n == n {
        (0..n).collect()
    } else {
        (0..sub_n).map(|_| rng.random_range(0..n)).collect()
    };
    let min_count = (opt.plane_min_fraction * sub_n as f64).max(30.0) as usize;
    for _ in 0..3 * opt.max_planes {
        if planes.len() >= opt.max_planes || sample.len() < min_count {
            break;
        }
        let walls = WallSamples::gather(cloud, &sample, &sigma, opt.plane_k_sigma);
        let opts = ConsensusOptions {
            sampling: Sampling::Independent,
            ..ConsensusOptions::ransac(1.0, 300)
        };
        let Some(best) = consensus::find(&walls, &opts, rng) else {
            break;
        };
        if best.inliers.len() < min_count {
            break;
        }
        let inl: Vec<Vector3<f64>> = best
            .inliers
            .iter()
            .map(|&k| cloud.points[sample[k]])
            .collect();
        let Some(plane) = Plane::fit(&inl) else {
            break;
        };
        let (n2, d2) = (plane.normal, plane.offset);
        let off = |i: usize| (n2.dot(&cloud.points[i]) - d2).abs() >= opt.plane_k_sigma * sigma[i];
        // a wall's points scatter about it as its range noise does (Gaussian: of those
        // within k σ, P(|z|<1)/P(|z|<k) = 0.69 at k = 2.5); a plane laid through clutter has
        // them spread evenly over its gate (1/k = 0.4)
        let z: Vec<f64> = best
            .inliers
            .iter()
            .map(|&k| (n2.dot(&cloud.points[sample[k]]) - d2).abs() / sigma[sample[k]])
            .collect();
        let gated = z.iter().filter(|&&v| v <= opt.plane_k_sigma).count().max(1);
        let core = z.iter().filter(|&&v| v <= 1.0).count();
        let wall_like = core as f64 / gated as f64 >= WALL_CORE_FRACTION;
        let min_spread = opt.min_wall_spread_mm.max(0.5 * opt.diameter_mm);
        if !wall_like || plane.spreads()[1] < min_spread {
            refused.push(RefusedPlane {
                points: best.inliers.len(),
                core_fraction: core as f64 / gated as f64,
                spread_mm: plane.spreads()[1],
                min_spread_mm: min_spread,
            });
            // not a wall (a table top, a box side, a person's back…): its points stay in
            // the cloud, but the search for walls goes on without them
            let drop: std::collections::HashSet<usize> =
                best.inliers.iter().map(|&k| sample[k]).collect();
            sample.retain(|i| !drop.contains(i));
            continue;
        }
        planes.push((n2, d2));
        sample.retain(|&i| off(i));
    }
    keep.par_iter_mut().enumerate().for_each(|(i, k)| {
        let p = cloud.points[i];
        *k = planes
            .iter()
            .all(|(nv, d)| (nv.dot(&p) - d).abs() >= opt.plane_k_sigma * sigma[i]);
    });
    (planes, keep)
}

/// Euclidean clusters of the kept points: connected components of "closer than the link"
/// (`max(D/2, 2.5 σ(range))` for each point, the longer of a pair's two), found by
/// [`crate::clustering::link_components`] in time bounded by the points, whatever their
/// coordinates. `scale` shrinks the link distance (used to split a cluster that is too large).
fn clusters(cloud: &Cloud, idx: &[usize], opt: &FinderOptions, scale: f64) -> Vec<Vec<usize>> {
    let points: Vec<Vector3<f64>> = idx.iter().map(|&i| cloud.points[i]).collect();
    let link: Vec<f64> = idx
        .iter()
        .map(|&i| scale * (0.5 * opt.diameter_mm).max(2.5 * point_sigma(cloud, &opt.noise, i)))
        .collect();
    crate::clustering::link_components(&points, &link)
        .into_iter()
        .map(|g| g.into_iter().map(|k| idx[k]).collect())
        .collect()
}

/// Each split of a too-large cluster shortens the link by this factor…
const SPLIT_FACTOR: f64 = 0.7;
/// …down to this fraction of the nominal link.
const SPLIT_MIN_SCALE: f64 = 0.1;

/// Sphere through four points: (centre, radius).
pub fn sphere_through(p: [Vector3<f64>; 4]) -> Option<(Vector3<f64>, f64)> {
    let a = Matrix3::from_rows(&[
        (p[1] - p[0]).transpose() * 2.0,
        (p[2] - p[0]).transpose() * 2.0,
        (p[3] - p[0]).transpose() * 2.0,
    ]);
    let n0 = p[0].norm_squared();
    let b = Vector3::new(
        p[1].norm_squared() - n0,
        p[2].norm_squared() - n0,
        p[3].norm_squared() - n0,
    );
    let c = a.lu().solve(&b)?;
    let r = (p[0] - c).norm();
    (c.iter().all(|v| v.is_finite()) && r.is_finite()).then_some((c, r))
}

/// Spheres through four points of a cluster, for [`consensus::find`]: a centre is kept
/// only with a radius within `bounds` of the nominal one and behind the sampled surface;
/// the residual is the distance from the nominal sphere in units of the ray's range σ.
struct SphereSamples<'a> {
    rays: &'a [Ray],
    pts: &'a [Vector3<f64>],
    radius: f64,
    bounds: (f64, f64),
}

impl Estimator for SphereSamples<'_> {
    type Model = Vector3<f64>;
    fn len(&self) -> usize {
        self.pts.len()
    }
    fn sample_size(&self) -> usize {
        4
    }
    fn fit(&self, s: &[usize], centres: &mut Vec<Vector3<f64>>) {
        if (0..4).any(|a| (a + 1..4).any(|b| s[a] == s[b])) {
            return;
        }
        let pts = self.pts;
        let Some((c, r)) = sphere_through([pts[s[0]], pts[s[1]], pts[s[2]], pts[s[3]]]) else {
            return;
        };
        if r < self.bounds.0 * self.radius || r > self.bounds.1 * self.radius {
            return;
        }
        let sm = s.iter().map(|&k| pts[k]).sum::<Vector3<f64>>() / 4.0;
        let view = s.iter().map(|&k| self.rays[k].dir).sum::<Vector3<f64>>();
        if (c - sm).dot(&view) <= 0.0 {
            return; // the visible cap is in front of the centre
        }
        centres.push(c);
    }
    fn residual(&self, c: &Vector3<f64>, k: usize) -> f64 {
        ((self.pts[k] - c).norm() - self.radius).abs() / self.rays[k].sigma
    }
}

enum Outcome {
    Ball(Ball),
    Rejected(Rejected),
}

fn examine(
    cloud: &Cloud,
    index: &DirectionIndex,
    cl: &[usize],
    opt: &FinderOptions,
    planes: &[(Vector3<f64>, f64)],
    seed: u64,
) -> Outcome {
    let radius = opt.diameter_mm / 2.0;
    let rays: Vec<Ray> = cl
        .iter()
        .map(|&i| {
            Ray::from_point(
                cloud.origin(i),
                cloud.points[i],
                point_sigma(cloud, &opt.noise, i),
            )
        })
        .collect();
    let pts: Vec<Vector3<f64>> = rays.iter().map(|r| r.point()).collect();
    let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let spheres = SphereSamples {
        rays: &rays,
        pts: &pts,
        radius,
        bounds: opt.radius_bounds,
    };
    let opts = ConsensusOptions {
        sampling: Sampling::Independent,
        ..ConsensusOptions::ransac(2.0, opt.ransac_iters)
    };
    let init = consensus::find(&spheres, &opts, &mut consensus::rng(seed)).map(|c| c.model);
    let reject = |centre: Vector3<f64>, reason: String| {
        Outcome::Rejected(Rejected {
            centre,
            cluster_points: cl.len(),
            reason,
            seen_twice: false,
        })
    };
    let f = match fit_cluster(&rays, radius, init, opt) {
        Err(e) => return reject(init.unwrap_or(mean), format!("no sphere fit: {e}")),
        Ok(f) => f,
    };
    let cluster = (rays.as_slice(), pts.as_slice(), mean);
    if let Some(reason) = refusal(cloud, &f, cluster, planes, opt) {
        return reject(f.centre, reason);
    }
    let used: Vec<Ray> = f.used.iter().map(|&k| rays[k]).collect();
    let support = support(cloud, index, &used, &f, opt, cl.len());
    match verdict(&support, radius, opt) {
        Some(reason) => Outcome::Rejected(Rejected {
            centre: f.centre,
            cluster_points: cl.len(),
            seen_twice: support.seen_twice,
            reason,
        }),
        None => Outcome::Ball(Ball {
            range_mm: f.centre.norm(),
            centre: f.centre,
            cov: f.cov,
            inliers: f.used.iter().map(|&k| cl[k]).collect(),
            cluster_points: cl.len(),
            rejected_points: cl.len() - f.used.len(),
            sigma0: f.sigma0,
            support,
        }),
    }
}

/// The along-ray sphere fit of a cluster's rays from the consensus start `init`.
fn fit_cluster(
    rays: &[Ray],
    radius: f64,
    init: Option<Vector3<f64>>,
    opt: &FinderOptions,
) -> crate::error::Result<sphere_fit::SphereFit> {
    // a consensus start a centimetre off can lose the ball in the first passes of the fit
    // (a cluster with clutter beside the ball): then the orthogonal fit's start is tried
    match sphere_fit::fit_along_ray(rays, radius, init, &opt.fit) {
        Ok(f) if f.used.len() >= opt.min_inliers => Ok(f),
        first if init.is_some() => {
            match (
                first,
                sphere_fit::fit_along_ray(rays, radius, None, &opt.fit),
            ) {
                (Ok(a), Ok(b)) if b.used.len() <= a.used.len() => Ok(a),
                (_, Ok(b)) => Ok(b),
                (first, Err(_)) => first,
            }
        }
        first => first,
    }
}

/// Why fit `f` of a cluster (its rays, their points and their mean) is not a ball: too few
/// points, not a sphere of the diameter, off its cluster, cutting a wall, on a wall's noise
/// tail, or its centre not determined; `None` when it may be one.
fn refusal(
    cloud: &Cloud,
    f: &sphere_fit::SphereFit,
    (rays, pts, mean): (&[Ray], &[Vector3<f64>], Vector3<f64>),
    planes: &[(Vector3<f64>, f64)],
    opt: &FinderOptions,
) -> Option<String> {
    let radius = opt.diameter_mm / 2.0;
    if f.used.len() < opt.min_inliers {
        return Some(format!(
            "too few points on the ball after mixed-pixel rejection: {} (need {})",
            f.used.len(),
            opt.min_inliers
        ));
    }
    if f.sigma0 > opt.max_sigma0 {
        return Some(format!(
            "not a {} mm sphere: σ₀ = {:.2}",
            opt.diameter_mm, f.sigma0
        ));
    }
    if (f.centre - mean).norm() > opt.diameter_mm * 2.0 {
        return Some("fit left its cluster".into());
    }
    // a solid ball cannot stand inside a wall (it may rest on the floor: touching is
    // allowed, to the plane's noise and the ball's making)…
    if planes.iter().any(|(n, d)| {
        let side = if *d > 0.0 { -1.0 } else { 1.0 }; // sensor side of n·x = d
        let slack = 3.0 * opt.noise.sigma(f.centre.norm()) + opt.radius_tolerance * radius;
        side * (n.dot(&f.centre) - d) < radius - slack
            && plane_is_there(cloud, (n, *d), &f.centre, radius, opt)
    }) {
        return Some("sphere cuts a wall plane".into());
    }
    // …and a "sphere" whose points hug a removed wall is a fit to the wall's noise tail
    // (the points just beyond the plane gate: 96 % of the Gaussian tail beyond k σ lies
    // within k + 1 σ), not a ball in front of it
    if planes.iter().any(|(n, d)| {
        let near = f
            .used
            .iter()
            .filter(|&&k| (n.dot(&pts[k]) - d).abs() <= (opt.plane_k_sigma + 1.0) * rays[k].sigma)
            .count();
        2 * near > f.used.len()
    }) {
        return Some("its points are the noise tail of a removed wall".into());
    }
    if f.cov.symmetric_eigenvalues().max().sqrt() > opt.max_centre_sigma_mm {
        return Some(format!(
            "centre not determined by its {} rays: σ = {:.1} mm",
            f.used.len(),
            f.cov.symmetric_eigenvalues().max().sqrt()
        ));
    }
    None
}

/// True when the removed plane `n·x = d` has points (within its gate, and not on the sphere)
/// less than a radius from the foot of the sphere's centre on it: a plane is a finite wall,
/// a table top or a box side, and a sphere beside one does not cut it.
fn plane_is_there(
    cloud: &Cloud,
    (n, d): (&Vector3<f64>, f64),
    c: &Vector3<f64>,
    radius: f64,
    opt: &FinderOptions,
) -> bool {
    let foot = c - n * (n.dot(c) - d);
    (0..cloud.len())
        .filter(|&i| {
            let p = cloud.points[i];
            let sigma = point_sigma(cloud, &opt.noise, i);
            (p - foot).norm_squared() <= radius * radius
                && (n.dot(&p) - d).abs() <= opt.plane_k_sigma * sigma
                // the sphere's own points where the plane slices it are no wall
                && ((p - c).norm() - radius).abs() > opt.fit.outlier_k * sigma
        })
        .nth(2)
        .is_some()
}

/// Beams meeting a sphere at more than this incidence are left out of the test for beams
/// through it: near the rim the footprint spreads over the surface and, on real lidars
/// (the VLP-16 frames of `spherecalib-vlp16`), returns ranges up to 110 mm behind the
/// surface at 60–70°; inside 50° a real ball leaves at most 2 of 72–349 beams through, a
/// fit to a chair or a wall corner 9–38.
pub const THROUGH_MAX_INCIDENCE_DEG: f64 = 50.0;

/// Where a beam stands to a sphere (centre `c` with a largest σ `sigma_c`, radius
/// `radius`): `None` when it meets the sphere at more than [`THROUGH_MAX_INCIDENCE_DEG`], or
/// within its footprint or 3 `sigma_c` of the rim (a small ball's rim is where its centre's
/// uncertainty puts it), else its range minus the front intersection's, in units of its σ
/// and the centre's.
fn gated_residual(
    ray: &Ray,
    c: &Vector3<f64>,
    sigma_c: f64,
    radius: f64,
    opt: &FitOptions,
) -> Option<f64> {
    let w = c - ray.origin;
    let b = ray.dir.dot(&w);
    let h2 = (w.norm_squared() - b * b).max(0.0);
    let half_width = opt.beam_width_a_mm + opt.beam_width_b * ray.range;
    let h_max = (radius * THROUGH_MAX_INCIDENCE_DEG.to_radians().sin()).min(radius - half_width)
        - 3.0 * sigma_c;
    if b <= 0.0 || h_max <= 0.0 || h2 > h_max * h_max {
        return None;
    }
    let s = (radius * radius - h2).sqrt();
    Some((ray.range - (b - s)) / (ray.sigma * ray.sigma + sigma_c * sigma_c).sqrt())
}

/// The cloud's points binned by their direction from the frame's origin (azimuth and
/// elevation, [`DirectionIndex::BIN_RAD`] bins), so that the beams near one sphere are found
/// without visiting the whole cloud. Beams start at their own origins (a rotating LRF's
/// scanner is off the servo axis), so a query widens its cone by the largest origin's
/// distance.
struct DirectionIndex {
    /// Point indices sorted by bin…
    order: Vec<u32>,
    /// …and each bin's range in `order`, by key.
    bins: HashMap<(i32, i32), (u32, u32)>,
    max_origin: f64,
}

impl DirectionIndex {
    const BIN_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

    fn key(p: &Vector3<f64>) -> (i32, i32) {
        let az = p.y.atan2(p.x);
        let el = p.z.atan2(p.x.hypot(p.y));
        (
            (az / Self::BIN_RAD).floor() as i32,
            (el / Self::BIN_RAD).floor() as i32,
        )
    }

    fn new(cloud: &Cloud) -> Self {
        let keys: Vec<(i32, i32)> = cloud.points.par_iter().map(Self::key).collect();
        let mut order: Vec<u32> = (0..cloud.len() as u32).collect();
        order.par_sort_unstable_by_key(|&i| keys[i as usize]);
        let mut bins = HashMap::new();
        let mut start = 0;
        for k in 1..=order.len() {
            if k == order.len() || keys[order[k] as usize] != keys[order[start] as usize] {
                bins.insert(keys[order[start] as usize], (start as u32, k as u32));
                start = k;
            }
        }
        let max_origin = (0..cloud.len())
            .map(|i| cloud.origin(i).norm())
            .fold(0.0, f64::max);
        DirectionIndex {
            order,
            bins,
            max_origin,
        }
    }

    /// Every point whose beam may pass within `reach` of `c` (a superset: the caller tests
    /// each exactly).
    fn near_cone(&self, c: &Vector3<f64>, reach: f64) -> Vec<usize> {
        let dist = c.norm();
        let sin_a = (reach + self.max_origin) / dist.max(1e-9);
        if sin_a >= 0.99 {
            return self.order.iter().map(|&i| i as usize).collect();
        }
        let a = sin_a.asin() + 1.5 * Self::BIN_RAD;
        let (kaz, kel) = Self::key(c);
        let el_c = c.z.atan2(c.x.hypot(c.y));
        let n_el = (a / Self::BIN_RAD).ceil() as i32;
        let full_turn = (std::f64::consts::TAU / Self::BIN_RAD).ceil() as i32;
        let mut out = Vec::new();
        for del in -n_el..=n_el {
            let el = el_c + del as f64 * Self::BIN_RAD;
            let cos_el = (el.abs() + Self::BIN_RAD)
                .min(std::f64::consts::FRAC_PI_2)
                .cos();
            let n_az = if cos_el < 1e-3 {
                full_turn
            } else {
                ((a / cos_el / Self::BIN_RAD).ceil() as i32).min(full_turn)
            };
            for daz in -n_az..=n_az {
                // azimuth wraps at ±π
                let mut az = kaz + daz;
                let half = full_turn / 2;
                if az < -half {
                    az += full_turn;
                } else if az >= half {
                    az -= full_turn;
                }
                if let Some(&(s, e)) = self.bins.get(&(az, kel + del)) {
                    out.extend(
                        self.order[s as usize..e as usize]
                            .iter()
                            .map(|&i| i as usize),
                    );
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// The evidence of the whole cloud for a fitted sphere (see [`Support`]); `inliers` are the
/// fit's rays, `cluster_points` the size of the cluster they came from.
fn support(
    cloud: &Cloud,
    index: &DirectionIndex,
    inliers: &[Ray],
    fit: &sphere_fit::SphereFit,
    opt: &FinderOptions,
    cluster_points: usize,
) -> Support {
    let (c, radius) = (&fit.centre, fit.radius);
    let sigma_c = (fit.cov_posterior().symmetric_eigenvalues().max().max(0.0))
        .sqrt()
        .max(fit.cov.symmetric_eigenvalues().max().max(0.0).sqrt());
    let k = opt.fit.outlier_k;
    // sectors around the centre line, seen along the mean beam
    let view = inliers.iter().map(|r| r.dir).sum::<Vector3<f64>>();
    let view = if view.norm() > 0.0 {
        view.normalize()
    } else {
        Vector3::x()
    };
    let e1 = view.cross(&Vector3::z());
    let e1 = if e1.norm() > 1e-6 {
        e1.normalize()
    } else {
        view.cross(&Vector3::x()).normalize()
    };
    let e2 = view.cross(&e1);
    let sector = |d: &Vector3<f64>| {
        let a = d
            .dot(&e2)
            .atan2(d.dot(&e1))
            .rem_euclid(std::f64::consts::TAU);
        ((a / std::f64::consts::TAU * 8.0) as usize).min(7)
    };
    // the annulus starts clear of the rim by the footprint and the centre's uncertainty (at
    // the farthest range of a beam to it) and is BESIDE_WIDTH radii wide
    let far = (c.norm() + radius) * (1.0 + 1e-9);
    let inner_at = |range: f64| {
        radius + 2.0 * (opt.fit.beam_width_a_mm + opt.fit.beam_width_b * range) + 3.0 * sigma_c
    };
    let outer = inner_at(far) + BESIDE_WIDTH * radius;
    let (mut on_surface, mut through) = (0, 0);
    let mut beside = [0usize; 8];
    for i in index.near_cone(c, outer) {
        let o = cloud.origin(i);
        // cheap rejection: the beam's line passes the centre farther than the annulus around
        // the ball (or the ball is behind the origin)
        let v = cloud.points[i] - o;
        let w = c - o;
        let vw = v.dot(&w);
        let (v2, w2) = (v.norm_squared(), w.norm_squared());
        if vw <= 0.0 || vw * vw < v2 * (w2 - outer * outer) {
            continue;
        }
        let ray = Ray::from_point(o, cloud.points[i], point_sigma(cloud, &opt.noise, i));
        match gated_residual(&ray, c, sigma_c, radius, &opt.fit) {
            Some(z) if z.abs() <= k => on_surface += 1,
            Some(z) if z > k => through += 1,
            Some(_) => {}
            None => {
                // a beam passing just outside the rim that stops at the ball's depth: the
                // surface goes on beside the ball
                let b = ray.dir.dot(&w);
                let q = o + ray.dir * b - c;
                let h = q.norm();
                let front = b - radius; // the depth of a surface the cap would be part of
                let sd = (ray.sigma * ray.sigma + sigma_c * sigma_c).sqrt();
                if h > inner_at(ray.range)
                    && h <= outer
                    && ray.range >= front - k * sd
                    && ray.range <= front + (0.5 * radius).max(k * sd)
                {
                    beside[sector(&q)] += 1;
                }
            }
        }
    }
    let (free_radius_mm, sigma_free_radius_mm) =
        match sphere_fit::free_radius_along_ray(inliers, *c, radius, &opt.fit) {
            Ok((r, sr, s0)) => (r, sr * s0.max(1.0)),
            Err(_) => (f64::NAN, f64::INFINITY),
        };
    let mut sectors = [false; 8];
    for r in inliers {
        let d = r.point() - c;
        if (d - view * d.dot(&view)).norm() >= radius / 4.0 {
            sectors[sector(&d)] = true;
        }
    }
    let occupied: Vec<usize> = (0..8).filter(|&s| beside[s] >= BESIDE_MIN_BEAMS).collect();
    Support {
        on_surface,
        through,
        cluster_fraction: inliers.len() as f64 / cluster_points.max(1) as f64,
        free_radius_mm,
        sigma_free_radius_mm,
        range_sigma_mm: opt.noise.sigma(c.norm()).max(0.5),
        seen_twice: through > through_allowed(on_surface + through, opt.through_rate)
            && 2 * through >= on_surface,
        coverage: sectors.iter().filter(|&&b| b).count(),
        beside: occupied.iter().fold(0u8, |m, &s| m | (1 << s)),
    }
}

/// Why a fitted sphere is not a ball, or `None` when its support holds.
fn verdict(s: &Support, radius: f64, opt: &FinderOptions) -> Option<String> {
    if s.through > through_allowed(s.on_surface + s.through, opt.through_rate)
        && !(opt.keep_seen_twice && s.seen_twice)
    {
        return Some(format!(
            "{} beams pass through where the sphere would be ({} meet it): not a solid ball{}",
            s.through,
            s.on_surface,
            if 2 * s.through >= s.on_surface {
                " (or one ball seen twice: its points from different sweeps do not coincide, as under a wrong mount model)"
            } else {
                ""
            }
        ));
    }
    // beyond its σ and the ball's making, a radius from points whose range σ is a fair part
    // of it is biased by the surface's curvature, by O(σ²/R). Where the range σ is over a
    // quarter of the radius (a ping-pong ball under a URG-04LX) the cap's curvature is
    // barely above the noise: a fit that fails or runs off (r outside R/3…3R) says the
    // radius is not determined, not that it is wrong.
    let dr = (s.free_radius_mm - radius).abs();
    let curvature = s.range_sigma_mm.powi(2) / radius;
    let testable = s.free_radius_determined(radius) || s.range_sigma_mm <= radius / 4.0;
    if testable && !(dr <= 3.0 * s.sigma_free_radius_mm + opt.radius_tolerance * radius + curvature)
    {
        return Some(format!(
            "a free-radius fit gives r = {:.1} ± {:.1} mm, not the nominal {:.1} mm",
            s.free_radius_mm, s.sigma_free_radius_mm, radius
        ));
    }
    if s.cluster_fraction < opt.min_cluster_fraction {
        return Some(format!(
            "only {:.0} % of its cluster lies on it (need {:.0} %)",
            100.0 * s.cluster_fraction,
            100.0 * opt.min_cluster_fraction
        ));
    }
    // a line through the ball: two sectors 3–4 apart occupied with a free sector on each of
    // the two arcs between them (a floor or a body beside a real ball fills one unbroken
    // arc: a half ring, or one side)
    let on = |k: usize| s.beside & (1 << (k % 8)) != 0;
    let free_between = |a: usize, b: usize| (a + 1..b).any(|k| !on(k));
    let line = (0..8).any(|a| {
        (a + 3..=a + 5).any(|b| on(a) && on(b) && free_between(a, b) && free_between(b, a + 8))
    });
    if s.beside.count_ones() >= 6 {
        return Some(format!(
            "a surface surrounds it at its front's depth (sectors {:08b} of the ring around it): a bump on a surface, not a ball",
            s.beside
        ));
    }
    if line {
        return Some(format!(
            "a surface runs through it at its front's depth (sectors {:08b} of the ring around it): a piece of a pole or an edge, not a ball",
            s.beside
        ));
    }
    if s.coverage < opt.min_sectors {
        return Some(format!(
            "its points cover {} of 8 sectors around the centre (need {}): a patch, not a ball",
            s.coverage, opt.min_sectors
        ));
    }
    None
}

/// Finds every ball of the given diameter in the cloud.
pub fn find_balls(cloud: &Cloud, opt: &FinderOptions) -> FindResult {
    let mut rng = pingcal_geometry::consensus::rng(opt.seed);
    let (planes, keep) = if opt.remove_planes {
        remove_planes(cloud, opt, &mut rng, &mut Vec::new())
    } else {
        (Vec::new(), vec![true; cloud.len()])
    };
    let idx: Vec<usize> = (0..cloud.len()).filter(|&i| keep[i]).collect();
    let all = clusters(cloud, &idx, opt, 1.0);
    let n_clusters = all.len();
    // A cluster larger than a ball is split by clustering it again with a shorter link. In a
    // dense sweep the few wall points beyond the plane gate (the Gaussian tail, ~1 % of a
    // wall) come closer together than the link distance and chain the balls in front of the
    // wall into one wall-sized cluster; a ball's own points are far denser than that tail, so
    // a shorter link separates them again. A sparse sweep never needs the split.
    let extent_ok = |c: &[usize]| {
        let m = c.iter().map(|&i| cloud.points[i]).sum::<Vector3<f64>>() / c.len() as f64;
        c.iter()
            .all(|&i| (cloud.points[i] - m).norm() <= opt.max_cluster_extent_d * opt.diameter_mm)
    };
    let mut cands: Vec<Vec<usize>> = Vec::new();
    let mut work: Vec<(Vec<usize>, f64)> = all.into_iter().map(|c| (c, 1.0)).collect();
    while let Some((c, scale)) = work.pop() {
        if c.len() < opt.min_points {
            continue;
        }
        if extent_ok(&c) {
            cands.push(c);
        } else if scale > SPLIT_MIN_SCALE {
            let s = scale * SPLIT_FACTOR;
            work.extend(clusters(cloud, &c, opt, s).into_iter().map(|p| (p, s)));
        }
    }
    cands.sort_by_key(|g| g[0]);
    let index = DirectionIndex::new(cloud);
    let outcomes: Vec<Outcome> = cands
        .par_iter()
        .enumerate()
        .map(|(k, c)| {
            examine(
                cloud,
                &index,
                c,
                opt,
                &planes,
                opt.seed ^ (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15),
            )
        })
        .collect();
    let mut res = FindResult {
        planes,
        clusters: n_clusters,
        ..Default::default()
    };
    for o in outcomes {
        match o {
            Outcome::Ball(b) => {
                // one ball split into two clusters: keep the better-supported fit
                if let Some(prev) = res
                    .balls
                    .iter_mut()
                    .find(|p| (p.centre - b.centre).norm() < opt.diameter_mm / 2.0)
                {
                    if b.inliers.len() > prev.inliers.len() {
                        *prev = b;
                    }
                } else {
                    res.balls.push(b);
                }
            }
            Outcome::Rejected(r) => res.rejected.push(r),
        }
    }
    res.balls.sort_by(|a, b| a.range_mm.total_cmp(&b.range_mm));
    res
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beams_through_a_ball_allowed_by_the_binomial_tail() {
        // n p = 0.28: P(X ≥ 3) = 2.7e-3, P(X ≥ 4) = 1.7e-4
        assert_eq!(through_allowed(28, 0.01), 3);
        assert_eq!(through_allowed(0, 0.01), 0);
        // n p = 3.5: P(X ≥ 10) = 3.1e-3, P(X ≥ 11) = 9.5e-4 (scipy.stats.binom)
        assert_eq!(through_allowed(350, 0.01), 10);
        // normal approximation past n p = 30
        assert_eq!(through_allowed(10_000, 0.01), 130);
    }

    #[test]
    fn four_point_sphere() {
        let c = Vector3::new(1.0, 2.0, 3.0);
        let p = [Vector3::x(), Vector3::y(), Vector3::z(), -Vector3::x()].map(|d| c + d * 19.0);
        let (cc, r) = sphere_through(p).unwrap();
        assert!((cc - c).norm() < 1e-9 && (r - 19.0).abs() < 1e-9);
        assert!(sphere_through([
            Vector3::zeros(),
            Vector3::x(),
            Vector3::y(),
            Vector3::x() + Vector3::y()
        ])
        .is_none());
    }
}
