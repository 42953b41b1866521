//! OpenCV's stereo geometry from a calibrated pair, computed as OpenCV computes it, so that
//! `opencv/stereo.yaml` holds what `cv2.stereoRectify` and `cv2.stereoCalibrate` would give
//! for the same cameras: E, F, and the rectification R1, R2, P1, P2, Q of Bouguet's method
//! with `CALIB_ZERO_DISPARITY` and `alpha = -1` (no rescaling), the defaults.
//!
//! The steps (OpenCV's `stereoRectify`): the rotation is split in two halves, `r_r =
//! exp(−½ log R)`; a rotation `wR` turns the half-rotated baseline `r_r T` onto the x axis
//! (or y, for a vertical pair); `R1 = wR r_rᵀ`, `R2 = wR r_r`. The new focal length is the
//! mean of the two cameras' focal lengths across the baseline; each new principal point
//! centres the four undistorted image corners (undistorted by OpenCV's five fixed-point
//! iterations, the points held in single precision as OpenCV holds them), and with
//! zero disparity both take their mean.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Vector3};
use pingcal_geometry::{exp_so3, log_so3, skew};

/// A pinhole camera with OpenCV's distortion coefficients.
#[derive(Clone, Copy, Debug)]
pub struct CvCamera {
    /// fx, fy, cx, cy (px).
    pub k: [f64; 4],
    /// k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 (OpenCV's order; zeros beyond the
    /// model's).
    pub dist: [f64; 12],
}

impl CvCamera {
    /// The camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        let [fx, fy, cx, cy] = self.k;
        Matrix3::new(fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0)
    }

    /// `cv::undistortPoints` of one pixel without R and P: normalised coordinates after
    /// OpenCV's five fixed-point iterations (its rational and thin-prism terms included).
    fn undistort(&self, u: f64, v: f64) -> (f64, f64) {
        let [fx, fy, cx, cy] = self.k;
        let [k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4] = self.dist;
        let (x0, y0) = ((u - cx) / fx, (v - cy) / fy);
        let (mut x, mut y) = (x0, y0);
        for _ in 0..5 {
            let r2 = x * x + y * y;
            let icdist =
                (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2) / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2);
            if icdist < 0.0 {
                return (x0, y0);
            }
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) + s1 * r2 + s2 * r2 * r2;
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y + s3 * r2 + s4 * r2 * r2;
            x = (x0 - dx) * icdist;
            y = (y0 - dy) * icdist;
        }
        (x, y)
    }
}

/// The stereo geometry of a pair: `p_2 = R p_1 + T` between the OpenCV camera frames.
#[derive(Clone, Debug)]
pub struct StereoCv {
    /// Essential matrix `[T]× R`.
    pub e: Matrix3<f64>,
    /// Fundamental matrix `K2⁻ᵀ E K1⁻¹`, scaled to F₃₃ = 1 as `stereoCalibrate` does.
    pub f: Matrix3<f64>,
    /// Rectifying rotation of camera 1.
    pub r1: Matrix3<f64>,
    /// Rectifying rotation of camera 2.
    pub r2: Matrix3<f64>,
    /// Projection matrix of rectified camera 1.
    pub p1: Matrix3x4<f64>,
    /// Projection matrix of rectified camera 2 (the baseline times f in its last column).
    pub p2: Matrix3x4<f64>,
    /// Disparity-to-depth matrix.
    pub q: Matrix4<f64>,
}

/// E and F of the pair (`None` when K2 cannot be inverted).
fn essential_fundamental(
    c1: &CvCamera,
    c2: &CvCamera,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    let e = skew(t) * r;
    let f = c2.matrix().try_inverse()?.transpose() * e * c1.matrix().try_inverse()?;
    let f = if f[(2, 2)].abs() > 0.0 {
        f / f[(2, 2)]
    } else {
        f
    };
    Some((e, f))
}

/// The rectifying rotations (R1, R2), the baseline's axis (0: x, horizontal pair; 1: y)
/// and the rectified baseline `R2 T`.
fn rotations(
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
) -> (Matrix3<f64>, Matrix3<f64>, usize, Vector3<f64>) {
    let r_r = exp_so3(&(log_so3(r) * -0.5));
    let th = r_r * t;
    let idx = if th.x.abs() > th.y.abs() { 0 } else { 1 };
    let c = th[idx];
    let mut uu = Vector3::zeros();
    uu[idx] = if c > 0.0 { 1.0 } else { -1.0 };
    let mut ww = th.cross(&uu);
    let nw = ww.norm();
    if nw > 0.0 {
        ww *= (c.abs() / th.norm()).clamp(-1.0, 1.0).acos() / nw;
    }
    let w_r = exp_so3(&ww);
    let r2 = w_r * r_r;
    (w_r * r_r.transpose(), r2, idx, r2 * t)
}

