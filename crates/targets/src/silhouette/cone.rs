//! The centre of a sphere of known radius from rays through its outline: every ray on the
//! silhouette cone makes the angle `α = asin(r/|c|)` with the direction to the centre `c`.
//!
//! The residual of unit ray `q` is `acos(q·ĉ) − asin(r/|c|)` (radians), its derivatives by
//! the three coordinates of `c` analytic ([`cone_residuals`]). [`fit_cone`] is Gauss–Newton
//! from a start, with the covariance `s² (JᵀJ)⁻¹` from the residuals' mean square; [`robust_fit`]
//! is the same by iteratively reweighted least squares with Tukey's biweight on a scale from
//! the residuals' median absolute deviation, for outlines partly covered or crossed by other
//! edges, and says which rays are inliers. Rays are in any right-handed camera frame; the
//! centre comes out in that frame, in the radius' unit.

use nalgebra::{Matrix3, Vector3};

type V3 = Vector3<f64>;

/// Residuals (radians) and Jacobian rows of the silhouette cone of a sphere of radius `r`
/// centred at `c` against unit rays `q`: `acos(q·ĉ) − asin(r/|c|)`. `None` when the camera
/// is inside the sphere.
pub fn cone_residuals(q: &[V3], c: &V3, r: f64) -> Option<(Vec<f64>, Vec<V3>)> {
    let d = c.norm();
    if !(d > r * 1.0001) {
        return None;
    }
    let u = c / d;
    let alpha = (r / d).asin();
    let dalpha = u * (-r / (d * d * (1.0 - (r / d).powi(2)).sqrt()));
    let mut res = Vec::with_capacity(q.len());
    let mut jac = Vec::with_capacity(q.len());
    for qi in q {
        let cos = qi.dot(&u).clamp(-1.0, 1.0);
        let theta = cos.acos();
        let sin = theta.sin().max(1e-12);
        let dtheta = -(qi - u * cos) / (d * sin);
        res.push(theta - alpha);
        jac.push(dtheta - dalpha);
    }
    Some((res, jac))
}

/// Weighted Gauss–Newton of the centre from `c0` (weights `w`, `None`: all 1); the centre
/// and the normal matrix `Σ wᵢ Jᵢ Jᵢᵀ` at it.
fn gauss_newton(q: &[V3], w: Option<&[f64]>, c0: V3, r: f64) -> Option<(V3, Matrix3<f64>)> {
    let mut c = c0;
    for _ in 0..30 {
        let (res, jac) = cone_residuals(q, &c, r)?;
        let mut n = Matrix3::zeros();
        let mut g = V3::zeros();
        for (i, (e, j)) in res.iter().zip(&jac).enumerate() {
            let wi = w.map_or(1.0, |w| w[i]);
            n += j * j.transpose() * wi;
            g += j * (*e * wi);
        }
        let mut dx = n.try_inverse()? * (-g);
        // never jump through the camera: at most half way towards it per step
        let lim = 0.5 * (c.norm() - r);
        if dx.norm() > lim {
            dx *= lim / dx.norm();
        }
        c += dx;
        if dx.norm() < 1e-10 * c.norm() {
            break;
        }
    }
    let (_, jac) = cone_residuals(q, &c, r)?;
    let mut n = Matrix3::zeros();
    for (i, j) in jac.iter().enumerate() {
        n += j * j.transpose() * w.map_or(1.0, |w| w[i]);
    }
    c.iter().all(|v| v.is_finite()).then_some((c, n))
}

/// Gauss–Newton fit of the centre to the rays; returns the centre, its covariance
/// `s²(JᵀJ)⁻¹` with s² the residuals' mean square over n − 3, and s (radians).
pub fn fit_cone(q: &[V3], c0: V3, r: f64) -> Option<(V3, Matrix3<f64>, f64)> {
    let (c, n) = gauss_newton(q, None, c0, r)?;
    let (res, _) = cone_residuals(q, &c, r)?;
    let dof = res.len().checked_sub(3).filter(|&d| d > 0)?;
    let s2 = res.iter().map(|e| e * e).sum::<f64>() / dof as f64;
    let cov = n.try_inverse()? * s2;
    Some((c, cov, s2.sqrt()))
}

