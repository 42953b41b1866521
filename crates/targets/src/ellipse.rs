//! Ellipses: the conic fit (Fitzgibbon's direct least squares in Halíř & Flusser's numerically
//! stable form, on normalised coordinates), conversion between conic and geometric parameters,
//! the affine map from the unit circle, and point-to-ellipse (Sampson) distances.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

/// An ellipse in pixel coordinates: centre, semi-axes `a >= b > 0`, and `theta`, the angle of
/// the major axis from the x axis towards the y axis (radians).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Ellipse {
    /// Centre x, px.
    pub cx: f64,
    /// Centre y, px, down.
    pub cy: f64,
    /// Semi-major axis, px.
    pub a: f64,
    /// Semi-minor axis, px (`b <= a`).
    pub b: f64,
    /// Angle of the major axis from the x axis towards the y axis, radians (clockwise on
    /// screen, y being down).
    pub theta: f64,
}

impl Ellipse {
    /// A circle.
    pub fn circle(cx: f64, cy: f64, r: f64) -> Self {
        Ellipse {
            cx,
            cy,
            a: r,
            b: r,
            theta: 0.0,
        }
    }

    /// The ellipse of the second moments of a region: for a uniformly filled ellipse the
    /// (central) moments are a²/4 along the major axis and b²/4 along the minor one.
    pub fn from_moments(cx: f64, cy: f64, mxx: f64, mxy: f64, myy: f64) -> Option<Self> {
        let tr = mxx + myy;
        let det = mxx * myy - mxy * mxy;
        let disc = ((tr * tr) / 4.0 - det).max(0.0).sqrt();
        let l1 = tr / 2.0 + disc;
        let l2 = tr / 2.0 - disc;
        if !(l2 > 0.0) || !l1.is_finite() {
            return None;
        }
        let theta = 0.5 * (2.0 * mxy).atan2(mxx - myy);
        Some(Ellipse {
            cx,
            cy,
            a: 2.0 * l1.sqrt(),
            b: 2.0 * l2.sqrt(),
            theta,
        })
    }

    /// Linear part of the map from the unit circle onto this ellipse: R(θ)·diag(a, b).
    pub fn affine(&self) -> [[f64; 2]; 2] {
        let (s, c) = self.theta.sin_cos();
        [[c * self.a, -s * self.b], [s * self.a, c * self.b]]
    }

    /// Maps (u, v) in the unit-circle frame to the image.
    #[inline]
    pub fn map(&self, u: f64, v: f64) -> (f64, f64) {
        let (s, c) = self.theta.sin_cos();
        let (p, q) = (u * self.a, v * self.b);
        (self.cx + c * p - s * q, self.cy + s * p + c * q)
    }

    /// Maps an image point to the unit-circle frame (inverse of [`Ellipse::map`]).
    #[inline]
    pub fn unmap(&self, x: f64, y: f64) -> (f64, f64) {
        let (s, c) = self.theta.sin_cos();
        let (dx, dy) = (x - self.cx, y - self.cy);
        ((c * dx + s * dy) / self.a, (-s * dx + c * dy) / self.b)
    }

    /// Point of the ellipse at parameter `t`.
    pub fn point(&self, t: f64) -> (f64, f64) {
        self.map(t.cos(), t.sin())
    }

    /// Scaled copy (same centre and orientation).
    pub fn scaled(&self, k: f64) -> Self {
        Ellipse {
            a: self.a * k,
            b: self.b * k,
            ..*self
        }
    }

    /// Mean radius √(ab).
    pub fn radius(&self) -> f64 {
        (self.a * self.b).sqrt()
    }

