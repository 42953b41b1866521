//! Residuals and Jacobians of the image observations at the current estimate.
//!
//! Residuals are whitened (divided by the observation's σ) and robustified (scaled by
//! √ρ′), so that the solver sees an ordinary least-squares problem ½ Σ |r|² whose value at
//! the current estimate is the true robust cost ½ Σ ρ(|r/σ|²).

use super::layout::Layout;
use crate::problem::Problem;
use nalgebra::{Matrix2x3, Vector2, Vector3};
use pingcal_geometry::skew;
use rayon::prelude::*;

/// The linearization of all observations.
pub(crate) struct Linearization {
    /// Whitened, robustified residual per observation.
    pub r: Vec<Vector2<f64>>,
    /// Camera-side Jacobian per observation: its two rows, each `ncols` long.
    pub jc: Vec<f64>,
    /// Point Jacobian per observation.
    pub jp: Vec<Matrix2x3<f64>>,
    /// W = J_cᵀ J_p per observation (ncols × 3), stored as its three columns, each
    /// `ncols` long.
    pub w: Vec<f64>,
    /// Per distance: whitened residual and its Jacobian with respect to the first point
    /// (the second point's is its negative).
    pub dist: Vec<(f64, Vector3<f64>)>,
    /// ½ Σ ρ + ½ Σ distance² + ½ Σ control².
    pub cost: f64,
}

impl Linearization {
    pub fn new(layout: &Layout) -> Self {
        let n = layout.obs_ncols.len();
        Self {
            r: vec![Vector2::zeros(); n],
            jc: vec![0.0; layout.jc_len],
            jp: vec![Matrix2x3::zeros(); n],
            w: vec![0.0; layout.w_len],
            dist: Vec::new(),
            cost: 0.0,
        }
    }
}

/// Splits `buf` into consecutive mutable pieces starting at `offsets` (increasing), the
/// last ending at `buf.len()`.
pub(crate) fn split_at_offsets<'a, T>(mut buf: &'a mut [T], offsets: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(offsets.len());
    let mut base = 0;
    for k in 0..offsets.len() {
        let end = if k + 1 < offsets.len() {
            offsets[k + 1]
        } else {
            base + buf.len()
        };
        let (head, tail) = buf.split_at_mut(end - base);
        out.push(head);
        buf = tail;
        base = end;
    }
    out
}

/// The robust cost ½ Σ ρ(|r/σ|²) at the current estimate, or the index of the first
/// observation that does not project.
pub(crate) fn cost(problem: &Problem) -> Result<f64, usize> {
    problem
        .observations
        .par_iter()
        .enumerate()
        .with_min_len(256)
        .map(|(i, o)| {
            let r = problem.residual(o).ok_or(i)? / o.sigma;
            Ok::<f64, usize>(0.5 * problem.loss.evaluate(r.norm_squared()).0)
        })
        .try_reduce(|| 0.0, |a, b| Ok(a + b))
        .map(|c| c + constraint_cost(problem))
}

/// ½ Σ of the whitened distance and control-point residuals.
pub(crate) fn constraint_cost(problem: &Problem) -> f64 {
    let mut c = 0.0;
    for d in &problem.distances {
        let l = (problem.points[d.a].position - problem.points[d.b].position).norm();
        c += 0.5 * ((l - d.value) / d.sigma).powi(2);
    }
    for pr in &problem.point_priors {
        let r = (problem.points[pr.point].position - pr.position).component_div(&pr.sigma);
        c += 0.5 * r.norm_squared();
    }
    c
}

