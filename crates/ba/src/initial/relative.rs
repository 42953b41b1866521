//! Relative orientation of two images: the essential matrix from corresponding rays,
//! by the normalised 8-point algorithm inside RANSAC, decomposed into the four (R, t)
//! candidates of which cheirality (points in front of both cameras) keeps one.
//!
//! Conventions: the rays are unit vectors in each camera's frame (X right, Y forward,
//! Z up, as [`crate::camera::CameraModel::unproject`] gives them); the result is the pose of
//! the second camera in the first camera's frame, `x₂ = R x₁ + t` with |t| = 1, and the
//! epipolar constraint is `d₂ᵀ E d₁ = 0` with `E = [t]× R`. For the 8-point system the rays
//! are put on the image plane Y = 1 and normalised (Hartley: centroid at the origin, mean
//! distance √2), which keeps it well conditioned for narrow fields of view.
//!
//! Flat scenes: the 8-point algorithm is degenerate when all points lie on one plane (a flat
//! test field), where a whole family of essential matrices fits. A homography between the
//! two images is therefore estimated as well (normalised 4-point DLT in RANSAC on the same
//! plane coordinates); when it explains at least 80 % as many correspondences as the
//! essential matrix, the scene is taken as planar and the pose comes from the homography's
//! decomposition (Faugeras & Lustman 1988: eight candidates, ±t), the candidate with the
//! most points in front of both cameras winning. [`Relative::planar`] says which path
//! was taken.

use nalgebra::{Matrix3, SMatrix, Vector2, Vector3};
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator, RefitRule};
use pingcal_geometry::dlt::hartley_normaliser;
use pingcal_geometry::skew;
use pingcal_geometry::Rigid3;

/// Options of [`relative_orientation`].
#[derive(Clone, Debug)]
pub struct RelativeOptions {
    /// Inlier threshold on the epipolar (angular) error, radians (pixels / focal length in
    /// pixels).
    pub threshold_rad: f64,
    /// RANSAC samples.
    pub samples: usize,
    /// Seed of the sampler.
    pub seed: u64,
    /// Fewest inliers accepted.
    pub min_inliers: usize,
    /// Largest radial distortion that the rays may carry unmodelled (nominal intrinsics
    /// without distortion), as a fraction of the radius of the pair's outermost ray: 0.25
    /// covers the −15 % barrel distortion of a wide-angle lens at the image corners. Used by
    /// [`relative_orientation_radial`]; 0 takes the rays as given.
    pub radial_bound: f64,
}

impl Default for RelativeOptions {
    fn default() -> Self {
        Self {
            threshold_rad: 2e-3,
            samples: 500,
            seed: 1,
            min_inliers: 12,
            radial_bound: 0.25,
        }
    }
}

/// A relative orientation.
#[derive(Clone, Debug)]
pub struct Relative {
    /// Camera 1's frame → camera 2's frame (|t| = 1).
    pub camera2_from_camera1: Rigid3,
    /// The essential matrix.
    pub essential: Matrix3<f64>,
    /// Per correspondence: consistent with the epipolar geometry and in front of both.
    pub inliers: Vec<bool>,
    /// Median intersection angle of the inliers, degrees (the strength of the baseline).
    pub median_angle_deg: f64,
    /// The pose came from a homography (a planar scene).
    pub planar: bool,
    /// The radial correction of the rays with which it was found, as a fraction of the radius
    /// at the outermost ray (0: the rays as given; see [`relative_orientation_radial`]).
    pub radial_correction: f64,
}

/// Why a relative orientation failed.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum RelativeError {
    /// Fewer than 8 correspondences.
    #[error("relative orientation needs at least 8 corresponding rays, got {got}")]
    TooFewPoints {
        /// Correspondences given (the shorter of the two ray lists).
        got: usize,
    },
    /// No consistent essential matrix.
    #[error("no essential matrix with at least {needed} inliers (best {best} of {count}); a flat scene or a pure rotation?")]
    NoConsensus {
        /// Fewest inliers accepted ([`RelativeOptions::min_inliers`], at least 8).
        needed: usize,
        /// Inliers of the best orientation found (0: no sample gave one).
        best: usize,
        /// Correspondences given.
        count: usize,
    },
}

fn plane(d: &Vector3<f64>) -> Option<Vector2<f64>> {
    (d.y > 1e-9).then(|| Vector2::new(d.x / d.y, d.z / d.y))
}

