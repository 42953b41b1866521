//! One camera model fitted to another over an image: what an export to a format that
//! cannot hold a model does, with the loss it states.
//!
//! Each pixel `u` of a grid over the image has its ray `q = unproject_S(u)` through the
//! source model S. The target model T's parameters θ (those marked free; the rest held)
//! minimise `Σ ‖project_T(θ, q) − u‖²` over the grid, by Levenberg–Marquardt on T's own
//! analytic Jacobian ∂(u, v)/∂θ ([`CameraModel::project`]). The loss is the largest and
//! the RMS distance `‖project_T(θ, q) − u‖` over the grid: how far T puts, in pixels, the
//! rays that S puts on the grid's pixels; 0 for an exact conversion.

use super::CameraModel;
use nalgebra::{DMatrix, DVector, Vector2, Vector3};

/// The loss grid's largest spacing between pixels, px.
pub const GRID_STEP_PX: f64 = 8.0;

/// The loss grid of a `width × height` image: `n_u × n_v` pixels evenly spaced from 0 to
/// W − 1 and from 0 to H − 1 (the corners and edges included), `n = ⌈(W − 1)/8⌉ + 1`, so
/// no two neighbours are more than [`GRID_STEP_PX`] apart.
pub fn loss_grid(width: u32, height: u32) -> (usize, usize) {
    let n = |len: u32| (f64::from(len.max(1) - 1) / GRID_STEP_PX).ceil() as usize + 1;
    (n(width), n(height))
}

/// The pixels of [`loss_grid`], row by row (v outer, u inner).
pub fn grid_pixels(width: u32, height: u32) -> Vec<Vector2<f64>> {
    let (nu, nv) = loss_grid(width, height);
    let at = |i: usize, n: usize, len: u32| {
        if n < 2 {
            0.0
        } else {
            i as f64 * f64::from(len - 1) / (n - 1) as f64
        }
    };
    (0..nv)
        .flat_map(|j| (0..nu).map(move |i| Vector2::new(at(i, nu, width), at(j, nv, height))))
        .collect()
}

/// How far a model puts the grid's rays from their pixels, px.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loss {
    /// The largest distance.
    pub max_px: f64,
    /// The root mean square distance.
    pub rms_px: f64,
}

/// The rays of a grid of pixels through a model: the pixels that have one, and the rays.
#[derive(Clone, Debug, Default)]
pub struct GridRays {
    /// The pixels that have a ray.
    pub pixels: Vec<Vector2<f64>>,
    /// Their unit rays (camera frame).
    pub rays: Vec<Vector3<f64>>,
    /// Pixels of the grid without a ray (beyond the model's field, or where its
    /// distortion cannot be inverted).
    pub missed: usize,
}

impl GridRays {
    /// The rays of `pixels` through `model` at `params`.
    pub fn of(model: &dyn CameraModel, params: &[f64], pixels: &[Vector2<f64>]) -> Self {
        let mut out = GridRays::default();
        for uv in pixels {
            match model.unproject(params, uv) {
                Some(q) => {
                    out.pixels.push(*uv);
                    out.rays.push(q);
                }
                None => out.missed += 1,
            }
        }
        out
    }

    /// The loss of `model` at `params` over these rays ([`Loss`]); a ray it cannot project
    /// counts as infinitely far.
    pub fn loss(&self, model: &dyn CameraModel, params: &[f64]) -> Loss {
        let (mut max, mut sum) = (0.0f64, 0.0);
        for (uv, q) in self.pixels.iter().zip(&self.rays) {
            let e = match model.project(params, q, None, None) {
                Some(p) => (p - uv).norm(),
                None => f64::INFINITY,
            };
            max = max.max(e);
            sum += e * e;
        }
        Loss {
            max_px: max,
            rms_px: (sum / self.pixels.len().max(1) as f64).sqrt(),
        }
    }
}