/// [`fit_cone`] with weights `w` (relative: scaled to mean 1), the covariance
/// `s² (JᵀWJ)⁻¹` with `s² = Σ wᵢ eᵢ² / (n − 3)`, and the normal matrix's inverse
/// `(JᵀWJ)⁻¹` (for [`fit_cone`]'s callers that propagate more than the residuals' scatter).
#[allow(clippy::type_complexity)]
pub fn fit_cone_weighted(
    q: &[V3],
    w: &[f64],
    c0: V3,
    r: f64,
) -> Option<(V3, Matrix3<f64>, f64, Matrix3<f64>)> {
    let mean = w.iter().sum::<f64>() / w.len().max(1) as f64;
    if !(mean > 0.0) {
        return None;
    }
    let w: Vec<f64> = w.iter().map(|x| x / mean).collect();
    let (c, n) = gauss_newton(q, Some(&w), c0, r)?;
    let (res, _) = cone_residuals(q, &c, r)?;
    let dof = res.len().checked_sub(3).filter(|&d| d > 0)?;
    let s2 = res.iter().zip(&w).map(|(e, wi)| wi * e * e).sum::<f64>() / dof as f64;
    let ni = n.try_inverse()?;
    Some((c, ni * s2, s2.sqrt(), ni))
}

/// A robust fit's result.
#[derive(Clone, Debug)]
pub struct RobustCone {
    /// The centre.
    pub centre: V3,
    /// Each ray's residual at it, radians.
    pub residuals: Vec<f64>,
    /// Whether each ray is an inlier: `|residual| ≤ max(3 σ, floor)`.
    pub inlier: Vec<bool>,
    /// The robust σ of the residuals (1.4826 · MAD), radians.
    pub sigma: f64,
}

/// The centre of the sphere of radius `r` whose silhouette cone passes through three unit
/// rays: the circle through their tips on the unit sphere is the cone's base, its plane's
/// normal the axis and its distance from the origin cos α; `None` for rays on one great
/// circle or a cone wider than a hemisphere.
pub fn cone_through(q: [&V3; 3], r: f64) -> Option<V3> {
    let n = (q[1] - q[0]).cross(&(q[2] - q[0]));
    let nn = n.norm();
    if !(nn > 1e-12) {
        return None;
    }
    let mut w = n / nn;
    let mut cos = w.dot(q[0]);
    if cos < 0.0 {
        (w, cos) = (-w, -cos);
    }
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    (cos > 0.0 && sin > 1e-9).then(|| w * (r / sin))
}

/// The number of samples of [`consensus_start`].
pub const CONSENSUS_SAMPLES: usize = 300;

/// MSAC over minimal samples (three rays, [`cone_through`]) with threshold `tau`: the
/// centre that most rays fit within `tau` (the least `Σ min(e², τ²)`), from
/// [`CONSENSUS_SAMPLES`] samples of a generator with a fixed seed (the same rays give the
/// same start); `start` competes too. What a poor start cannot find by descent: the outline
/// half of whose edge points are a stand's or a shadow's.
fn consensus_start(q: &[V3], r: f64, tau: f64, start: V3) -> Option<V3> {
    use rand::Rng;
    let cost = |c: &V3| -> Option<f64> {
        let (res, _) = cone_residuals(q, c, r)?;
        Some(res.iter().map(|e| (e * e).min(tau * tau)).sum())
    };
    let mut best = (cost(&start).unwrap_or(f64::INFINITY), start);
    let mut g = pingcal_geometry::consensus::rng(0x5EED_C0DE);
    let n = q.len();
    for _ in 0..CONSENSUS_SAMPLES {
        // three rays from the three thirds of the list (spread around the outline)
        let k = [0, 1, 2].map(|t| (t * n / 3 + g.random_range(0..n / 3)).min(n - 1));
        let Some(c) = cone_through([&q[k[0]], &q[k[1]], &q[k[2]]], r) else {
            continue;
        };
        if let Some(v) = cost(&c).filter(|v| *v < best.0) {
            best = (v, c);
        }
    }
    best.0.is_finite().then_some(best.1)
}

