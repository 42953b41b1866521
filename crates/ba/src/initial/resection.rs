//! Space resection: the pose of one image from points of known (approximate) object
//! coordinates.
//!
//! Closed form: Grunert's P3P (as reviewed by Haralick et al., IJCV 1994) on the unit rays
//! of three points, the quartic solved through the eigenvalues of its companion matrix,
//! the pose from the three camera-frame points by an absolute orientation (SVD). It works
//! for planar and non-planar point sets alike (a DLT would not for a flat test field).
//! RANSAC (MSAC scoring of the reprojection errors in pixels; every triple when there are
//! few points, otherwise seeded random triples) picks the best pose, which is then refined
//! by Levenberg–Marquardt on the reprojection errors of its inliers.
//!
//! Rays come from [`CameraModel::unproject`]: in the camera frame of docs/formats.md (X right,
//! Y forward, Z up); nothing here depends on which axis is the optical axis, except the
//! requirement that points be in front of the camera (the model's `project` says so).

use crate::camera::CameraModel;
use nalgebra::{DMatrix, Matrix6, Vector2, Vector3, Vector6};
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator, Sampling};
use pingcal_geometry::skew;
use pingcal_geometry::Plane;
use pingcal_geometry::Rigid3;

/// Options of [`resect`].
#[derive(Clone, Debug)]
pub struct ResectionOptions {
    /// Inlier threshold on the reprojection error, pixels.
    pub threshold_px: f64,
    /// Most RANSAC samples (when there are too many triples to try them all).
    pub max_samples: usize,
    /// Seed of the sampler (results are reproducible).
    pub seed: u64,
    /// Fewest inliers accepted (at least 4: three define the pose, one checks it).
    pub min_inliers: usize,
}

impl Default for ResectionOptions {
    fn default() -> Self {
        Self {
            threshold_px: 10.0,
            max_samples: 500,
            seed: 1,
            min_inliers: 4,
        }
    }
}

/// A resected pose.
#[derive(Clone, Debug)]
pub struct Resection {
    /// The pose: object → camera.
    pub camera_from_object: Rigid3,
    /// Per input point: reprojection error under the threshold at the refined pose.
    pub inliers: Vec<bool>,
    /// RMS reprojection error of the inliers, pixels (per coordinate).
    pub rms_px: f64,
}

/// Why a resection failed.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum ResectionError {
    /// Fewer than 4 usable points.
    #[error("resection needs at least 4 points of known coordinates, got {got}")]
    TooFewPoints {
        /// Points whose pixel back-projects and whose coordinates are finite.
        got: usize,
    },
    /// The object points are (nearly) on one line: the pose is not determined.
    #[error("the {count} object points are nearly collinear: the pose is not determined")]
    Collinear {
        /// Usable points (pixel back-projects, coordinates finite).
        count: usize,
    },
    /// No sample gave a pose with enough inliers.
    #[error("no pose found with at least {needed} inliers (best: {best} of {count} points within {threshold_px} px)")]
    NoConsensus {
        /// Fewest inliers accepted ([`ResectionOptions::min_inliers`], at least 4).
        needed: usize,
        /// Inliers of the best pose found (0: no sample gave a pose).
        best: usize,
        /// Usable points (pixel back-projects, coordinates finite).
        count: usize,
        /// The inlier threshold on the reprojection error, pixels.
        threshold_px: f64,
    },
}