/// `target`'s parameters, from `start` with those marked `free` adjusted, that put `grid`'s
/// rays nearest their pixels in the least-squares sense (see the module doc), with their
/// loss. `None` when the grid is empty, a ray does not project at the start, or the
/// normal equations are singular (a free parameter the grid does not determine).
pub fn refit(
    grid: &GridRays,
    target: &dyn CameraModel,
    start: &[f64],
    free: &[bool],
) -> Option<(Vec<f64>, Loss)> {
    let n = target.num_params();
    let cols: Vec<usize> = (0..n).filter(|&k| free[k]).collect();
    if grid.pixels.is_empty() || start.len() != n || free.len() != n {
        return None;
    }
    let mut theta = start.to_vec();
    if cols.is_empty() {
        let loss = grid.loss(target, &theta);
        return loss.max_px.is_finite().then_some((theta, loss));
    }
    let cost = |p: &[f64]| -> Option<f64> {
        let mut s = 0.0;
        for (uv, q) in grid.pixels.iter().zip(&grid.rays) {
            s += (target.project(p, q, None, None)? - uv).norm_squared();
        }
        Some(s)
    };
    let mut c0 = cost(&theta)?;
    let mut lambda = 1e-6;
    let mut jac = vec![0.0; 2 * n];
    for _ in 0..100 {
        let m = cols.len();
        let mut jtj = DMatrix::<f64>::zeros(m, m);
        let mut jtr = DVector::<f64>::zeros(m);
        for (uv, q) in grid.pixels.iter().zip(&grid.rays) {
            let p = target.project(&theta, q, None, Some(&mut jac))?;
            let r = p - uv;
            for (a, &ka) in cols.iter().enumerate() {
                let (ja_u, ja_v) = (jac[ka], jac[n + ka]);
                jtr[a] += ja_u * r.x + ja_v * r.y;
                for (b, &kb) in cols.iter().enumerate().skip(a) {
                    jtj[(a, b)] += ja_u * jac[kb] + ja_v * jac[n + kb];
                }
            }
        }
        for a in 0..m {
            for b in 0..a {
                jtj[(a, b)] = jtj[(b, a)];
            }
        }
        let mut improved = false;
        for _ in 0..20 {
            let mut damped = jtj.clone();
            for a in 0..m {
                damped[(a, a)] += lambda * jtj[(a, a)].max(1e-300);
            }
            let step = damped.cholesky()?.solve(&(-&jtr));
            let mut trial = theta.clone();
            for (a, &k) in cols.iter().enumerate() {
                trial[k] += step[a];
            }
            match cost(&trial) {
                Some(c) if c <= c0 => {
                    let small = step
                        .iter()
                        .zip(&cols)
                        .all(|(s, &k)| s.abs() <= 1e-12 * theta[k].abs().max(1e-9));
                    let flat = c0 - c <= 1e-15 * c0.max(1e-300);
                    theta = trial;
                    c0 = c;
                    lambda = (lambda * 0.3).max(1e-12);
                    improved = !(small || flat);
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            break;
        }
    }
    let loss = grid.loss(target, &theta);
    loss.max_px.is_finite().then_some((theta, loss))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DoubleSphereCamera, FisheyeCamera, OpenCvCamera};

    fn grid(w: u32, h: u32, n: usize) -> Vec<Vector2<f64>> {
        (0..=n)
            .flat_map(|j| {
                (0..=n).map(move |i| {
                    Vector2::new(
                        (w - 1) as f64 * i as f64 / n as f64,
                        (h - 1) as f64 * j as f64 / n as f64,
                    )
                })
            })
            .collect()
    }

    #[test]
    fn a_model_refitted_to_itself_from_elsewhere_is_exact() {
        let truth = [360.0, 361.0, 641.0, 399.0, 0.02, -0.005, 0.001, -2e-4];
        let g = GridRays::of(&FisheyeCamera, &truth, &grid(1280, 800, 30));
        assert_eq!(g.missed, 0);
        let start = [340.0, 340.0, 639.5, 399.5, 0.0, 0.0, 0.0, 0.0];
        let (p, loss) = refit(&g, &FisheyeCamera, &start, &[true; 8]).unwrap();
        assert!(loss.max_px < 1e-6, "{loss:?}");
        for (a, b) in p.iter().zip(&truth) {
            assert!((a - b).abs() < 1e-6 * b.abs().max(1e-3), "{p:?}");
        }
    }

    /// A double sphere has no exact Kannala–Brandt form: the refit states a loss, smaller
    /// than that of the same focal length with no distortion.
    #[test]
    fn a_model_that_cannot_hold_another_states_its_loss() {
        let ds = [300.0, 300.5, 641.0, 399.0, -0.2, 0.58];
        let g = GridRays::of(&DoubleSphereCamera, &ds, &grid(1280, 800, 30));
        let start = [ds[0] / 0.8, ds[1] / 0.8, ds[2], ds[3], 0.0, 0.0, 0.0, 0.0];
        let plain = g.loss(&FisheyeCamera, &start);
        let (_, loss) = refit(&g, &FisheyeCamera, &start, &[true; 8]).unwrap();
        assert!(
            loss.max_px > 1e-6 && loss.max_px < 0.2 * plain.max_px,
            "{loss:?} {plain:?}"
        );
        // held parameters stay where they are
        let mut free = [true; 8];
        free[2] = false;
        let (p, _) = refit(&g, &FisheyeCamera, &start, &free).unwrap();
        assert_eq!(p[2], start[2]);
    }

    #[test]
    fn a_pinhole_refit_of_a_wide_lens_does_not_fail() {
        // 16 OpenCV parameters, only fx fy cx cy k1 k2 p1 p2 free (Kalibr's radtan)
        let truth = [
            420.0, 421.0, 641.0, 399.0, 0.05, 0.0, 1e-4, -1.2e-4, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0,
            0.0, 0.0,
        ];
        let g = GridRays::of(&OpenCvCamera, &truth, &grid(1280, 800, 20));
        let mut start = truth;
        start[9] = 0.0;
        let free: Vec<bool> = (0..16).map(|k| k < 8).collect();
        let (_, loss) = refit(&g, &OpenCvCamera, &start, &free).unwrap();
        assert!(loss.max_px.is_finite() && loss.rms_px <= loss.max_px);
    }
}