/// How far a real ball's outline departs from a sphere's, as a fraction of its radius: the
/// robust fit's core is at least this wide ([`robust_fit`]).
pub const SHAPE_TOLERANCE: f64 = 0.005;

/// The robust fit: the consensus of minimal samples ([`consensus_start`], threshold
/// `τ = 3 floor +` [`SHAPE_TOLERANCE`] × the cone's half-angle), then iteratively reweighted least squares with Tukey's biweight
/// (c = 4.685 σ) whose scale σ is grown from the consensus' core: 1.4826 × the median
/// absolute residual of the rays within `max(3σ, τ)` of the cone (at least `floor / 3`),
/// until σ and the centre settle (at most 30 rounds). A scale from all the residuals would
/// be the outliers' once they are more than half (a stand and a shadow hiding the lower
/// half of the outline, a partly visible one); this one is the outline's, be its spread a
/// tenth of a pixel or, on a real ball that is not quite a sphere, more. Inliers: within
/// `max(3σ, floor)`. `floor`: the smallest residual scale worth telling apart (radians,
/// e.g. a quarter pixel's angle). The rays are taken in their order around the outline.
pub fn robust_fit(q: &[V3], c0: V3, r: f64, floor: f64) -> Option<RobustCone> {
    if q.len() < 6 {
        return None;
    }
    // the core's least width: three floors, and half a per cent of the outline's radius (a
    // real ball's outline departs from a sphere's by about that)
    let tau = 3.0 * floor + SHAPE_TOLERANCE * (r / c0.norm().max(r * 1.0001)).asin();
    let mut c = consensus_start(q, r, tau, c0).unwrap_or(c0);
    let mut sigma = floor;
    let mut w = vec![1.0; q.len()];
    let scale = |res: &[f64], sigma: f64| -> Option<f64> {
        let lim = (3.0 * sigma).max(tau);
        let mut core: Vec<f64> = res.iter().map(|e| e.abs()).filter(|e| *e <= lim).collect();
        if core.len() < 6 {
            return None;
        }
        let mid = core.len() / 2;
        let med = *core.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
        Some((1.4826 * med).max(floor / 3.0))
    };
    for _ in 0..30 {
        let (res, _) = cone_residuals(q, &c, r)?;
        let s = scale(&res, sigma)?;
        let k = 4.685 * s;
        for (wi, e) in w.iter_mut().zip(&res) {
            let u = e / k;
            *wi = if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            };
        }
        let (cn, _) = gauss_newton(q, Some(&w), c, r)?;
        let settled = (s - sigma).abs() < 1e-3 * s && (cn - c).norm() < 1e-7 * cn.norm();
        (c, sigma) = (cn, s);
        if settled {
            break;
        }
    }
    let (res, _) = cone_residuals(q, &c, r)?;
    let sigma = scale(&res, sigma)?;
    let lim = (3.0 * sigma).max(floor);
    let inlier = res.iter().map(|e| e.abs() <= lim).collect();
    Some(RobustCone {
        centre: c,
        residuals: res,
        inlier,
        sigma,
    })
}

/// The variance inflation of a mean of the correlated series `res` (ordered around the
/// outline, cyclic): `1 + 2 Σ ρ_l` over lags 1–4, at least 1.
pub fn correlation_inflation(res: &[f64]) -> f64 {
    let n = res.len();
    if n < 16 {
        return 1.0;
    }
    let m = res.iter().sum::<f64>() / n as f64;
    let c0 = res.iter().map(|e| (e - m).powi(2)).sum::<f64>();
    if !(c0 > 0.0) {
        return 1.0;
    }
    let rho: f64 = (1..=4)
        .map(|l| {
            (0..n)
                .map(|i| (res[i] - m) * (res[(i + l) % n] - m))
                .sum::<f64>()
                / c0
        })
        .sum();
    (1.0 + 2.0 * rho).max(1.0)
}