/// Plane coordinates of a ray set and their Hartley normalising transform, or `None` if a
/// ray does not point forward.
fn normalised_plane(d: &[Vector3<f64>]) -> Option<(Vec<Vector2<f64>>, Matrix3<f64>)> {
    let p: Vec<Vector2<f64>> = d.iter().map(plane).collect::<Option<_>>()?;
    let t = hartley_normaliser(&p);
    Some((p, t))
}

/// The essential matrix (singular values 1, 1, 0) from eight or more correspondences of
/// unit rays (camera frames), by the normalised 8-point algorithm.
pub fn essential_8point(d1: &[Vector3<f64>], d2: &[Vector3<f64>]) -> Option<Matrix3<f64>> {
    let n = d1.len().min(d2.len());
    if n < 8 {
        return None;
    }
    let (p1, t1) = normalised_plane(&d1[..n])?;
    let (p2, t2) = normalised_plane(&d2[..n])?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (a, b) in p1.iter().zip(&p2) {
        let h1 = t1 * Vector3::new(a.x, a.y, 1.0);
        let h2 = t2 * Vector3::new(b.x, b.y, 1.0);
        let mut row = SMatrix::<f64, 9, 1>::zeros();
        for i in 0..3 {
            for j in 0..3 {
                row[3 * i + j] = h2[i] * h1[j];
            }
        }
        ata += row * row.transpose();
    }
    let eig = ata.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    let v = eig.eigenvectors.column(k);
    let fhat = Matrix3::from_fn(|i, j| v[3 * i + j]);
    // Back to homogeneous plane coordinates h = (X/Y, Z/Y, 1) = P d / Y.
    let eh = t2.transpose() * fhat * t1;
    let perm = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0);
    let e = perm.transpose() * eh * perm;
    let svd = e.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let e = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0)) * vt;
    e.iter().all(|x| x.is_finite()).then_some(e)
}

/// The four (R, t) of an essential matrix.
pub fn decompose_essential(e: &Matrix3<f64>) -> Vec<Rigid3> {
    let svd = e.svd(true, true);
    let (Some(mut u), Some(mut vt)) = (svd.u, svd.v_t) else {
        return Vec::new();
    };
    if u.determinant() < 0.0 {
        u = -u;
    }
    if vt.determinant() < 0.0 {
        vt = -vt;
    }
    let w = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let t: Vector3<f64> = u.column(2).into_owned();
    let mut out = Vec::new();
    for r in [u * w * vt, u * w.transpose() * vt] {
        for s in [1.0, -1.0] {
            out.push(Rigid3 {
                rotation: r,
                translation: t * s,
            });
        }
    }
    out
}

/// Depths (λ₁, λ₂) along the two rays of the point closest to both, camera 2 at `pose`
/// relative to camera 1.
pub fn depths(pose: &Rigid3, d1: &Vector3<f64>, d2: &Vector3<f64>) -> Option<(f64, f64)> {
    // λ₁ R d₁ − λ₂ d₂ = −t, least squares.
    let a = pose.rotation * d1;
    let m = nalgebra::Matrix3x2::from_columns(&[a, -d2]);
    let ata = m.transpose() * m;
    let sol = ata.try_inverse()? * (m.transpose() * (-pose.translation));
    Some((sol[0], sol[1]))
}

fn epipolar_error(e: &Matrix3<f64>, d1: &Vector3<f64>, d2: &Vector3<f64>) -> f64 {
    let n1 = e * d1;
    let n2 = e.transpose() * d2;
    let den = (n1.norm_squared() + n2.norm_squared()).sqrt();
    if den > 0.0 {
        (d2.dot(&n1)).abs() / den * 2f64.sqrt()
    } else {
        f64::INFINITY
    }
}

fn best_decomposition(
    e: &Matrix3<f64>,
    d1: &[Vector3<f64>],
    d2: &[Vector3<f64>],
    use_k: &[bool],
) -> (Rigid3, usize) {
    let mut best = (Rigid3::identity(), 0usize);
    for pose in decompose_essential(e) {
        let count = (0..d1.len())
            .filter(|&k| {
                use_k[k] && depths(&pose, &d1[k], &d2[k]).is_some_and(|(a, b)| a > 0.0 && b > 0.0)
            })
            .count();
        if count > best.1 {
            best = (pose, count);
        }
    }
    best
}