/// Real roots of the polynomial `c[0] xⁿ + c[1] xⁿ⁻¹ + … + c[n]` (eigenvalues of the
/// companion matrix, polished by Newton's method).
pub fn real_roots(c: &[f64]) -> Vec<f64> {
    let scale = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return Vec::new();
    }
    let mut k = 0;
    while k < c.len() && c[k].abs() <= 1e-12 * scale {
        k += 1;
    }
    let c = &c[k..];
    let n = c.len().saturating_sub(1);
    if n == 0 {
        return Vec::new();
    }
    let mut m = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        m[(0, j)] = -c[j + 1] / c[0];
    }
    for i in 1..n {
        m[(i, i - 1)] = 1.0;
    }
    let eval = |x: f64| c.iter().fold(0.0, |acc, v| acc * x + v);
    let deriv = |x: f64| {
        c[..n]
            .iter()
            .enumerate()
            .fold(0.0, |acc, (i, v)| acc * x + v * (n - i) as f64)
    };
    let mut out = Vec::new();
    for z in m.complex_eigenvalues().iter() {
        if !(z.re.is_finite() && z.im.is_finite()) {
            continue;
        }
        if z.im.abs() > 1e-6 * (1.0 + z.re.abs()) {
            continue;
        }
        let mut x = z.re;
        for _ in 0..5 {
            let d = deriv(x);
            if d == 0.0 {
                break;
            }
            let step = eval(x) / d;
            if !step.is_finite() {
                break;
            }
            x -= step;
        }
        out.push(x);
    }
    out
}