    /// Conic coefficients (A, B, C, D, E, F) of A x² + B xy + C y² + D x + E y + F = 0.
    pub fn conic(&self) -> [f64; 6] {
        let (s, c) = self.theta.sin_cos();
        let (a2, b2) = (self.a * self.a, self.b * self.b);
        let aa = c * c / a2 + s * s / b2;
        let bb = 2.0 * c * s * (1.0 / a2 - 1.0 / b2);
        let cc = s * s / a2 + c * c / b2;
        let (x0, y0) = (self.cx, self.cy);
        let dd = -2.0 * aa * x0 - bb * y0;
        let ee = -bb * x0 - 2.0 * cc * y0;
        let ff = aa * x0 * x0 + bb * x0 * y0 + cc * y0 * y0 - 1.0;
        [aa, bb, cc, dd, ee, ff]
    }

    /// The map to and from the unit-circle frame with its trigonometry done once (for loops).
    pub fn frame(&self) -> Frame {
        let (s, c) = self.theta.sin_cos();
        Frame {
            cx: self.cx,
            cy: self.cy,
            c,
            s,
            a: self.a,
            b: self.b,
        }
    }

    /// Signed Sampson distance of a point to the ellipse (first-order orthogonal distance;
    /// positive outside).
    pub fn sampson_distance(&self, x: f64, y: f64) -> f64 {
        sampson(&self.conic(), x, y)
    }
}

/// [`Ellipse::map`] and [`Ellipse::unmap`] with precomputed cosine and sine.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    cx: f64,
    cy: f64,
    c: f64,
    s: f64,
    a: f64,
    b: f64,
}

impl Frame {
    /// Unit-circle frame → image.
    #[inline]
    pub fn map(&self, u: f64, v: f64) -> (f64, f64) {
        let (p, q) = (u * self.a, v * self.b);
        (
            self.cx + self.c * p - self.s * q,
            self.cy + self.s * p + self.c * q,
        )
    }

    /// Image → unit-circle frame.
    #[inline]
    pub fn unmap(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.cx, y - self.cy);
        (
            (self.c * dx + self.s * dy) / self.a,
            (-self.s * dx + self.c * dy) / self.b,
        )
    }
}

/// The real eigenvalues of a 3×3 matrix: the real roots of its characteristic cubic, by the
/// trigonometric form (three real roots) or Cardano's (one), each polished by two Newton steps
/// on the cubic. A pair of complex roots whose imaginary parts vanish (a double root) counts as
/// real, once per root.
pub fn real_eigenvalues(m: &Matrix3<f64>) -> Vec<f64> {
    // λ³ + a λ² + b λ + c = 0.
    let a = -m.trace();
    let b = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)] + m[(0, 0)] * m[(2, 2)]
        - m[(0, 2)] * m[(2, 0)]
        + m[(1, 1)] * m[(2, 2)]
        - m[(1, 2)] * m[(2, 1)];
    let c = -m.determinant();
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return Vec::new();
    }
    // λ = t − a/3: t³ + p t + q = 0.
    let p = b - a * a / 3.0;
    let q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
    let disc = (q / 2.0).powi(2) + (p / 3.0).powi(3);
    let mut roots: Vec<f64> = if disc > 0.0 {
        let sq = disc.sqrt();
        vec![(-q / 2.0 + sq).cbrt() + (-q / 2.0 - sq).cbrt()]
    } else if p < 0.0 {
        let r = (-p / 3.0).sqrt();
        let phi = (-q / (2.0 * r * r * r)).clamp(-1.0, 1.0).acos();
        (0..3)
            .map(|k| 2.0 * r * ((phi - 2.0 * std::f64::consts::PI * k as f64) / 3.0).cos())
            .collect()
    } else {
        // p = q = 0: a triple root.
        vec![0.0; 3]
    };
    for t in roots.iter_mut() {
        let mut l = *t - a / 3.0;
        for _ in 0..2 {
            let f = ((l + a) * l + b) * l + c;
            let d = (3.0 * l + 2.0 * a) * l + b;
            if d != 0.0 && (f / d).is_finite() {
                l -= f / d;
            }
        }
        *t = l;
    }
    roots
}