/// The permutation between pingcal's camera frame (X right, Y forward, Z up) and the frame
/// (X, Z, Y) in which the plane coordinates (X/Y, Z/Y, 1) are homogeneous points.
fn perm() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0)
}

/// The homography `h₂ ~ H h₁` between the plane coordinates h = (X/Y, Z/Y, 1) of four or
/// more correspondences of unit rays (normalised DLT), or `None`.
pub fn homography_dlt(d1: &[Vector3<f64>], d2: &[Vector3<f64>]) -> Option<Matrix3<f64>> {
    let n = d1.len().min(d2.len());
    if n < 4 {
        return None;
    }
    let p1: Vec<Vector2<f64>> = d1[..n].iter().map(plane).collect::<Option<_>>()?;
    let p2: Vec<Vector2<f64>> = d2[..n].iter().map(plane).collect::<Option<_>>()?;
    pingcal_geometry::dlt::homography_dlt(&p1, &p2)
}

/// Transfer error of a homography for one correspondence (plane units ≈ radians).
fn homography_error(h: &Matrix3<f64>, d1: &Vector3<f64>, d2: &Vector3<f64>) -> f64 {
    let (Some(a), Some(b)) = (plane(d1), plane(d2)) else {
        return f64::INFINITY;
    };
    let q = h * Vector3::new(a.x, a.y, 1.0);
    if q.z.abs() < 1e-12 {
        return f64::INFINITY;
    }
    let e = Vector2::new(q.x / q.z, q.y / q.z) - b;
    let r = h.try_inverse().map(|hi| hi * Vector3::new(b.x, b.y, 1.0));
    let e2 = match r {
        Some(r) if r.z.abs() > 1e-12 => (Vector2::new(r.x / r.z, r.y / r.z) - a).norm(),
        _ => f64::INFINITY,
    };
    0.5 * (e.norm() + e2)
}

/// The candidate poses (camera 2 in camera 1's frame, |t| = 1, both signs of t) of a
/// homography between plane coordinates (Faugeras & Lustman's SVD decomposition).
pub fn decompose_homography(h: &Matrix3<f64>) -> Vec<Rigid3> {
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Vec::new();
    };
    // Sort the singular values (nalgebra does not promise an order).
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
    let u = Matrix3::from_columns(&order.map(|k| u.column(k).into_owned()));
    let vt = Matrix3::from_rows(&order.map(|k| vt.row(k).into_owned()));
    let w = order.map(|k| svd.singular_values[k]);
    let (d1, d2, d3) = (w[0], w[1], w[2]);
    if !(d3 > 0.0) || d1 / d2 < 1.00001 || d2 / d3 < 1.00001 {
        return Vec::new();
    }
    let s = u.determinant() * vt.determinant();
    let (q1, q2, q3) = (d1 * d1, d2 * d2, d3 * d3);
    let a1 = ((q1 - q2) / (q1 - q3)).sqrt();
    let a3 = ((q2 - q3) / (q1 - q3)).sqrt();
    let x1 = [a1, a1, -a1, -a1];
    let x3 = [a3, -a3, a3, -a3];
    let p = perm();
    let mut out = Vec::new();
    let mut push = |r: Matrix3<f64>, t: Vector3<f64>| {
        let tn = t.norm();
        if tn > 0.0 && r.iter().all(|v| v.is_finite()) {
            for sign in [1.0, -1.0] {
                out.push(Rigid3 {
                    rotation: p * r * p,
                    translation: p * (t * (sign / tn)),
                });
            }
        }
    };
    // d' = d2.
    let st = ((q1 - q2) * (q2 - q3)).sqrt() / ((d1 + d3) * d2);
    let ct = (q2 + d1 * d3) / ((d1 + d3) * d2);
    for (i, sg) in [1.0, -1.0, -1.0, 1.0].iter().enumerate() {
        let rp = Matrix3::new(ct, 0.0, -st * sg, 0.0, 1.0, 0.0, st * sg, 0.0, ct);
        let tp = Vector3::new(x1[i], 0.0, -x3[i]) * (d1 - d3);
        push(u * rp * vt * s, u * tp);
    }
    // d' = −d2.
    let sp = ((q1 - q2) * (q2 - q3)).sqrt() / ((d1 - d3) * d2);
    let cp = (d1 * d3 - q2) / ((d1 - d3) * d2);
    for (i, sg) in [1.0, -1.0, -1.0, 1.0].iter().enumerate() {
        let rp = Matrix3::new(cp, 0.0, sp * sg, 0.0, -1.0, 0.0, sp * sg, 0.0, -cp);
        let tp = Vector3::new(x1[i], 0.0, x3[i]) * (d1 + d3);
        push(u * rp * vt * s, u * tp);
    }
    out
}

