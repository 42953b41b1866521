//! Hartley normalisation and the normalised direct linear transform (DLT) of a homography.
//!
//! Hartley (1997): before a DLT, translate the points so that their centroid is the origin
//! and scale them so that their mean distance from it is √2; the linear system is then well
//! conditioned whatever the units. [`hartley_normaliser`] is that similarity `T`;
//! [`homography_dlt`] solves `x'ᵢ ~ H xᵢ` on the normalised points (the null vector of the
//! stacked `x' × (H x) = 0` rows, as the eigenvector of `AᵀA` with the smallest eigenvalue)
//! and returns `H = T'⁻¹ Ĥ T` scaled to unit Frobenius norm.

use nalgebra::{Matrix3, SMatrix, Vector2, Vector3};

/// The similarity `T` (3×3, homogeneous) that moves the centroid of `p` to the origin and
/// makes the mean distance from it √2 (the identity scale for coincident points).
pub fn hartley_normaliser(p: &[Vector2<f64>]) -> Matrix3<f64> {
    let n = p.len().max(1) as f64;
    let m = p.iter().sum::<Vector2<f64>>() / n;
    let md = p.iter().map(|q| (q - m).norm()).sum::<f64>() / n;
    let s = if md > 0.0 {
        std::f64::consts::SQRT_2 / md
    } else {
        1.0
    };
    Matrix3::new(s, 0.0, -s * m.x, 0.0, s, -s * m.y, 0.0, 0.0, 1.0)
}

/// The homography `dst ~ H src` of four or more correspondences (normalised DLT, least
/// squares for more than four), scaled to `‖H‖ = 1`; `None` for fewer than four pairs,
/// mismatched lengths or a degenerate (non-finite) result.
pub fn homography_dlt(src: &[Vector2<f64>], dst: &[Vector2<f64>]) -> Option<Matrix3<f64>> {
    if src.len() < 4 || dst.len() != src.len() {
        return None;
    }
    let (t1, t2) = (hartley_normaliser(src), hartley_normaliser(dst));
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (a, b) in src.iter().zip(dst) {
        let x = t1 * Vector3::new(a.x, a.y, 1.0);
        let y = t2 * Vector3::new(b.x, b.y, 1.0);
        // y × (H x) = 0: two independent rows.
        let mut r1 = SMatrix::<f64, 9, 1>::zeros();
        let mut r2 = SMatrix::<f64, 9, 1>::zeros();
        for j in 0..3 {
            r1[3 + j] = -y.z * x[j];
            r1[6 + j] = y.y * x[j];
            r2[j] = y.z * x[j];
            r2[6 + j] = -y.x * x[j];
        }
        ata += r1 * r1.transpose() + r2 * r2.transpose();
    }
    if !ata.iter().all(|v| v.is_finite()) {
        return None;
    }
    let eig = ata.symmetric_eigen();
    let k = eig.eigenvalues.imin();
    let v = eig.eigenvectors.column(k);
    let hn = Matrix3::from_fn(|i, j| v[3 * i + j]);
    let h = t2.try_inverse()? * hn * t1;
    let s = h.norm();
    (s > 0.0 && h.iter().all(|x| x.is_finite())).then(|| h / s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normaliser_centres_and_scales() {
        let p = [
            Vector2::new(100.0, 200.0),
            Vector2::new(300.0, 200.0),
            Vector2::new(200.0, 400.0),
        ];
        let t = hartley_normaliser(&p);
        let q: Vec<Vector2<f64>> = p
            .iter()
            .map(|a| (t * Vector3::new(a.x, a.y, 1.0)).xy())
            .collect();
        let m = q.iter().sum::<Vector2<f64>>() / 3.0;
        assert!(m.norm() < 1e-12);
        let md = q.iter().map(|a| a.norm()).sum::<f64>() / 3.0;
        assert!((md - 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn recovers_a_homography_in_pixel_units() {
        let h = Matrix3::new(1.2, 0.1, 300.0, -0.05, 0.9, 120.0, 1e-4, -2e-4, 1.0);
        let src: Vec<Vector2<f64>> = (0..20)
            .map(|i| Vector2::new((i % 5) as f64 * 400.0, (i / 5) as f64 * 300.0))
            .collect();
        let dst: Vec<Vector2<f64>> = src
            .iter()
            .map(|p| {
                let v = h * Vector3::new(p.x, p.y, 1.0);
                v.xy() / v.z
            })
            .collect();
        let e = homography_dlt(&src, &dst).unwrap();
        let e = e / e[(2, 2)];
        assert!((e - h).norm() < 1e-9 * h.norm(), "{e}");
        assert!(homography_dlt(&src[..3], &dst[..3]).is_none());
    }
}
