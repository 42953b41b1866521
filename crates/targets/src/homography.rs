//! Plane-to-image homography: the normalised DLT and the RANSAC loop of `pingcal-geometry`,
//! with a seeded generator (results are deterministic for a given seed). Used to verify
//! coded-target IDs on a flat panel and to predict where the other targets of the panel are.

use nalgebra::{Matrix3, Vector2, Vector3};
use pingcal_geometry::consensus::{self, ConsensusOptions, Estimator, RefitRule};
use pingcal_geometry::dlt::homography_dlt;

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

/// Least-squares homography (normalised DLT, [`pingcal_geometry::dlt::homography_dlt`]) from
/// at least 4 correspondences `src[i] → dst[i]`.
pub fn fit_homography(src: &[[f64; 2]], dst: &[[f64; 2]]) -> Option<Homography> {
    let all: Vec<usize> = (0..src.len().min(dst.len())).collect();
    (src.len() == dst.len())
        .then(|| Correspondences { src, dst }.fit_on(&all))
        .flatten()
}

/// Result of [`ransac_homography`].
#[derive(Clone, Debug)]
pub struct RansacHomography {
    /// The homography `dst ~ H · src`, refitted to its inliers.
    pub h: Homography,
    /// Per correspondence: within `threshold` of the final model.
    pub inliers: Vec<bool>,
    /// Per correspondence: transfer error |H src − dst| in destination units.
    pub errors: Vec<f64>,
}

/// Point correspondences under a homography, for [`consensus::find`]: 4-point DLT, the
/// transfer error, the least-squares refit on the inliers.
struct Correspondences<'a> {
    src: &'a [[f64; 2]],
    dst: &'a [[f64; 2]],
}

impl Correspondences<'_> {
    fn fit_on(&self, idx: &[usize]) -> Option<Homography> {
        let s: Vec<Vector2<f64>> = idx.iter().map(|&i| Vector2::from(self.src[i])).collect();
        let d: Vec<Vector2<f64>> = idx.iter().map(|&i| Vector2::from(self.dst[i])).collect();
        homography_dlt(&s, &d).map(Homography)
    }

    /// Transfer error |H src − dst| of correspondence `i`.
    fn error(&self, h: &Homography, i: usize) -> f64 {
        match h.apply(self.src[i]) {
            Some(p) => ((p[0] - self.dst[i][0]).powi(2) + (p[1] - self.dst[i][1]).powi(2)).sqrt(),
            None => f64::INFINITY,
        }
    }
}

impl Estimator for Correspondences<'_> {
    type Model = Homography;
    fn len(&self) -> usize {
        self.src.len()
    }
    fn sample_size(&self) -> usize {
        4
    }
    fn fit(&self, sample: &[usize], models: &mut Vec<Homography>) {
        models.extend(self.fit_on(sample));
    }
    fn residual(&self, h: &Homography, i: usize) -> f64 {
        self.error(h, i)
    }
    fn refit(&self, inliers: &[usize], _: &Homography) -> Option<Homography> {
        self.fit_on(inliers)
    }
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
    let est = Correspondences { src, dst };
    let opts = ConsensusOptions {
        final_refits: 2,
        final_refit_rule: RefitRule::Always,
        ..ConsensusOptions::ransac(threshold, iterations)
    };
    let h = consensus::find(&est, &opts, &mut consensus::rng(seed))?.model;
    let errors: Vec<f64> = (0..n).map(|i| est.error(&h, i)).collect();
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