/// Angular error of a correspondence under a pose: the rays' distance from the point
/// closest to both, as seen from each camera (radians, the larger of the two); infinite
/// behind a camera.
fn pose_error(pose: &Rigid3, d1: &Vector3<f64>, d2: &Vector3<f64>) -> f64 {
    match depths(pose, d1, d2) {
        Some((a, b)) if a > 0.0 && b > 0.0 => {
            let x1 = d1 * a;
            let x2 = pose.transform(&x1);
            let e2 = (x2.normalize() - d2).norm();
            // Camera 1 sees x1 exactly along d1; measure the miss at camera 2 and the
            // symmetric one through the other depth.
            let y2 = d2 * b;
            let y1 = pose.inverse().transform(&y2);
            e2.max((y1.normalize() - d1).norm())
        }
        _ => f64::INFINITY,
    }
}

/// A 3×3 matrix from corresponding rays (the 8-point E, the 4-point homography).
type RaySolver = fn(&[Vector3<f64>], &[Vector3<f64>]) -> Option<Matrix3<f64>>;

/// A 3×3 matrix model (essential matrix or homography) of corresponding ray pairs, for
/// [`consensus::find`]: a minimal solver (also the least-squares refit on more pairs) and
/// the error of one pair (radians).
struct RayPairs<'a> {
    d1: &'a [Vector3<f64>],
    d2: &'a [Vector3<f64>],
    size: usize,
    solve: RaySolver,
    error: fn(&Matrix3<f64>, &Vector3<f64>, &Vector3<f64>) -> f64,
}

impl RayPairs<'_> {
    fn solve_on(&self, pairs: &[usize]) -> Option<Matrix3<f64>> {
        let s1: Vec<_> = pairs.iter().map(|&k| self.d1[k]).collect();
        let s2: Vec<_> = pairs.iter().map(|&k| self.d2[k]).collect();
        (self.solve)(&s1, &s2)
    }
}

impl Estimator for RayPairs<'_> {
    type Model = Matrix3<f64>;
    fn len(&self) -> usize {
        self.d1.len()
    }
    fn sample_size(&self) -> usize {
        self.size
    }
    fn fit(&self, sample: &[usize], models: &mut Vec<Matrix3<f64>>) {
        models.extend(self.solve_on(sample));
    }
    fn residual(&self, m: &Matrix3<f64>, k: usize) -> f64 {
        (self.error)(m, &self.d1[k], &self.d2[k])
    }
    fn refit(&self, inliers: &[usize], _: &Matrix3<f64>) -> Option<Matrix3<f64>> {
        self.solve_on(inliers)
    }
}

/// MSAC over `options.samples` seeded minimal samples of `est`, the best model refitted on
/// its inliers `refits` times (a refit kept when it has at least as many inliers): the
/// model and its inlier flags.
fn ray_msac(
    est: &RayPairs,
    options: &RelativeOptions,
    seed: u64,
    refits: usize,
) -> Option<(Matrix3<f64>, Vec<bool>)> {
    let opts = ConsensusOptions {
        final_refits: refits,
        final_refit_rule: RefitRule::NotFewerInliers,
        ..ConsensusOptions::msac(options.threshold_rad, options.samples)
    };
    let found = consensus::find(est, &opts, &mut consensus::rng(seed))?;
    let mut inl = vec![false; est.len()];
    for k in found.inliers {
        inl[k] = true;
    }
    Some((found.model, inl))
}

fn homography_ransac(
    d1: &[Vector3<f64>],
    d2: &[Vector3<f64>],
    options: &RelativeOptions,
) -> Option<(Matrix3<f64>, Vec<bool>)> {
    let est = RayPairs {
        d1,
        d2,
        size: 4,
        solve: homography_dlt,
        error: homography_error,
    };
    ray_msac(&est, options, options.seed ^ 0x5eed, 1)
}