/// The unit rays of the silhouette cone of a sphere of radius `r` at `c`, at `n` angles
/// evenly around it (the first in the plane of ĉ and the frame's third axis, or its first
/// when ĉ is along the third), and the cone's axis and half-angle.
pub fn cone_rays(c: &V3, r: f64, n: usize) -> Option<Vec<V3>> {
    let d = c.norm();
    if !(d > r) {
        return None;
    }
    let u = c / d;
    let helper = if u.z.abs() < 0.9 { V3::z() } else { V3::x() };
    let e1 = u.cross(&helper).normalize();
    let e2 = u.cross(&e1);
    let alpha = (r / d).asin();
    Some(
        (0..n)
            .map(|k| {
                let phi = std::f64::consts::TAU * k as f64 / n as f64;
                u * alpha.cos() + (e1 * phi.cos() + e2 * phi.sin()) * alpha.sin()
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_jacobian_is_the_central_difference_of_the_residuals() {
        let c = V3::new(300.0, 2500.0, -400.0);
        let q: Vec<V3> = (0..7)
            .map(|k| V3::new(0.1 + 0.02 * k as f64, 1.0, -0.15 + 0.01 * k as f64).normalize())
            .collect();
        let (_, jac) = cone_residuals(&q, &c, 250.0).unwrap();
        for axis in 0..3 {
            let h = 1e-3;
            let mut cp = c;
            let mut cm = c;
            cp[axis] += h;
            cm[axis] -= h;
            let (rp, _) = cone_residuals(&q, &cp, 250.0).unwrap();
            let (rm, _) = cone_residuals(&q, &cm, 250.0).unwrap();
            for i in 0..q.len() {
                let num = (rp[i] - rm[i]) / (2.0 * h);
                assert!(
                    (num - jac[i][axis]).abs() < 1e-6 * jac[i].norm().max(1e-9),
                    "ray {i} axis {axis}: {num} vs {}",
                    jac[i][axis]
                );
            }
        }
    }

    #[test]
    fn the_robust_fit_ignores_a_covered_part_of_the_outline() {
        let c = V3::new(-400.0, 3000.0, 250.0);
        let r = 300.0;
        let mut q = cone_rays(&c, r, 200).unwrap();
        // a quarter of the outline replaced by a stand's edge: rays 3° inside
        let u = c.normalize();
        for qi in q.iter_mut().take(50) {
            let axis = u.cross(qi).normalize();
            *qi = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), -0.05)
                * *qi;
        }
        let fit = robust_fit(&q, c * 1.1 + V3::new(40.0, 0.0, 30.0), r, 1e-5).unwrap();
        assert!((fit.centre - c).norm() < 1e-3, "{}", fit.centre);
        assert_eq!(fit.inlier.iter().filter(|&&b| !b).count(), 50);
        // the plain least squares is pulled away
        let (ls, _, _) = fit_cone(&q, c, r).unwrap();
        assert!((ls - c).norm() > 10.0);
    }

    #[test]
    fn three_rays_on_a_cone_give_its_sphere() {
        let c = V3::new(-700.0, 4000.0, 900.0);
        let q = cone_rays(&c, 300.0, 7).unwrap();
        let got = cone_through([&q[0], &q[2], &q[5]], 300.0).unwrap();
        assert!((got - c).norm() < 1e-6 * c.norm(), "{got}");
        assert!(cone_through([&q[0], &q[0], &q[5]], 300.0).is_none());
    }

    #[test]
    fn correlated_residuals_inflate_the_variance() {
        // xorshift64: independent uniform values
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let white: Vec<f64> = (0..400)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        assert!(correlation_inflation(&white) < 1.3);
        let smooth: Vec<f64> = (0..400)
            .map(|i| (i as f64 * 0.2).sin() + 0.1 * white[i])
            .collect();
        assert!(correlation_inflation(&smooth) > 5.0);
    }
}