/// Signed Sampson distance of (x, y) to the conic `k` (see [`Ellipse::conic`]).
#[inline]
pub fn sampson(k: &[f64; 6], x: f64, y: f64) -> f64 {
    {
        let [a, b, c, d, e, f] = *k;
        let q = a * x * x + b * x * y + c * y * y + d * x + e * y + f;
        let gx = 2.0 * a * x + b * y + d;
        let gy = b * x + 2.0 * c * y + e;
        let g = (gx * gx + gy * gy).sqrt();
        if g > 0.0 {
            q / g
        } else {
            0.0
        }
    }
}

impl Ellipse {
    /// Geometric parameters from conic coefficients; `None` unless the conic is a real ellipse.
    pub fn from_conic(k: [f64; 6]) -> Option<Self> {
        let [a, b, c, d, e, f] = k;
        let den = 4.0 * a * c - b * b;
        if !(den > 0.0) {
            return None;
        }
        let cx = (b * e - 2.0 * c * d) / den;
        let cy = (b * d - 2.0 * a * e) / den;
        // Value at the centre; the quadratic part is [[a, b/2], [b/2, c]].
        let f0 = f + 0.5 * (d * cx + e * cy);
        let tr = a + c;
        let disc = (((a - c) * (a - c)) + b * b).sqrt();
        let l1 = (tr + disc) / 2.0;
        let l2 = (tr - disc) / 2.0;
        // Ellipse: l1 u² + l2 v² = -f0 in the eigenframe. Both l must have sign opposite to f0.
        let (l1, l2, f0) = if l1 < 0.0 {
            (-l1, -l2, -f0)
        } else {
            (l1, l2, f0)
        };
        if !(l2 > 0.0) || !(f0 < 0.0) {
            return None;
        }
        // Larger eigenvalue ↔ minor axis.
        let semi_minor = (-f0 / l1).sqrt();
        let semi_major = (-f0 / l2).sqrt();
        // Direction of the eigenvector of l2 (the major axis).
        let theta = if b.abs() < 1e-300 && (a - c).abs() < 1e-300 {
            0.0
        } else {
            // angle of the axis of the smaller eigenvalue of [[a,b/2],[b/2,c]]
            0.5 * (b).atan2(a - c) + std::f64::consts::FRAC_PI_2
        };
        // After the sign flip above the eigenvalues have changed order: the axis along `theta`
        // (of length `semi_major`) is then the shorter one; swap to keep a ≥ b.
        let (semi_major, semi_minor, theta) = if semi_major >= semi_minor {
            (semi_major, semi_minor, theta)
        } else {
            (semi_minor, semi_major, theta + std::f64::consts::FRAC_PI_2)
        };
        let el = Ellipse {
            cx,
            cy,
            a: semi_major,
            b: semi_minor,
            theta: normalize_angle(theta),
        };
        if el.a.is_finite() && el.b.is_finite() && el.cx.is_finite() && el.cy.is_finite() {
            Some(el)
        } else {
            None
        }
    }
}

fn normalize_angle(t: f64) -> f64 {
    let pi = std::f64::consts::PI;
    let mut t = t % pi;
    if t < -pi / 2.0 {
        t += pi;
    }
    if t >= pi / 2.0 {
        t -= pi;
    }
    t
}