/// Relative orientation from corresponding unit rays `d1[k]` ↔ `d2[k]`.
pub fn relative_orientation(
    d1: &[Vector3<f64>],
    d2: &[Vector3<f64>],
    options: &RelativeOptions,
) -> Result<Relative, RelativeError> {
    let n = d1.len().min(d2.len());
    if n < 8 {
        return Err(RelativeError::TooFewPoints { got: n });
    }
    let needed = options.min_inliers.max(8);
    let t = options.threshold_rad;
    // MSAC, the best E refitted on its inliers (twice), then the decomposition with the most
    // points in front.
    let est = RayPairs {
        d1: &d1[..n],
        d2: &d2[..n],
        size: 8,
        solve: essential_8point,
        error: epipolar_error,
    };
    let Some((mut e, mut inl)) = ray_msac(&est, options, options.seed, 2) else {
        return Err(RelativeError::NoConsensus {
            needed,
            best: 0,
            count: n,
        });
    };
    let (mut pose, _) = best_decomposition(&e, &d1[..n], &d2[..n], &inl);
    let mut planar = false;
    let n_e = inl.iter().filter(|v| **v).count();
    if let Some((h, h_inl)) = homography_ransac(&d1[..n], &d2[..n], options) {
        let n_h = h_inl.iter().filter(|v| **v).count();
        if n_h >= 8 && 5 * n_h >= 4 * n_e {
            // A planar scene (or too little parallax for E): the homography decides.
            let mut best_h: Option<(usize, f64, Rigid3)> = None;
            for cand in decompose_homography(&h) {
                let (mut count, mut err) = (0usize, 0.0);
                for k in 0..n {
                    if h_inl[k] {
                        let e = pose_error(&cand, &d1[k], &d2[k]);
                        if e < 2.0 * t {
                            count += 1;
                            err += e;
                        }
                    }
                }
                let better = best_h
                    .as_ref()
                    .is_none_or(|b| count > b.0 || (count == b.0 && err < b.1));
                if better {
                    best_h = Some((count, err, cand));
                }
            }
            if let Some((count, _, cand)) = best_h {
                if count >= 8 {
                    pose = cand;
                    e = essential_from_pose(&cand);
                    inl = (0..n)
                        .map(|k| h_inl[k] && pose_error(&cand, &d1[k], &d2[k]) < 2.0 * t)
                        .collect();
                    planar = true;
                }
            }
        }
    }
    let mut angles = Vec::new();
    for k in 0..n {
        if inl[k] {
            match depths(&pose, &d1[k], &d2[k]) {
                Some((a, b)) if a > 0.0 && b > 0.0 => {
                    // Angle between the two rays at the point, in camera 1's frame.
                    let r2 = pose.rotation.transpose() * d2[k];
                    angles.push(d1[k].dot(&r2).clamp(-1.0, 1.0).acos().to_degrees());
                }
                _ => inl[k] = false,
            }
        }
    }
    let count = angles.len();
    if count < needed {
        return Err(RelativeError::NoConsensus {
            needed,
            best: count,
            count: n,
        });
    }
    angles.sort_by(f64::total_cmp);
    Ok(Relative {
        camera2_from_camera1: pose,
        essential: e,
        inliers: inl,
        median_angle_deg: angles[count / 2],
        planar,
        radial_correction: 0.0,
    })
}

/// Ray `d` (camera frame, Y forward) with its tangent-plane radius ρ scaled by `1 + κ ρ²`
/// (rays at or behind 90° are left as they are).
fn radially_corrected(d: &Vector3<f64>, kappa: f64) -> Vector3<f64> {
    if d.y <= 0.0 {
        return *d;
    }
    let s = 1.0 + kappa * (d.x * d.x + d.z * d.z) / (d.y * d.y);
    Vector3::new(d.x * s, d.y, d.z * s).normalize()
}

/// How well a relative orientation explains its rays: inliers, then the smaller sum of their
/// epipolar errors.
fn support(r: &Relative, d1: &[Vector3<f64>], d2: &[Vector3<f64>]) -> (usize, f64) {
    let err = (0..r.inliers.len())
        .filter(|&k| r.inliers[k])
        .map(|k| epipolar_error(&r.essential, &d1[k], &d2[k]))
        .sum();
    (r.inliers.iter().filter(|v| **v).count(), err)
}

