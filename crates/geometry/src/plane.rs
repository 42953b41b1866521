//! The least-squares (orthogonal) plane of a point set.
//!
//! With the centroid `m` and the scatter matrix `S = Σ (pᵢ − m)(pᵢ − m)ᵀ`, the plane's unit
//! normal is the eigenvector of S with the smallest eigenvalue λ₀; the eigenvalues
//! λ₀ ≤ λ₁ ≤ λ₂ are the sums of squared distances along the normal and the two in-plane
//! directions, so `√(λ₀/n)` is the RMS distance of the points from the plane and
//! `√(λ₁/n)`, `√(λ₂/n)` their in-plane spreads (a line, not a plane, when λ₁ is small too).

use nalgebra::{Matrix3, Vector3};

/// A plane `n · x = d` fitted to points, with the spreads that tell how well.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal (its sign is that of the eigen-solver: orient it if it matters).
    pub normal: Vector3<f64>,
    /// Offset: `normal · x = offset` on the plane.
    pub offset: f64,
    /// Centroid of the points.
    pub centroid: Vector3<f64>,
    /// Eigenvalues of the scatter matrix, ascending (see the module doc).
    pub eigenvalues: [f64; 3],
    /// Number of points fitted.
    pub count: usize,
}

impl Plane {
    /// The least-squares plane of `pts`, or `None` for fewer than 3 points or non-finite
    /// coordinates.
    pub fn fit(pts: &[Vector3<f64>]) -> Option<Plane> {
        if pts.len() < 3 {
            return None;
        }
        let m = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
        if !m.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut s = Matrix3::zeros();
        for p in pts {
            let d = p - m;
            s += d * d.transpose();
        }
        let e = s.symmetric_eigen();
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| e.eigenvalues[a].total_cmp(&e.eigenvalues[b]));
        let normal = e.eigenvectors.column(idx[0]).into_owned();
        Some(Plane {
            normal,
            offset: normal.dot(&m),
            centroid: m,
            eigenvalues: idx.map(|i| e.eigenvalues[i]),
            count: pts.len(),
        })
    }

    /// Signed distance of `x` from the plane (positive on the normal's side).
    pub fn distance(&self, x: &Vector3<f64>) -> f64 {
        self.normal.dot(x) - self.offset
    }

    /// RMS distance of the fitted points from the plane and their two in-plane spreads
    /// (standard deviations), ascending: `√(λᵢ / n)`.
    pub fn spreads(&self) -> Vector3<f64> {
        let n = self.count as f64;
        Vector3::from(self.eigenvalues.map(|v| (v.max(0.0) / n).sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_tilted_plane_and_reports_its_spreads() {
        let n = Vector3::new(1.0, 2.0, 2.0).normalize();
        let (u, v) = (
            Vector3::new(2.0, -1.0, 0.0).normalize(),
            n.cross(&Vector3::new(2.0, -1.0, 0.0).normalize()),
        );
        let pts: Vec<_> = (0..100)
            .map(|i| {
                let (a, b) = ((i % 10) as f64 * 10.0, (i / 10) as f64 * 20.0);
                n * 7.0
                    + u * a
                    + v * b
                    + n * if (i % 10 + i / 10) % 2 == 0 {
                        0.1
                    } else {
                        -0.1
                    }
            })
            .collect();
        let p = Plane::fit(&pts).unwrap();
        assert!(p.normal.dot(&n).abs() > 1.0 - 1e-12);
        assert!((p.distance(&(n * 7.0))).abs() < 1e-9);
        assert!((p.spreads()[0] - 0.1).abs() < 1e-9);
        assert!(Plane::fit(&pts[..2]).is_none());
        assert!(Plane::fit(&[Vector3::new(f64::NAN, 0.0, 0.0); 3]).is_none());
    }
}