/// Direct least-squares ellipse fit (Fitzgibbon, Pilu & Fisher 1999; Halíř & Flusser 1998)
/// to at least 5 points. Coordinates are centred and scaled first. `None` when the points do
/// not determine an ellipse.
pub fn fit_ellipse(points: &[(f64, f64)]) -> Option<Ellipse> {
    let n = points.len();
    if n < 5 {
        return None;
    }
    let (mut mx, mut my) = (0.0, 0.0);
    for &(x, y) in points {
        mx += x;
        my += y;
    }
    mx /= n as f64;
    my /= n as f64;
    let mut s = 0.0;
    for &(x, y) in points {
        s += ((x - mx).powi(2) + (y - my).powi(2)).sqrt();
    }
    s /= n as f64;
    if !(s > 0.0) {
        return None;
    }
    let mut s1 = Matrix3::<f64>::zeros();
    let mut s2 = Matrix3::<f64>::zeros();
    let mut s3 = Matrix3::<f64>::zeros();
    for &(x, y) in points {
        let (x, y) = ((x - mx) / s, (y - my) / s);
        let d1 = Vector3::new(x * x, x * y, y * y);
        let d2 = Vector3::new(x, y, 1.0);
        s1 += d1 * d1.transpose();
        s2 += d1 * d2.transpose();
        s3 += d2 * d2.transpose();
    }
    let s3inv = s3.try_inverse()?;
    let t = -(s3inv * s2.transpose());
    let m = s1 + s2 * t;
    // C1⁻¹ · M with C1 = [[0,0,2],[0,-1,0],[2,0,0]].
    let m = Matrix3::new(
        m[(2, 0)] / 2.0,
        m[(2, 1)] / 2.0,
        m[(2, 2)] / 2.0,
        -m[(1, 0)],
        -m[(1, 1)],
        -m[(1, 2)],
        m[(0, 0)] / 2.0,
        m[(0, 1)] / 2.0,
        m[(0, 2)] / 2.0,
    );
    let mut best: Option<(f64, Vector3<f64>)> = None;
    for l in real_eigenvalues(&m) {
        // Eigenvector: the null vector of M − λI, the largest of the cross products of two of
        // its rows (the matrix has rank 2 for a simple eigenvalue).
        let a = m - Matrix3::identity() * l;
        let (r0, r1, r2) = (
            a.row(0).transpose(),
            a.row(1).transpose(),
            a.row(2).transpose(),
        );
        let v = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)]
            .into_iter()
            .max_by(|p, q| p.norm_squared().total_cmp(&q.norm_squared()))?;
        if !(v.norm_squared() > 0.0) {
            continue;
        }
        let v = v.normalize();
        let cond = 4.0 * v[0] * v[2] - v[1] * v[1];
        if cond > 0.0 && best.as_ref().is_none_or(|(c, _)| cond > *c) {
            best = Some((cond, v));
        }
    }
    let (_, a1) = best?;
    let a2 = t * a1;
    // Conic in normalised coordinates x' = (x - mx)/s; substitute back.
    let (a, b, c, d, e, f) = (a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]);
    let s2_ = s * s;
    let aa = a / s2_;
    let bb = b / s2_;
    let cc = c / s2_;
    let dd = d / s - 2.0 * a * mx / s2_ - b * my / s2_;
    let ee = e / s - 2.0 * c * my / s2_ - b * mx / s2_;
    let ff = f + (a * mx * mx + b * mx * my + c * my * my) / s2_ - (d * mx + e * my) / s;
    Ellipse::from_conic([aa, bb, cc, dd, ee, ff])
}