/// [`relative_orientation`] of rays that may carry a radial distortion the nominal intrinsics
/// do not model, up to `options.radial_bound` of the radius at the outermost ray: a radial
/// correction `ρ' = ρ (1 + κ ρ²)` of both images' rays is estimated with the orientation (a
/// grid of 5 % steps within the bound, then three halvings around the best) and the one that
/// most rays agree with wins; the rays as given win ties, and are kept without a search
/// when every ray agrees with them. Near the image corners such a lens
/// moves points by tens of pixels, far beyond the epipolar threshold, so that with few common
/// points too few would remain consistent with the uncorrected rays. The error, when no
/// correction gives an orientation, is that of the rays with the most support.
pub fn relative_orientation_radial(
    d1: &[Vector3<f64>],
    d2: &[Vector3<f64>],
    options: &RelativeOptions,
) -> Result<Relative, RelativeError> {
    let rho2 = d1
        .iter()
        .chain(d2)
        .filter(|d| d.y > 0.0)
        .map(|d| (d.x * d.x + d.z * d.z) / (d.y * d.y))
        .fold(0.0, f64::max);
    let plain = relative_orientation(d1, d2, options);
    let bound = options.radial_bound.abs();
    let all_agree = plain.as_ref().is_ok_and(|r| r.inliers.iter().all(|v| *v));
    if all_agree || !(bound > 0.0 && rho2 > 0.0) {
        return plain;
    }
    let mut best: Option<((usize, f64), Relative)> = None;
    let mut best_error = plain.as_ref().err().cloned();
    let mut consider = |fraction: f64, best: &mut Option<((usize, f64), Relative)>| {
        let kappa = fraction / rho2;
        let c1: Vec<_> = d1.iter().map(|d| radially_corrected(d, kappa)).collect();
        let c2: Vec<_> = d2.iter().map(|d| radially_corrected(d, kappa)).collect();
        match relative_orientation(&c1, &c2, options) {
            Ok(mut r) => {
                let s = support(&r, &c1, &c2);
                if best
                    .as_ref()
                    .is_none_or(|(b, _)| s.0 > b.0 || (s.0 == b.0 && s.1 < b.1))
                {
                    r.radial_correction = fraction;
                    *best = Some((s, r));
                }
            }
            Err(e) => {
                if let (
                    Some(RelativeError::NoConsensus { best: w, .. }),
                    RelativeError::NoConsensus { best: b, .. },
                ) = (&best_error, &e)
                {
                    if b > w {
                        best_error = Some(e);
                    }
                }
            }
        }
    };
    if let Ok(r) = &plain {
        best = Some((support(r, d1, d2), r.clone()));
    }
    let step = 0.05;
    let n = (bound / step).round().max(1.0) as i32;
    for j in (-n..=n).filter(|&j| j != 0) {
        consider(bound * f64::from(j) / f64::from(n), &mut best);
    }
    let mut h = bound / f64::from(n) / 2.0;
    for _ in 0..3 {
        let Some(centre) = best.as_ref().map(|(_, r)| r.radial_correction) else {
            break;
        };
        for f in [centre - h, centre + h] {
            if f != 0.0 && f.abs() <= bound {
                consider(f, &mut best);
            }
        }
        h /= 2.0;
    }
    match best {
        Some((_, r)) => Ok(r),
        None => Err(best_error.unwrap_or(RelativeError::NoConsensus {
            needed: options.min_inliers.max(8),
            best: 0,
            count: d1.len().min(d2.len()),
        })),
    }
}

