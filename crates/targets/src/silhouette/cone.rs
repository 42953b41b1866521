//! The centre of a sphere of known radius from rays through its outline: every ray on the
//! silhouette cone makes the angle `α = asin(r/|c|)` with the direction to the centre `c`.
//!
//! The residual of unit ray `q` is `acos(q·ĉ) − asin(r/|c|)` (radians), its derivatives by
//! the three coordinates of `c` analytic ([`cone_residuals`]). [`fit_cone`] is Gauss–Newton
//! from a start (`pingcal_geometry::least_squares`, steps never through the camera), with
//! the covariance `s² (JᵀJ)⁻¹` from the residuals' mean square; [`robust_fit`] is the same
//! by iteratively reweighted least squares with Tukey's biweight on a scale from
//! the residuals' median absolute deviation, for outlines partly covered or crossed by other
//! edges, and says which rays are inliers. Rays are in any right-handed camera frame; the
//! centre comes out in that frame, in the radius' unit.

use nalgebra::{Matrix3, Vector3, U3};
use pingcal_geometry::least_squares::{minimize, Normal, Objective, Options, Strategy};

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

/// The cone's least-squares problem: rays `q` with weights `w` (`None`: all 1), radius `r`.
struct Cone<'a> {
    q: &'a [V3],
    w: Option<&'a [f64]>,
    r: f64,
}

impl Objective<U3> for Cone<'_> {
    fn normal(&mut self, c: &V3) -> Option<Normal<U3>> {
        let (res, jac) = cone_residuals(self.q, c, self.r)?;
        let mut n = Matrix3::zeros();
        let mut g = V3::zeros();
        let mut cost = 0.0;
        for (i, (e, j)) in res.iter().zip(&jac).enumerate() {
            let wi = self.w.map_or(1.0, |w| w[i]);
            n += j * j.transpose() * wi;
            g += j * (*e * wi);
            cost += wi * e * e;
        }
        Some(Normal {
            matrix: n,
            gradient: g,
            cost,
        })
    }

    /// Never through the camera: at most half way towards it per step.
    fn limit_step(&self, c: &V3, step: V3) -> V3 {
        let lim = 0.5 * (c.norm() - self.r);
        if step.norm() > lim {
            step * (lim / step.norm())
        } else {
            step
        }
    }
}

/// Weighted Gauss–Newton of the centre from `c0` (weights `w`, `None`: all 1; at most 30
/// steps, until one is under 1e-10 of the distance).
fn gauss_newton(q: &[V3], w: Option<&[f64]>, c0: V3, r: f64) -> Option<V3> {
    let options = Options {
        strategy: Strategy::GaussNewton,
        max_iterations: 30,
        small_step: |s| s.length < 1e-10 * s.to,
        cost_tolerance: 0.0,
    };
    Some(minimize(c0, &options, &mut Cone { q, w, r })?.x)
}

/// Gauss–Newton fit of the centre to the rays; returns the centre, its covariance
/// `s²(JᵀJ)⁻¹` with s² the residuals' mean square over n − 3, and s (radians).
pub fn fit_cone(q: &[V3], c0: V3, r: f64) -> Option<(V3, Matrix3<f64>, f64)> {
    let c = gauss_newton(q, None, c0, r)?;
    let at = Cone { q, w: None, r }.normal(&c)?;
    let dof = q.len().checked_sub(3).filter(|&d| d > 0)?;
    let s2 = at.cost / dof as f64;
    let cov = at.matrix.try_inverse()? * s2;
    Some((c, cov, s2.sqrt()))
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

/// The median of `v` (which it reorders).
fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
}

/// Per place the candidate ray nearest the cone of (`c`, `r`) (the smallest absolute
/// residual; the first of equals) and its index; a place of one candidate is that one.
fn nearest(places: &[Vec<V3>], c: &V3, r: f64) -> (Vec<V3>, Vec<usize>) {
    let d = c.norm();
    let u = c / d;
    let alpha = (r / d).clamp(-1.0, 1.0).asin();
    let off = |q: &V3| (q.dot(&u).clamp(-1.0, 1.0).acos() - alpha).abs();
    places
        .iter()
        .map(|cands| {
            let mut k = 0;
            for (j, q) in cands.iter().enumerate().skip(1) {
                if off(q) < off(&cands[k]) {
                    k = j;
                }
            }
            (cands[k], k)
        })
        .unzip()
}