/// Fills `lin` at the current estimate. Returns the (problem) index of an observation that
/// does not project, if any.
pub(crate) fn linearize(
    problem: &Problem,
    layout: &Layout,
    lin: &mut Linearization,
) -> Result<(), usize> {
    let jc_parts = split_at_offsets(&mut lin.jc, &layout.obs_jc_offset);
    let w_parts = split_at_offsets(&mut lin.w, &layout.obs_w_offset);
    let cost = lin
        .r
        .par_iter_mut()
        .zip(lin.jp.par_iter_mut())
        .zip(jc_parts.into_par_iter().zip(w_parts.into_par_iter()))
        .enumerate()
        .with_min_len(256)
        .map(|(i, ((r, jp), (jc, w)))| {
            let o = &problem.observations[layout.obs_order[i] as usize];
            let im = &problem.images[o.image];
            let cam = &problem.cameras[im.camera];
            let x = &problem.points[o.point].position;
            let rx = im.camera_from_object.rotation * x;
            let xc = rx + im.camera_from_object.translation;
            let mut dxc = Matrix2x3::zeros();
            let n = cam.params.len();
            // Intrinsic Jacobian on the stack for the usual models (≤ 16 parameters).
            let mut small = [0.0f64; 32];
            let mut large = Vec::new();
            let ji = if n <= 16 {
                &mut small[..2 * n]
            } else {
                large.resize(2 * n, 0.0);
                &mut large[..]
            };
            let uv = cam
                .model
                .project(&cam.params, &xc, Some(&mut dxc), Some(ji))
                .ok_or(layout.obs_order[i] as usize)?;
            let res = (uv - o.uv) / o.sigma;
            let (rho, rho1) = problem.loss.evaluate(res.norm_squared());
            let scale = rho1.sqrt() / o.sigma;
            *r = res * rho1.sqrt();
            let dxc = dxc * scale;
            *jp = dxc * im.camera_from_object.rotation;
            let nc = jc.len() / 2;
            let (j0, j1) = jc.split_at_mut(nc);
            let mut col = 0;
            if let Some((r, base)) = layout.image_rig[o.image] {
                // xc = R_r (R_b X + t_b) + t_r with left updates of both poses:
                // ∂xc/∂δω_b = −R_r [R_b X]×, ∂xc/∂δt_b = R_r; ∂xc/∂δω_r = −[xc − t_r]×, ∂xc/∂δt_r = I.
                let rig = &problem.rigs[r].member_from_base;
                let b = &problem.images[base].camera_from_object;
                if layout.image_slot[base].is_some() {
                    let jr = dxc * rig.rotation;
                    let jw = -(jr * skew(&(b.rotation * x)));
                    for k in 0..3 {
                        j0[k] = jw[(0, k)];
                        j1[k] = jw[(1, k)];
                        j0[3 + k] = jr[(0, k)];
                        j1[3 + k] = jr[(1, k)];
                    }
                    col = 6;
                }
                if layout.rig_slot[r].is_some() {
                    let jw = -(dxc * skew(&(xc - rig.translation)));
                    for k in 0..3 {
                        j0[col + k] = jw[(0, k)];
                        j1[col + k] = jw[(1, k)];
                        j0[col + 3 + k] = dxc[(0, k)];
                        j1[col + 3 + k] = dxc[(1, k)];
                    }
                    col += 6;
                }
            } else if layout.image_slot[o.image].is_some() {
                // ∂xc/∂δω = −[R X]×, ∂xc/∂δt = I.
                let jw = -(dxc * skew(&rx));
                for k in 0..3 {
                    j0[k] = jw[(0, k)];
                    j1[k] = jw[(1, k)];
                    j0[3 + k] = dxc[(0, k)];
                    j1[3 + k] = dxc[(1, k)];
                }
                col = 6;
            }
            if layout.camera_slot[im.camera].is_some() {
                for &k in &layout.camera_free[im.camera] {
                    j0[col] = ji[k] * scale;
                    j1[col] = ji[n + k] * scale;
                    col += 1;
                }
            }
            if layout.point_slot[o.point].is_some() {
                for k in 0..3 {
                    j0[col + k] = jp[(0, k)];
                    j1[col + k] = jp[(1, k)];
                }
            }
            for m in 0..3 {
                let (a, b) = (jp[(0, m)], jp[(1, m)]);
                for (wk, (x, y)) in w[m * nc..(m + 1) * nc]
                    .iter_mut()
                    .zip(j0.iter().zip(j1.iter()))
                {
                    *wk = x * a + y * b;
                }
            }
            Ok::<f64, usize>(0.5 * rho)
        })
        .try_reduce(|| 0.0, |a, b| Ok(a + b))?;
    lin.dist.clear();
    for d in &problem.distances {
        let v = problem.points[d.a].position - problem.points[d.b].position;
        let l = v.norm();
        let u = if l > 0.0 { v / l } else { Vector3::zeros() };
        lin.dist.push(((l - d.value) / d.sigma, u / d.sigma));
    }
    lin.cost = cost + constraint_cost(problem);
    Ok(())
}