/// The rigid transform (R, t) with `to ≈ R·from + t` (least squares, SVD), or `None` for
/// fewer than 3 points or a degenerate configuration.
pub fn rigid_transform(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Option<Rigid3> {
    similarity_transform(from, to, false).map(|(p, _)| p)
}

/// The similarity `to ≈ s·R·from + t` ([`pingcal_geometry::umeyama()`]); with
/// `with_scale == false`, s = 1. Returns the pose (R, t) and s, or `None` where Umeyama
/// gives an error (fewer than 3 points, coincident points for a scale, non-finite data).
pub fn similarity_transform(
    from: &[Vector3<f64>],
    to: &[Vector3<f64>],
    with_scale: bool,
) -> Option<(Rigid3, f64)> {
    let s = pingcal_geometry::umeyama(from, to, None, with_scale).ok()?;
    let pose = Rigid3 {
        rotation: s.rotation,
        translation: s.translation,
    };
    Some((pose, s.scale))
}

/// Grunert's P3P: the poses (up to four) that put the object points `x` on the unit rays
/// `j` (camera frame). Candidates are checked against the three distance equations.
pub fn p3p(j: &[Vector3<f64>; 3], x: &[Vector3<f64>; 3]) -> Vec<Rigid3> {
    let a2 = (x[1] - x[2]).norm_squared();
    let b2 = (x[0] - x[2]).norm_squared();
    let c2 = (x[0] - x[1]).norm_squared();
    if a2 == 0.0 || b2 == 0.0 || c2 == 0.0 {
        return Vec::new();
    }
    let ca = j[1].dot(&j[2]);
    let cb = j[0].dot(&j[2]);
    let cg = j[0].dot(&j[1]);
    let amc = (a2 - c2) / b2;
    let apc = (a2 + c2) / b2;
    let a4 = (amc - 1.0).powi(2) - 4.0 * c2 / b2 * ca * ca;
    let a3 = 4.0 * (amc * (1.0 - amc) * cb - (1.0 - apc) * ca * cg + 2.0 * c2 / b2 * ca * ca * cb);
    let a2c = 2.0
        * (amc * amc - 1.0 + 2.0 * amc * amc * cb * cb + 2.0 * (b2 - c2) / b2 * ca * ca
            - 4.0 * apc * ca * cb * cg
            + 2.0 * (b2 - a2) / b2 * cg * cg);
    let a1 = 4.0 * (-amc * (1.0 + amc) * cb + 2.0 * a2 / b2 * cg * cg * cb - (1.0 - apc) * ca * cg);
    let a0 = (1.0 + amc).powi(2) - 4.0 * a2 / b2 * cg * cg;
    let mut out = Vec::new();
    for v in real_roots(&[a4, a3, a2c, a1, a0]) {
        let den = 2.0 * (cg - v * ca);
        if den.abs() < 1e-14 {
            continue;
        }
        let u = ((-1.0 + amc) * v * v - 2.0 * amc * cb * v + 1.0 + amc) / den;
        let q = 1.0 + v * v - 2.0 * v * cb;
        if !(q > 0.0) || u <= 0.0 || v <= 0.0 {
            continue;
        }
        let s1 = (b2 / q).sqrt();
        let (s2, s3) = (u * s1, v * s1);
        let p = [j[0] * s1, j[1] * s2, j[2] * s3];
        // Check the three side lengths (rejects spurious roots).
        let ok = [(1, 2, a2), (0, 2, b2), (0, 1, c2)]
            .iter()
            .all(|&(m, n, d2)| ((p[m] - p[n]).norm_squared() - d2).abs() < 1e-6 * d2);
        if !ok {
            continue;
        }
        if let Some(pose) = rigid_transform(x, &p) {
            out.push(pose);
        }
    }
    out
}

fn reprojection(
    model: &dyn CameraModel,
    params: &[f64],
    pose: &Rigid3,
    x: &Vector3<f64>,
    uv: &Vector2<f64>,
) -> Option<Vector2<f64>> {
    model
        .project(params, &pose.transform(x), None, None)
        .map(|p| p - uv)
}

/// Residuals (pixels) and their 2×6 Jacobians with respect to the pose update of
/// [`Rigid3::plus`] (δω then δt): `∂xc/∂δω = −[R X]×`, `∂xc/∂δt = I`.
pub fn pose_residual_jacobian(
    model: &dyn CameraModel,
    params: &[f64],
    pose: &Rigid3,
    x: &Vector3<f64>,
    uv: &Vector2<f64>,
) -> Option<(Vector2<f64>, nalgebra::Matrix2x6<f64>)> {
    let rx = pose.rotation * x;
    let xc = rx + pose.translation;
    let mut jp = nalgebra::Matrix2x3::zeros();
    let p = model.project(params, &xc, Some(&mut jp), None)?;
    let jw = jp * (-skew(&rx));
    let mut j = nalgebra::Matrix2x6::zeros();
    j.fixed_view_mut::<2, 3>(0, 0).copy_from(&jw);
    j.fixed_view_mut::<2, 3>(0, 3).copy_from(&jp);
    Some((p - uv, j))
}

/// Levenberg–Marquardt refinement of a pose on the reprojection errors of the points
/// with `use_point[k]`. Returns the refined pose (the input pose if nothing improves).
pub fn refine_pose(
    model: &dyn CameraModel,
    params: &[f64],
    uv: &[Vector2<f64>],
    x: &[Vector3<f64>],
    use_point: &[bool],
    pose: &Rigid3,
) -> Rigid3 {
    let cost = |p: &Rigid3| -> Option<f64> {
        let mut s = 0.0;
        for k in 0..uv.len() {
            if use_point[k] {
                s += reprojection(model, params, p, &x[k], &uv[k])?.norm_squared();
            }
        }
        Some(s)
    };
    let mut pose = *pose;
    let Some(mut c) = cost(&pose) else {
        return pose;
    };
    let mut lambda = 1e-3;
    for _ in 0..50 {
        let mut h = Matrix6::zeros();
        let mut g = Vector6::zeros();
        for k in 0..uv.len() {
            if !use_point[k] {
                continue;
            }
            if let Some((r, j)) = pose_residual_jacobian(model, params, &pose, &x[k], &uv[k]) {
                h += j.transpose() * j;
                g += j.transpose() * r;
            }
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut hd = h;
            for i in 0..6 {
                hd[(i, i)] *= 1.0 + lambda;
                hd[(i, i)] += 1e-12;
            }
            let Some(step) = hd.cholesky().map(|ch| ch.solve(&(-g))) else {
                lambda *= 10.0;
                continue;
            };
            let trial = pose.plus(step.as_slice());
            match cost(&trial) {
                Some(ct) if ct < c => {
                    let rel = (c - ct) / c.max(1e-300);
                    pose = trial;
                    c = ct;
                    lambda = (lambda * 0.3).max(1e-12);
                    improved = rel > 1e-12;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    pose
}

/// The P3P poses of triples of (ray, object point) pairs, for [`consensus::find`]; the
/// residual is the reprojection error in pixels.
struct P3pSamples<'a> {
    model: &'a dyn CameraModel,
    params: &'a [f64],
    uv: Vec<Vector2<f64>>,
    pts: &'a [Vector3<f64>],
    rays: &'a [Vector3<f64>],
}

impl Estimator for P3pSamples<'_> {
    type Model = Rigid3;
    fn len(&self) -> usize {
        self.pts.len()
    }
    fn sample_size(&self) -> usize {
        3
    }
    fn fit(&self, t: &[usize], poses: &mut Vec<Rigid3>) {
        let xs = [self.pts[t[0]], self.pts[t[1]], self.pts[t[2]]];
        // Skip thin triangles: the P3P is ill-conditioned on them.
        let area = (xs[1] - xs[0]).cross(&(xs[2] - xs[0])).norm();
        let side = (xs[1] - xs[0])
            .norm_squared()
            .max((xs[2] - xs[0]).norm_squared())
            .max((xs[2] - xs[1]).norm_squared());
        if area < 1e-3 * side {
            return;
        }
        poses.extend(p3p(
            &[self.rays[t[0]], self.rays[t[1]], self.rays[t[2]]],
            &xs,
        ));
    }
    fn residual(&self, pose: &Rigid3, k: usize) -> f64 {
        self.residual_squared(pose, k).sqrt()
    }
    fn residual_squared(&self, pose: &Rigid3, k: usize) -> f64 {
        reprojection(self.model, self.params, pose, &self.pts[k], &self.uv[k])
            .map_or(f64::INFINITY, |r| r.norm_squared())
    }
}

/// Whether the points are (nearly) on one line: the second spread of their scatter (the
/// eigenvalues of [`Plane::fit`]) is tiny against the first.
fn collinear(x: &[Vector3<f64>]) -> bool {
    Plane::fit(x).is_none_or(|p| {
        let [_, second, first] = p.eigenvalues;
        !(first > 0.0) || second < 1e-8 * first
    })
}

/// Resects one image from the pixel measurements `uv` of the object points `x` (same
/// order), with the camera model and approximate intrinsics `params`.
pub fn resect(
    model: &dyn CameraModel,
    params: &[f64],
    uv: &[Vector2<f64>],
    x: &[Vector3<f64>],
    options: &ResectionOptions,
) -> Result<Resection, ResectionError> {
    let n = uv.len().min(x.len());
    // Rays of the points whose pixel can be back-projected.
    let mut idx = Vec::new();
    let mut rays = Vec::new();
    for k in 0..n {
        if let Some(r) = model.unproject(params, &uv[k]) {
            if x[k].iter().all(|v| v.is_finite()) {
                idx.push(k);
                rays.push(r);
            }
        }
    }
    let m = idx.len();
    let needed = options.min_inliers.max(4);
    if m < 4 {
        return Err(ResectionError::TooFewPoints { got: m });
    }
    let pts: Vec<Vector3<f64>> = idx.iter().map(|&k| x[k]).collect();
    if collinear(&pts) {
        return Err(ResectionError::Collinear { count: m });
    }
    let t2 = options.threshold_px * options.threshold_px;
    // MSAC on the reprojection errors: every triple when there are at most `max_samples`,
    // otherwise seeded random triples.
    let est = P3pSamples {
        model,
        params,
        uv: idx.iter().map(|&k| uv[k]).collect(),
        pts: &pts,
        rays: &rays,
    };
    let opts = ConsensusOptions {
        sampling: Sampling::RejectRepeats,
        exhaustive: true,
        ..ConsensusOptions::msac(options.threshold_px, options.max_samples)
    };
    let Some(pose) =
        consensus::find(&est, &opts, &mut consensus::rng(options.seed)).map(|c| c.model)
    else {
        return Err(ResectionError::NoConsensus {
            needed,
            best: 0,
            count: m,
            threshold_px: options.threshold_px,
        });
    };
    // Refine on the inliers, re-select, refine again.
    let mut usable = vec![false; n];
    for &k in &idx {
        usable[k] = true;
    }
    let mut pose = pose;
    let mut inliers = vec![false; n];
    for _ in 0..2 {
        for (k, flag) in inliers.iter_mut().enumerate() {
            *flag = usable[k]
                && reprojection(model, params, &pose, &x[k], &uv[k])
                    .is_some_and(|r| r.norm_squared() < t2);
        }
        if inliers.iter().filter(|v| **v).count() < needed {
            break;
        }
        pose = refine_pose(model, params, uv, x, &inliers, &pose);
    }
    for (k, flag) in inliers.iter_mut().enumerate() {
        *flag = usable[k]
            && reprojection(model, params, &pose, &x[k], &uv[k])
                .is_some_and(|r| r.norm_squared() < t2);
    }
    let count = inliers.iter().filter(|v| **v).count();
    if count < needed {
        return Err(ResectionError::NoConsensus {
            needed,
            best: count,
            count: m,
            threshold_px: options.threshold_px,
        });
    }
    let mut s = 0.0;
    for k in 0..n {
        if inliers[k] {
            s +=
                reprojection(model, params, &pose, &x[k], &uv[k]).map_or(0.0, |r| r.norm_squared());
        }
    }
    Ok(Resection {
        camera_from_object: pose,
        inliers,
        rms_px: (s / (2 * count) as f64).sqrt(),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::camera::PhotogrammetricCamera;
    use nalgebra::Matrix3;
    use pingcal_geometry::{exp_so3, from_opk};
    use rand::Rng;
    use rand_distr::{Distribution, Normal};

    pub fn camera() -> (PhotogrammetricCamera, Vec<f64>) {
        let cam = PhotogrammetricCamera::new(2272, 1704, 0.0031911);
        let mut p = vec![0.0; 10];
        p[0] = 7.46;
        p[1] = -0.01;
        p[2] = 0.1;
        p[3] = -4e-3;
        (cam, p)
    }

    /// A camera at `centre` looking at `target` (Y forward, Z roughly up).
    pub fn look_at(centre: Vector3<f64>, target: Vector3<f64>, roll: f64) -> Rigid3 {
        let y = (target - centre).normalize();
        let up = if y.z.abs() > 0.9 {
            Vector3::x()
        } else {
            Vector3::z()
        };
        let x = y.cross(&up).normalize();
        let z = x.cross(&y);
        let r = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
        Rigid3::from_rotation_and_centre(exp_so3(&Vector3::new(0.0, roll, 0.0)) * r, centre)
    }

    #[test]
    fn real_roots_of_a_quartic() {
        // (x−1)(x+2)(x−3)(x²+1) has real roots 1, −2, 3.
        let mut r = real_roots(&[1.0, -2.0, -4.0, 4.0, -5.0, 6.0]);
        r.sort_by(f64::total_cmp);
        assert_eq!(r.len(), 3);
        for (a, b) in r.iter().zip([-2.0, 1.0, 3.0]) {
            assert!((a - b).abs() < 1e-10, "{r:?}");
        }
    }

    #[test]
    fn p3p_recovers_the_true_pose_among_its_candidates() {
        let mut rng = pingcal_geometry::consensus::rng(5);
        for _ in 0..200 {
            let pose = Rigid3::from_rotation_and_centre(
                from_opk(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-3.0..3.0),
                ),
                Vector3::new(
                    rng.random_range(-5.0..5.0),
                    rng.random_range(-5.0..5.0),
                    rng.random_range(-5.0..5.0),
                ),
            );
            let inv = pose.inverse();
            let x: [Vector3<f64>; 3] = std::array::from_fn(|_| {
                let xc = Vector3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(2.0..6.0),
                    rng.random_range(-2.0..2.0),
                );
                inv.transform(&xc)
            });
            let j = x.map(|p| pose.transform(&p).normalize());
            let cands = p3p(&j, &x);
            let best = cands
                .iter()
                .map(|c| {
                    (c.rotation - pose.rotation).norm() + (c.translation - pose.translation).norm()
                })
                .fold(f64::INFINITY, f64::min);
            assert!(best < 1e-6, "{} candidates, best error {best}", cands.len());
        }
    }

    #[test]
    fn pose_jacobian_matches_central_differences() {
        let (cam, p) = camera();
        let pose = look_at(
            Vector3::new(0.3, -1.5, 1.2),
            Vector3::new(0.5, 0.5, 0.0),
            0.3,
        );
        let x = Vector3::new(0.2, 0.7, 0.05);
        let uv = Vector2::new(1000.0, 800.0);
        let (r0, j) = pose_residual_jacobian(&cam, &p, &pose, &x, &uv).unwrap();
        for k in 0..6 {
            let h = 1e-6;
            let mut d = [0.0; 6];
            d[k] = h;
            let rp = reprojection(&cam, &p, &pose.plus(&d), &x, &uv).unwrap();
            d[k] = -h;
            let rm = reprojection(&cam, &p, &pose.plus(&d), &x, &uv).unwrap();
            let fd = (rp - rm) / (2.0 * h);
            let an = j.column(k);
            assert!(
                (fd - an).norm() < 1e-5 * an.norm().max(1.0),
                "column {k}: fd {fd:?} analytic {an:?}"
            );
        }
        assert!(r0.iter().all(|v| v.is_finite()));
    }

    /// A flat 1 × 1 sheet of 10 × 10 points seen from `centre`.
    fn sheet() -> Vec<Vector3<f64>> {
        (0..100)
            .map(|k| Vector3::new((k % 10) as f64 / 9.0, (k / 10) as f64 / 9.0, 0.0))
            .collect()
    }

    #[test]
    fn resection_of_a_flat_sheet_with_noise_and_outliers() {
        let (cam, p) = camera();
        let truth = look_at(
            Vector3::new(0.4, -0.8, 1.5),
            Vector3::new(0.5, 0.5, 0.0),
            0.7,
        );
        let x = sheet();
        let noise = Normal::new(0.0, 0.2).unwrap();
        let mut rng = pingcal_geometry::consensus::rng(3);
        let mut uv: Vec<Vector2<f64>> = x
            .iter()
            .map(|x| {
                cam.project(&p, &truth.transform(x), None, None).unwrap()
                    + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng))
            })
            .collect();
        for k in (0..100).step_by(7) {
            uv[k] += Vector2::new(60.0, -45.0);
        }
        let res = resect(&cam, &p, &uv, &x, &ResectionOptions::default()).unwrap();
        let outliers: Vec<usize> = (0..100).filter(|k| !res.inliers[*k]).collect();
        assert_eq!(outliers, (0..100).step_by(7).collect::<Vec<_>>());
        assert!(res.rms_px < 0.3, "{}", res.rms_px);
        assert!((res.camera_from_object.centre() - truth.centre()).norm() < 2e-3);
        assert!((res.camera_from_object.rotation - truth.rotation).norm() < 1e-3);
    }

    #[test]
    fn degenerate_inputs_are_diagnosed() {
        let (cam, p) = camera();
        let truth = look_at(
            Vector3::new(0.4, -0.8, 1.5),
            Vector3::new(0.5, 0.5, 0.0),
            0.0,
        );
        let line: Vec<Vector3<f64>> = (0..6)
            .map(|k| Vector3::new(k as f64 * 0.1, 0.5, 0.0))
            .collect();
        let uv: Vec<Vector2<f64>> = line
            .iter()
            .map(|x| cam.project(&p, &truth.transform(x), None, None).unwrap())
            .collect();
        assert_eq!(
            resect(&cam, &p, &uv, &line, &ResectionOptions::default()).unwrap_err(),
            ResectionError::Collinear { count: 6 }
        );
        assert_eq!(
            resect(&cam, &p, &uv[..3], &line[..3], &ResectionOptions::default()).unwrap_err(),
            ResectionError::TooFewPoints { got: 3 }
        );
    }
}
