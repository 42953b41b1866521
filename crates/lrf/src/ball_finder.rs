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

fn point_sigma(cloud: &Cloud, noise: &RangeNoise, i: usize) -> f64 {
    noise
        .sigma((cloud.points[i] - cloud.origin(i)).norm())
        .max(0.5)
}

/// Planes through three points of the sub-sample `sample` (cloud indices), for
/// [`consensus::find`]; the residual is the distance in units of `k_sigma` × the point's
/// range σ. Three independent draws may repeat a point: no plane then.
struct WallSamples<'a> {
    cloud: &'a Cloud,
    sample: &'a [usize],
    sigma: &'a [f64],
    k_sigma: f64,
}

impl Estimator for WallSamples<'_> {
    type Model = (Vector3<f64>, f64);
    fn len(&self) -> usize {
        self.sample.len()
    }
    fn sample_size(&self) -> usize {
        3
    }
    fn fit(&self, s: &[usize], planes: &mut Vec<(Vector3<f64>, f64)>) {
        let [a, b, c] = [0, 1, 2].map(|k| self.cloud.points[self.sample[s[k]]]);
        let nrm = (b - a).cross(&(c - a));
        if nrm.norm() < 1e-9 {
            return;
        }
        let nrm = nrm.normalize();
        planes.push((nrm, nrm.dot(&a)));
    }
    fn residual(&self, (nrm, d): &(Vector3<f64>, f64), k: usize) -> f64 {
        let i = self.sample[k];
        (nrm.dot(&self.cloud.points[i]) - d).abs() / (self.k_sigma * self.sigma[i])
    }
}

/// Removes large planes; returns the planes and a mask of the points kept.
fn remove_planes(
    cloud: &Cloud,
    opt: &FinderOptions,
    rng: &mut SeededRng,
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
    for _ in 0..opt.max_planes {
        if sample.len() < min_count {
            break;
        }
        let walls = WallSamples {
            cloud,
            sample: &sample,
            sigma: &sigma,
            k_sigma: opt.plane_k_sigma,
        };
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
        if plane.spreads()[1] < 2.0 * opt.diameter_mm {
            break; // not a wall: too small
        }
        let (n2, d2) = (plane.normal, plane.offset);
        planes.push((n2, d2));
        sample.retain(|&i| (n2.dot(&cloud.points[i]) - d2).abs() >= opt.plane_k_sigma * sigma[i]);
    }
    keep.par_iter_mut().enumerate().for_each(|(i, k)| {
        let p = cloud.points[i];
        *k = planes
            .iter()
            .all(|(nv, d)| (nv.dot(&p) - d).abs() >= opt.plane_k_sigma * sigma[i]);
    });
    (planes, keep)
}

/// Euclidean clusters of the kept points (union-find on a hash grid).
/// `scale` shrinks the link distance (used to split a cluster that is too large).
fn clusters(cloud: &Cloud, idx: &[usize], opt: &FinderOptions, scale: f64) -> Vec<Vec<usize>> {
    if idx.is_empty() {
        return Vec::new();
    }
    let link: Vec<f64> = idx
        .iter()
        .map(|&i| scale * (0.5 * opt.diameter_mm).max(2.5 * point_sigma(cloud, &opt.noise, i)))
        .collect();
    let cell = link.iter().cloned().fold(0.0, f64::max);
    let key = |p: &Vector3<f64>| {
        (
            (p.x / cell).floor() as i64,
            (p.y / cell).floor() as i64,
            (p.z / cell).floor() as i64,
        )
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<usize>> = HashMap::new();
    for (k, &i) in idx.iter().enumerate() {
        grid.entry(key(&cloud.points[i])).or_default().push(k);
    }
    let mut parent: Vec<usize> = (0..idx.len()).collect();
    fn root(p: &mut [usize], mut a: usize) -> usize {
        while p[a] != a {
            p[a] = p[p[a]];
            a = p[a];
        }
        a
    }
    for (k, &i) in idx.iter().enumerate() {
        let p = cloud.points[i];
        let (x, y, z) = key(&p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(v) = grid.get(&(x + dx, y + dy, z + dz)) {
                        for &m in v {
                            if m > k && (cloud.points[idx[m]] - p).norm() < link[k].max(link[m]) {
                                let (a, b) = (root(&mut parent, k), root(&mut parent, m));
                                if a != b {
                                    parent[a.max(b)] = a.min(b);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for (k, &i) in idx.iter().enumerate() {
        let r = root(&mut parent, k);
        groups.entry(r).or_default().push(i);
    }
    let mut out: Vec<Vec<usize>> = groups.into_values().collect();
    out.sort_by_key(|g| g[0]);
    out
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
        })
    };
    match sphere_fit::fit_along_ray(&rays, radius, init, &opt.fit) {
        Err(e) => reject(init.unwrap_or(mean), format!("no sphere fit: {e}")),
        Ok(f) if f.used.len() < opt.min_inliers => reject(
            f.centre,
            format!(
                "too few points on the ball after mixed-pixel rejection: {} (need {})",
                f.used.len(),
                opt.min_inliers
            ),
        ),
        Ok(f) if f.sigma0 > opt.max_sigma0 => reject(
            f.centre,
            format!("not a {} mm sphere: σ₀ = {:.2}", opt.diameter_mm, f.sigma0),
        ),
        Ok(f) if (f.centre - mean).norm() > opt.diameter_mm * 2.0 => {
            reject(f.centre, "fit left its cluster".into())
        }
        // a real ball stands clear in front of every wall (seen from the sensor); a "sphere"
        // whose back is within one range σ of a wall, or behind it, is a fit to the wall's
        // noise tail (the points just beyond the plane gate)
        Ok(f)
            if planes.iter().any(|(n, d)| {
                let side = if *d > 0.0 { -1.0 } else { 1.0 }; // sensor side of n·x = d
                side * (n.dot(&f.centre) - d) < radius + opt.noise.sigma(f.centre.norm())
            }) =>
        {
            reject(
                f.centre,
                "sphere cuts a wall plane or stands within 1σ of it".into(),
            )
        }
        Ok(f) if f.cov.symmetric_eigenvalues().max().sqrt() > opt.max_centre_sigma_mm => reject(
            f.centre,
            format!(
                "centre not determined by its {} rays: σ = {:.1} mm",
                f.used.len(),
                f.cov.symmetric_eigenvalues().max().sqrt()
            ),
        ),
        Ok(f) => Outcome::Ball(Ball {
            range_mm: f.centre.norm(),
            centre: f.centre,
            cov: f.cov,
            inliers: f.used.iter().map(|&k| cl[k]).collect(),
            cluster_points: cl.len(),
            rejected_points: cl.len() - f.used.len(),
            sigma0: f.sigma0,
        }),
    }
}

/// Finds every ball of the given diameter in the cloud.
pub fn find_balls(cloud: &Cloud, opt: &FinderOptions) -> FindResult {
    let mut rng = pingcal_geometry::consensus::rng(opt.seed);
    let (planes, keep) = if opt.remove_planes {
        remove_planes(cloud, opt, &mut rng)
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
    let outcomes: Vec<Outcome> = cands
        .par_iter()
        .enumerate()
        .map(|(k, c)| {
            examine(
                cloud,
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