/// Least trimmed squares by concentration steps (Rousseeuw & Van Driessen): from `c0`, the
/// least squares of the half of the places with the smallest residuals (each place's
/// candidate nearest the cone), repeated until that half stops changing (at most 20 times).
/// Half the outline may be wrong (a stand, a shadow, an edge behind), however far off, and
/// the start may be poor.
fn trimmed(places: &[Vec<V3>], c0: V3, r: f64) -> Option<V3> {
    let h = places.len().div_ceil(2).max(6);
    let mut c = gauss_newton(&nearest(places, &c0, r).0, None, c0, r)?;
    let mut last: Vec<usize> = Vec::new();
    for _ in 0..20 {
        let (q, _) = nearest(places, &c, r);
        let (res, _) = cone_residuals(&q, &c, r)?;
        let mut idx: Vec<usize> = (0..q.len()).collect();
        idx.sort_by(|&a, &b| res[a].abs().total_cmp(&res[b].abs()).then(a.cmp(&b)));
        idx.truncate(h);
        idx.sort_unstable();
        if idx == last {
            break;
        }
        let sub: Vec<V3> = idx.iter().map(|&i| q[i]).collect();
        c = gauss_newton(&sub, None, c, r)?;
        last = idx;
    }
    Some(c)
}

/// The robust fit: least trimmed squares (concentration steps) from `c0`, then iteratively reweighted least squares with
/// Tukey's biweight (c = 4.685 σ, σ = 1.4826 · the median absolute residual, at least
/// `floor / 3`) until σ settles; inliers within `max(3σ, floor)`. `floor`: the smallest
/// residual scale worth telling apart (radians, e.g. a quarter pixel's angle).
pub fn robust_fit(q: &[V3], c0: V3, r: f64, floor: f64) -> Option<RobustCone> {
    let places: Vec<Vec<V3>> = q.iter().map(|x| vec![*x]).collect();
    robust_fit_choosing(&places, c0, r, floor).map(|(f, _)| f)
}

/// [`robust_fit`] with several candidate rays per place of the outline (the edges found
/// along one normal, each non-empty): in every step each place takes its candidate nearest
/// the current cone, and the estimator weighs those (the multiple-hypothesis robust
/// estimator of Vacchetti, Lepetit & Fua 2004). So the outline's own edge is used wherever
/// it is among the candidates, even where a stronger edge of the background lies within the
/// search. Returns the fit (residuals and inliers per place) and each place's candidate.
pub fn robust_fit_choosing(
    places: &[Vec<V3>],
    c0: V3,
    r: f64,
    floor: f64,
) -> Option<(RobustCone, Vec<usize>)> {
    if places.len() < 6 || places.iter().any(|p| p.is_empty()) {
        return None;
    }
    let mut c = trimmed(places, c0, r)?;
    let mut sigma = f64::INFINITY;
    let mut w = vec![1.0; places.len()];
    for _ in 0..12 {
        let (q, _) = nearest(places, &c, r);
        let (res, _) = cone_residuals(&q, &c, r)?;
        let mut abs: Vec<f64> = res.iter().map(|e| e.abs()).collect();
        let s = (1.4826 * median(&mut abs)).max(floor / 3.0);
        let k = 4.685 * s;
        for (wi, e) in w.iter_mut().zip(&res) {
            let u = e / k;
            *wi = if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            };
        }
        if w.iter().filter(|&&x| x > 0.0).count() < 6 {
            return None;
        }
        let cn = gauss_newton(&q, Some(&w), c, r)?;
        let moved = (cn - c).norm();
        c = cn;
        let settled = (s - sigma).abs() < 0.01 * s && moved < 1e-7 * c.norm();
        sigma = s;
        if settled {
            break;
        }
    }
    let (q, chosen) = nearest(places, &c, r);
    let (res, _) = cone_residuals(&q, &c, r)?;
    let mut abs: Vec<f64> = res.iter().map(|e| e.abs()).collect();
    let sigma = (1.4826 * median(&mut abs)).max(floor / 3.0);
    let lim = (3.0 * sigma).max(floor);
    let inlier = res.iter().map(|e| e.abs() <= lim).collect();
    Some((
        RobustCone {
            centre: c,
            residuals: res,
            inlier,
            sigma,
        },
        chosen,
    ))
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