/// `[t]× R` (for tests and callers that build E from a pose).
pub fn essential_from_pose(pose: &Rigid3) -> Matrix3<f64> {
    skew(&pose.translation) * pose.rotation
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_geometry::from_opk;
    use rand::Rng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn recovers_relative_pose_from_noisy_rays_with_outliers() {
        let mut rng = pingcal_geometry::consensus::rng(4);
        let truth = Rigid3 {
            rotation: from_opk(0.1, -0.3, 0.2),
            translation: Vector3::new(-1.0, 0.1, 0.2).normalize(),
        };
        let noise = Normal::new(0.0, 2e-4).unwrap();
        let (mut d1, mut d2) = (Vec::new(), Vec::new());
        while d1.len() < 100 {
            // A 3D scene 3–6 units ahead of camera 1.
            let x = Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(3.0..6.0),
                rng.random_range(-1.5..1.5),
            );
            let x2 = truth.transform(&x);
            if x2.y < 0.5 {
                continue;
            }
            let mut n = || Vector3::new(noise.sample(&mut rng), 0.0, noise.sample(&mut rng));
            d1.push((x / x.y + n()).normalize());
            d2.push((x2 / x2.y + n()).normalize());
        }
        for k in (0..100).step_by(9) {
            d2[k] = (d2[k] + Vector3::new(0.05, 0.0, -0.04)).normalize();
        }
        let r = relative_orientation(&d1, &d2, &RelativeOptions::default()).unwrap();
        assert!(
            (r.camera2_from_camera1.rotation - truth.rotation).norm() < 2e-3,
            "{:?}",
            r.camera2_from_camera1.rotation
        );
        assert!(
            (r.camera2_from_camera1.translation - truth.translation).norm() < 1e-2,
            "{:?}",
            r.camera2_from_camera1.translation
        );
        for k in (0..100).step_by(9) {
            assert!(!r.inliers[k]);
        }
        assert!(r.inliers.iter().filter(|v| **v).count() > 80);
        assert!(r.median_angle_deg > 5.0);
        assert!(!r.planar);
        // The exact E of the truth satisfies the constraint on noise-free rays.
        let e = essential_from_pose(&truth);
        let x = Vector3::new(0.3, 4.0, 0.2);
        assert!(
            truth
                .transform(&x)
                .normalize()
                .dot(&(e * x.normalize()))
                .abs()
                < 1e-12
        );
    }

    #[test]
    fn a_flat_scene_goes_through_the_homography() {
        let mut rng = pingcal_geometry::consensus::rng(8);
        // Camera 1 looks at a plane 4 units ahead, tilted; camera 2 moved sideways and turned.
        let truth = Rigid3 {
            rotation: from_opk(0.15, 0.05, 0.3),
            translation: Vector3::new(-1.0, 0.2, 0.1).normalize(),
        };
        let normal = Vector3::new(0.2, -1.0, 0.3).normalize();
        let noise = Normal::new(0.0, 2e-4).unwrap();
        let (mut d1, mut d2) = (Vec::new(), Vec::new());
        while d1.len() < 80 {
            // A point of the plane n·x = −4·n_y (through (0, 4, 0)).
            let (a, b) = (rng.random_range(-2.0..2.0), rng.random_range(-1.5..1.5));
            let x0 = Vector3::new(a, 4.0, b);
            let x = x0 - normal * (normal.dot(&x0) - normal.dot(&Vector3::new(0.0, 4.0, 0.0)));
            let x2 = truth.transform(&x);
            if x2.y < 0.5 || x.y < 0.5 {
                continue;
            }
            let mut n = || Vector3::new(noise.sample(&mut rng), 0.0, noise.sample(&mut rng));
            d1.push((x / x.y + n()).normalize());
            d2.push((x2 / x2.y + n()).normalize());
        }
        let r = relative_orientation(&d1, &d2, &RelativeOptions::default()).unwrap();
        assert!(r.planar);
        assert!(
            (r.camera2_from_camera1.rotation - truth.rotation).norm() < 5e-3,
            "{:?}",
            r.camera2_from_camera1.rotation
        );
        assert!(
            (r.camera2_from_camera1.translation - truth.translation).norm() < 2e-2,
            "{:?}",
            r.camera2_from_camera1.translation
        );
        assert!(r.inliers.iter().filter(|v| **v).count() > 70);
    }

    #[test]
    fn homography_decomposition_contains_the_truth() {
        let truth = Rigid3 {
            rotation: from_opk(-0.2, 0.1, 0.4),
            translation: Vector3::new(0.3, -0.5, 0.8).normalize(),
        };
        // Plane n·x = d in camera 1 (pingcal frame); H in plane coordinates.
        let n = Vector3::new(0.1, 1.0, -0.2).normalize();
        let d = 3.0;
        let p = perm();
        let h = p * (truth.rotation + truth.translation * n.transpose() / d) * p;
        let best = decompose_homography(&h)
            .iter()
            .map(|c| {
                (c.rotation - truth.rotation).norm() + (c.translation - truth.translation).norm()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(best < 1e-9, "{best}");
    }

    #[test]
    fn too_few_points() {
        let d = vec![Vector3::y(); 5];
        assert_eq!(
            relative_orientation(&d, &d, &RelativeOptions::default()).unwrap_err(),
            RelativeError::TooFewPoints { got: 5 }
        );
    }
}