/// The principal point that centres camera `cam`'s four undistorted image corners after
/// the rectifying rotation `rk` and the focal length `fc` (OpenCV keeps these points in
/// single precision, and so does this).
fn centring(cam: &CvCamera, rk: &Matrix3<f64>, fc: f64, size: (u32, u32)) -> (f64, f64) {
    let (nx, ny) = (f64::from(size.0), f64::from(size.1));
    let mut sum = (0.0, 0.0);
    for i in 0..4 {
        let u = f64::from(i % 2) * (nx - 1.0);
        let v = if i < 2 { 0.0 } else { ny - 1.0 };
        let (x, y) = cam.undistort(u, v);
        let p = rk * Vector3::new(f64::from(x as f32), f64::from(y as f32), 1.0);
        sum.0 += f64::from((fc * p.x / p.z) as f32);
        sum.1 += f64::from((fc * p.y / p.z) as f32);
    }
    (
        (nx - 1.0) / 2.0 - sum.0 / 4.0,
        (ny - 1.0) / 2.0 - sum.1 / 4.0,
    )
}

/// OpenCV's stereo geometry of cameras `c1`, `c2` (images of `size` = (width, height)) with
/// `p_2 = r p_1 + t` (see the module doc); `None` for a degenerate pair (no baseline, or a
/// camera matrix that cannot be inverted).
pub fn stereo_cv(
    c1: &CvCamera,
    c2: &CvCamera,
    size: (u32, u32),
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
) -> Option<StereoCv> {
    let (e, f) = essential_fundamental(c1, c2, r, t)?;
    let (r1, r2, idx, tr) = rotations(r, t);
    if tr[idx] == 0.0 {
        return None;
    }
    let across = 1 - idx;
    let fc = (c1.matrix()[(across, across)] + c2.matrix()[(across, across)]) * 0.5;
    let a = centring(c1, &r1, fc, size);
    let b = centring(c2, &r2, fc, size);
    let cc = ((a.0 + b.0) * 0.5, (a.1 + b.1) * 0.5);
    let mut p1 = Matrix3x4::zeros();
    p1[(0, 0)] = fc;
    p1[(1, 1)] = fc;
    p1[(0, 2)] = cc.0;
    p1[(1, 2)] = cc.1;
    p1[(2, 2)] = 1.0;
    let mut p2 = p1;
    p2[(idx, 3)] = tr[idx] * fc;
    let q = Matrix4::new(
        1.0,
        0.0,
        0.0,
        -cc.0, //
        0.0,
        1.0,
        0.0,
        -cc.1, //
        0.0,
        0.0,
        0.0,
        fc, //
        0.0,
        0.0,
        -1.0 / tr[idx],
        0.0,
    );
    Some(StereoCv {
        e,
        f,
        r1,
        r2,
        p1,
        p2,
        q,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_geometry::from_opk_deg;

    fn camera(fx: f64, cx: f64) -> CvCamera {
        CvCamera {
            k: [fx, fx * 1.001, cx, 361.0],
            dist: [
                -0.12, 0.015, 2.5e-4, 3.6e-4, -4.7e-4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            ],
        }
    }

    /// The rectified pair sees a point on one image row (horizontal epipolar lines), its
    /// disparity gives back its depth through Q, and x₂ᵀ F x₁ = 0 for its images.
    #[test]
    fn rectification_makes_rows_epipolar_and_q_inverts_disparity() {
        let (c1, c2) = (camera(653.4, 642.7), camera(653.8, 636.8));
        let r = from_opk_deg([0.3, -0.25, 0.1]);
        let t = Vector3::new(-120.0, -0.12, 0.83);
        let s = stereo_cv(&c1, &c2, (1280, 720), &r, &t).unwrap();
        for r in [&s.r1, &s.r2] {
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
        }
        let x1 = Vector3::new(150.0, -80.0, 1500.0);
        let x2 = r * x1 + t;
        // P1 and P2 both project from camera 1's rectified frame; camera 2's rectified
        // frame is that frame moved along x by the baseline R2 T
        let xr = s.r1 * x1;
        let tr = s.r2 * t;
        assert!(tr.y.abs() < 1e-9 && tr.z.abs() < 1e-9, "R2 T = {tr:?}");
        assert!((s.r2 * x2 - (xr + tr)).norm() < 1e-9);
        let img = |p: &Matrix3x4<f64>| {
            let h = p * xr.push(1.0);
            (h.x / h.z, h.y / h.z)
        };
        let ((u1, v1), (u2, v2)) = (img(&s.p1), img(&s.p2));
        assert!((v1 - v2).abs() < 1e-9, "rows {v1} vs {v2}");
        let back = s.q * Vector3::new(u1, v1, u1 - u2).push(1.0);
        assert!(
            (back.z / back.w - xr.z).abs() < 1e-6,
            "depth {}",
            back.z / back.w
        );
        let k = |c: &CvCamera, x: &Vector3<f64>| c.matrix() * (x / x.z);
        let epi = k(&c2, &x2).transpose() * s.f * k(&c1, &x1);
        assert!(epi[0].abs() < 1e-9, "x2' F x1 = {}", epi[0]);
        // the wrong direction of R (its transpose) breaks the epipolar constraint
        let wrong = stereo_cv(&c1, &c2, (1280, 720), &r.transpose(), &t).unwrap();
        let bad = k(&c2, &x2).transpose() * wrong.f * k(&c1, &x1);
        assert!(bad[0].abs() > 1e-4, "{}", bad[0]);
    }

    /// No baseline: no rectification.
    #[test]
    fn a_pair_without_baseline_is_refused() {
        let c = camera(650.0, 640.0);
        assert!(stereo_cv(&c, &c, (1280, 720), &Matrix3::identity(), &Vector3::zeros()).is_none());
    }
}
