//! Plane-to-image homography: normalised DLT, and RANSAC with a seeded generator (results are
//! deterministic for a given seed). Used to verify coded-target IDs on a flat panel and to
//! predict where the other targets of the panel are.

use nalgebra::{DMatrix, Matrix3, Vector3};
use rand::{rngs::StdRng, Rng, SeedableRng};

/// A homography `x' ~ H x` between 2D points.
#[derive(Clone, Copy, Debug)]
pub struct Homography(pub Matrix3<f64>);

impl Homography {
    /// Maps a point; `None` at (or behind) the line at infinity.
    pub fn apply(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        let v = self.0 * Vector3::new(p[0], p[1], 1.0);
        if v[2].abs() < 1e-12 {
            return None;
        }
        Some([v[0] / v[2], v[1] / v[2]])
    }
}

fn normaliser(pts: &[[f64; 2]]) -> Matrix3<f64> {
    let n = pts.len() as f64;
    let (mut mx, mut my) = (0.0, 0.0);
    for p in pts {
        mx += p[0];
        my += p[1];
    }
    mx /= n;
    my /= n;
    let mut d = 0.0;
    for p in pts {
        d += ((p[0] - mx).powi(2) + (p[1] - my).powi(2)).sqrt();
    }
    d /= n;
    let s = if d > 0.0 {
        std::f64::consts::SQRT_2 / d
    } else {
        1.0
    };
    Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0)
}

/// Least-squares homography (normalised DLT) from at least 4 correspondences `src[i] → dst[i]`.
pub fn fit_homography(src: &[[f64; 2]], dst: &[[f64; 2]]) -> Option<Homography> {
    let n = src.len();
    if n < 4 || dst.len() != n {
        return None;
    }
    let ts = normaliser(src);
    let td = normaliser(dst);
    let mut a = DMatrix::<f64>::zeros(2 * n, 9);
    for i in 0..n {
        let s = ts * Vector3::new(src[i][0], src[i][1], 1.0);
        let d = td * Vector3::new(dst[i][0], dst[i][1], 1.0);
        let (x, y, u, v) = (s[0], s[1], d[0], d[1]);
        let r = 2 * i;
        for (j, val) in [-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]
            .iter()
            .enumerate()
        {
            a[(r, j)] = *val;
        }
        for (j, val) in [0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]
            .iter()
            .enumerate()
        {
            a[(r + 1, j)] = *val;
        }
    }
    // Null vector of A: eigenvector of AᵀA with the smallest eigenvalue.
    let ata = a.transpose() * &a;
    let eig = nalgebra::SymmetricEigen::new(ata);
    let (imin, _) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |acc, (i, &v)| if v < acc.1 { (i, v) } else { acc },
        );
    let h = eig.eigenvectors.column(imin);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let hm = td.try_inverse()? * hn * ts;
    if !hm.iter().all(|v| v.is_finite()) || hm[(2, 2)].abs() < 1e-300 && hm.norm() == 0.0 {
        return None;
    }
    Some(Homography(hm / hm.norm()))
}

/// Result of [`ransac_homography`].
#[derive(Clone, Debug)]
pub struct RansacHomography {
    pub h: Homography,
    /// Per correspondence: within `threshold` of the final model.
    pub inliers: Vec<bool>,
    /// Per correspondence: transfer error |H src − dst| in destination units.
    pub errors: Vec<f64>,
}

/// RANSAC homography: `iterations` random 4-point samples from a generator seeded with `seed`,
/// the model with most inliers (transfer error ≤ `threshold`) refitted to its inliers twice.
pub fn ransac_homography(
    src: &[[f64; 2]],
    dst: &[[f64; 2]],
    threshold: f64,
    iterations: usize,
    seed: u64,
) -> Option<RansacHomography> {
    let n = src.len();
    if n < 4 || dst.len() != n {
        return None;
    }
    let err = |h: &Homography, i: usize| -> f64 {
        match h.apply(src[i]) {
            Some(p) => ((p[0] - dst[i][0]).powi(2) + (p[1] - dst[i][1]).powi(2)).sqrt(),
            None => f64::INFINITY,
        }
    };
    let mut rng = StdRng::seed_from_u64(seed);
    let mut best: Option<(usize, Homography)> = None;
    for _ in 0..iterations {
        let mut idx = [0usize; 4];
        for k in 0..4 {
            loop {
                let c = rng.random_range(0..n);
                if !idx[..k].contains(&c) {
                    idx[k] = c;
                    break;
                }
            }
        }
        let s: Vec<[f64; 2]> = idx.iter().map(|&i| src[i]).collect();
        let d: Vec<[f64; 2]> = idx.iter().map(|&i| dst[i]).collect();
        let Some(h) = fit_homography(&s, &d) else {
            continue;
        };
        let count = (0..n).filter(|&i| err(&h, i) <= threshold).count();
        if best.as_ref().is_none_or(|(c, _)| count > *c) {
            best = Some((count, h));
        }
    }
    let (_, mut h) = best?;
    for _ in 0..2 {
        let inl: Vec<usize> = (0..n).filter(|&i| err(&h, i) <= threshold).collect();
        if inl.len() < 4 {
            break;
        }
        let s: Vec<[f64; 2]> = inl.iter().map(|&i| src[i]).collect();
        let d: Vec<[f64; 2]> = inl.iter().map(|&i| dst[i]).collect();
        match fit_homography(&s, &d) {
            Some(h2) => h = h2,
            None => break,
        }
    }
    let errors: Vec<f64> = (0..n).map(|i| err(&h, i)).collect();
    let inliers = errors.iter().map(|&e| e <= threshold).collect();
    Some(RansacHomography { h, inliers, errors })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_homography_with_outliers() {
        let h = Homography(Matrix3::new(
            2.0, 0.3, 100.0, -0.2, 1.8, 50.0, 1e-4, -2e-4, 1.0,
        ));
        let mut src = Vec::new();
        let mut dst = Vec::new();
        for i in 0..10 {
            for j in 0..8 {
                let p = [i as f64 * 80.0, j as f64 * 80.0];
                src.push(p);
                dst.push(h.apply(p).unwrap());
            }
        }
        dst[3] = [0.0, 0.0];
        dst[40][0] += 30.0;
        let r = ransac_homography(&src, &dst, 1.0, 200, 7).unwrap();
        assert!(!r.inliers[3] && !r.inliers[40]);
        assert_eq!(r.inliers.iter().filter(|&&b| b).count(), 78);
        assert!(r
            .errors
            .iter()
            .enumerate()
            .all(|(i, &e)| i == 3 || i == 40 || e < 1e-6));
    }
}