/// cos and sin of i·2π/k for i in 0..k (the sampling angles of rays and rings), computed once
/// per `k` up to 256 and shared; larger `k` are computed on the spot.
pub(crate) fn unit_circle(k: usize) -> std::borrow::Cow<'static, [(f64, f64)]> {
    const MAX_CACHED: usize = 256;
    fn angles(k: usize) -> Vec<(f64, f64)> {
        (0..k)
            .map(|i| {
                let psi = i as f64 * 2.0 * std::f64::consts::PI / k as f64;
                (psi.cos(), psi.sin())
            })
            .collect()
    }
    static TABLES: std::sync::OnceLock<Vec<Vec<(f64, f64)>>> = std::sync::OnceLock::new();
    if k > MAX_CACHED {
        return std::borrow::Cow::Owned(angles(k));
    }
    let t = TABLES.get_or_init(|| (0..=MAX_CACHED).map(angles).collect());
    std::borrow::Cow::Borrowed(&t[k])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conic_round_trip() {
        let e = Ellipse {
            cx: 10.0,
            cy: -3.0,
            a: 7.0,
            b: 3.0,
            theta: 0.4,
        };
        let back = Ellipse::from_conic(e.conic()).unwrap();
        assert!((back.cx - e.cx).abs() < 1e-9 && (back.cy - e.cy).abs() < 1e-9);
        assert!((back.a - e.a).abs() < 1e-9 && (back.b - e.b).abs() < 1e-9);
        assert!((back.theta - e.theta).abs() < 1e-9);
    }

    /// A conic and its negative are the same ellipse: both give a ≥ b and the same axes (the
    /// negative once came back with a and b swapped and `theta` along the minor axis).
    #[test]
    fn negated_conic_is_the_same_ellipse() {
        for theta in [-1.4, -0.3, 0.0, 0.4, 1.2] {
            let e = Ellipse {
                cx: 10.0,
                cy: -3.0,
                a: 7.0,
                b: 3.0,
                theta,
            };
            let k = e.conic().map(|v| -2.5 * v);
            let back = Ellipse::from_conic(k).unwrap();
            assert!((back.cx - e.cx).abs() < 1e-9 && (back.cy - e.cy).abs() < 1e-9);
            assert!(
                (back.a - e.a).abs() < 1e-9 && (back.b - e.b).abs() < 1e-9,
                "{back:?}"
            );
            assert!((back.theta - e.theta).abs() < 1e-9, "{back:?}");
        }
    }

    /// The closed-form real eigenvalues agree with nalgebra's Schur decomposition.
    #[test]
    fn real_eigenvalues_match_schur() {
        let mut seed = 11u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..2000 {
            let m = Matrix3::from_fn(|_, _| rnd() * 10.0);
            let mut want: Vec<f64> = m
                .complex_eigenvalues()
                .iter()
                .filter(|l| l.im.abs() <= 1e-9 * (1.0 + l.re.abs()))
                .map(|l| l.re)
                .collect();
            let mut got = real_eigenvalues(&m);
            want.sort_by(f64::total_cmp);
            got.sort_by(f64::total_cmp);
            assert_eq!(want.len(), got.len(), "{m} {want:?} {got:?}");
            for (w, g) in want.iter().zip(&got) {
                assert!(
                    (w - g).abs() <= 1e-9 * (1.0 + w.abs()),
                    "{m} {want:?} {got:?}"
                );
            }
        }
    }

    #[test]
    fn fit_exact_points() {
        let e = Ellipse {
            cx: 1000.5,
            cy: 700.25,
            a: 12.0,
            b: 5.0,
            theta: -1.1,
        };
        let pts: Vec<_> = (0..40).map(|i| e.point(i as f64 * 0.157)).collect();
        let f = fit_ellipse(&pts).unwrap();
        assert!(
            (f.cx - e.cx).abs() < 1e-6 && (f.cy - e.cy).abs() < 1e-6,
            "{f:?}"
        );
        assert!((f.a - e.a).abs() < 1e-6 && (f.b - e.b).abs() < 1e-6);
        assert!((f.theta - e.theta).abs() < 1e-6);
        for p in &pts {
            assert!(f.sampson_distance(p.0, p.1).abs() < 1e-6);
        }
        let (u, v) = e.unmap(e.map(0.3, -0.7).0, e.map(0.3, -0.7).1);
        assert!((u - 0.3).abs() < 1e-12 && (v + 0.7).abs() < 1e-12);
    }

    #[test]
    fn moments_of_a_filled_ellipse() {
        // Moments of a uniformly filled ellipse: a²/4 and b²/4.
        let e = Ellipse::from_moments(0.0, 0.0, 25.0 / 4.0, 0.0, 4.0 / 4.0).unwrap();
        assert!((e.a - 5.0).abs() < 1e-12 && (e.b - 2.0).abs() < 1e-12);
    }
}
