//! Residuals and Jacobians of the image observations and the constraints at the current
//! estimate.
//!
//! Image residuals are whitened (divided by the observation's σ) and robustified (scaled
//! by √ρ′), so that the solver sees an ordinary least-squares problem ½ Σ |r|² whose value
//! at the current estimate is the true robust cost ½ Σ ρ(|r/σ|²). The constraints
//! ([`Problem::constraints`]) whiten their own residuals; the solver divides them by their
//! σ factor.

use super::layout::{BlockCols, Layout};
use crate::keys::{ImageKey, ParameterKey, PointKey};
use crate::problem::{Problem, ProblemError};
use crate::residual::{Block, Residual, Value};
use nalgebra::{DMatrix, Matrix2x3, Vector2};
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
    /// Per constraint, in the order of [`Problem::constraints`].
    pub constraints: Vec<ConstraintLin>,
    /// ½ Σ ρ + ½ Σ |constraint|².
    pub cost: f64,
}

/// One constraint's whitened residual and its Jacobian restricted to the free columns of
/// each of its blocks (`dim × cols.len()`, in the order of the layout's
/// [`BlockCols`]).
pub(crate) struct ConstraintLin {
    pub r: Vec<f64>,
    pub j: Vec<DMatrix<f64>>,
}

impl ConstraintLin {
    /// J δ for the update `delta_of(block) → the block's free columns' step`.
    pub fn apply(
        &self,
        cols: &[BlockCols],
        mut delta_of: impl FnMut(&BlockCols) -> Vec<f64>,
    ) -> Vec<f64> {
        let mut out = vec![0.0; self.r.len()];
        for (j, bc) in self.j.iter().zip(cols) {
            if bc.cols.is_empty() {
                continue;
            }
            let d = delta_of(bc);
            for (row, o) in out.iter_mut().enumerate() {
                *o += (0..d.len()).map(|c| j[(row, c)] * d[c]).sum::<f64>();
            }
        }
        out
    }
}

/// Where the problem is not defined at the current estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Undefined {
    /// An image observation (problem index) whose point does not project.
    Observation(usize),
    /// A constraint (index in [`Problem::constraints`]) whose residual is not defined.
    Constraint(usize),
}

impl Linearization {
    pub fn new(layout: &Layout) -> Self {
        let n = layout.obs_ncols.len();
        Self {
            r: vec![Vector2::zeros(); n],
            jc: vec![0.0; layout.jc_len],
            jp: vec![Matrix2x3::zeros(); n],
            w: vec![0.0; layout.w_len],
            constraints: Vec::new(),
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

impl Undefined {
    /// What it means, by name.
    pub fn describe(self, problem: &Problem) -> ProblemError {
        match self {
            Undefined::Observation(o) => {
                let ob = &problem.observations[o];
                ProblemError::NotProjectable {
                    point: problem.points[ob.point].name.clone(),
                    image: problem.images[ob.image].name.clone(),
                }
            }
            Undefined::Constraint(k) => {
                let group = (problem.constraints().nth(k)).map_or("?", |(r, _)| r.group());
                ProblemError::BadConstraint(format!(
                    "constraint {k} ({group}) is not defined at the current estimate"
                ))
            }
        }
    }
}

/// The robust cost ½ Σ ρ(|r/σ|²) + ½ Σ |constraint|² at the current estimate, or where it
/// is not defined.
pub(crate) fn cost(problem: &Problem) -> Result<f64, Undefined> {
    let terms = problem
        .observations
        .par_iter()
        .enumerate()
        .with_min_len(256)
        .map(|(i, o)| {
            let r = problem.residual(o).ok_or(Undefined::Observation(i))? / o.sigma;
            Ok::<f64, Undefined>(0.5 * problem.loss.evaluate(r.norm_squared()).0)
        });
    Ok(ordered_sum(terms)? + constraint_cost(problem)?)
}

/// Observations summed serially in each chunk of this many, then the chunks in turn.
const SUM_CHUNK: usize = 1024;

/// Σ of `terms` in an order fixed by the terms alone (chunks of [`SUM_CHUNK`], then the
/// chunks in turn), so the same problem gives the same bits on every run and with any
/// number of threads: rayon's `sum` and `reduce` add in the order its work stealing
/// happened to split the work. The first undefined term is returned.
fn ordered_sum(
    terms: impl IndexedParallelIterator<Item = Result<f64, Undefined>>,
) -> Result<f64, Undefined> {
    terms
        .fold_chunks(SUM_CHUNK, || Ok(0.0), |acc, t| Ok(acc? + t?))
        .collect::<Vec<_>>()
        .into_iter()
        .try_fold(0.0, |sum, chunk| Ok(sum + chunk?))
}

/// ½ Σ of the whitened constraint residuals (each divided by its σ factor).
pub(crate) fn constraint_cost(problem: &Problem) -> Result<f64, Undefined> {
    let mut c = 0.0;
    for (k, (residual, scale)) in problem.constraints().enumerate() {
        let r =
            constraint_residual(problem, residual, scale, None).ok_or(Undefined::Constraint(k))?;
        c += 0.5 * r.r.iter().map(|v| v * v).sum::<f64>();
    }
    Ok(c)
}

/// One constraint's whitened residual divided by `scale`, and with `cols` given its Jacobian
/// restricted to those free columns; None where it is not defined.
pub(crate) fn constraint_residual(
    problem: &Problem,
    residual: &dyn Residual,
    scale: f64,
    cols: Option<&[BlockCols]>,
) -> Option<ConstraintLin> {
    let blocks = residual.blocks();
    let values = block_values(problem, &blocks)?;
    let m = residual.dim();
    let mut r = vec![0.0; m];
    let Some(cols) = cols else {
        residual.evaluate(&values, &mut r, None).then_some(())?;
        r.iter_mut().for_each(|v| *v /= scale);
        return Some(ConstraintLin { r, j: Vec::new() });
    };
    let mut full: Vec<DMatrix<f64>> = (values.iter())
        .map(|v| DMatrix::zeros(m, v.tangent_dim()))
        .collect();
    residual
        .evaluate(&values, &mut r, Some(&mut full))
        .then_some(())?;
    for (f, b) in full.iter_mut().zip(&blocks) {
        if let crate::residual::Block::Pose(crate::keys::ImageKey(i)) = *b {
            if let Some(t) = centre_tangent(problem, i) {
                *f = &*f * DMatrix::from_column_slice(6, 6, t.as_slice());
            }
        }
    }
    r.iter_mut().for_each(|v| *v /= scale);
    let j = (full.iter().zip(cols))
        .map(|(f, bc)| DMatrix::from_fn(m, bc.cols.len(), |row, c| f[(row, bc.cols[c])] / scale))
        .collect();
    Some(ConstraintLin { r, j })
}

/// Writes the pose columns `(δω, δC_free)` of one observation (`jw` the 2 × 3 rotation part,
/// `jc` the 2 × 3 centre part of which only the columns `axes` are unknowns); returns the
/// number of columns written.
fn write_centred(
    j0: &mut [f64],
    j1: &mut [f64],
    jw: &nalgebra::Matrix2x3<f64>,
    jc: &nalgebra::Matrix2x3<f64>,
    axes: &[usize],
) -> usize {
    for k in 0..3 {
        j0[k] = jw[(0, k)];
        j1[k] = jw[(1, k)];
    }
    for (k, &a) in axes.iter().enumerate() {
        j0[3 + k] = jc[(0, a)];
        j1[3 + k] = jc[(1, a)];
    }
    3 + axes.len()
}

/// The 6 × 6 map `T` from the unknowns `(δω, δC)` of an image with held centre coordinates
/// to the left update `(δω, δt)` of its pose: `t = −R C` gives, to first order,
/// `δt = −[t]× δω − R δC`, so `T = [I 0; −[t]× −R]` and a Jacobian `J` with respect to
/// `(δω, δt)` is `J T` with respect to `(δω, δC)`. `None` for an image adjusted in
/// `(δω, δt)`.
pub(crate) fn centre_tangent(problem: &Problem, image: usize) -> Option<nalgebra::Matrix6<f64>> {
    let im = &problem.images[image];
    if !im.is_centre_held() {
        return None;
    }
    let p = &im.camera_from_object;
    let mut t = nalgebra::Matrix6::identity();
    t.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(-skew(&p.translation)));
    t.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-p.rotation));
    Some(t)
}

/// Fills `lin` at the current estimate, or says where the problem is not defined.
pub(crate) fn linearize(
    problem: &Problem,
    layout: &Layout,
    lin: &mut Linearization,
) -> Result<(), Undefined> {
    let jc_parts = split_at_offsets(&mut lin.jc, &layout.obs_jc_offset);
    let w_parts = split_at_offsets(&mut lin.w, &layout.obs_w_offset);
    let cost = lin
        .r
        .par_iter_mut()
        .zip(lin.jp.par_iter_mut())
        .zip(jc_parts.into_par_iter().zip(w_parts.into_par_iter()))
        .enumerate()
        .with_min_len(256)
        .map(|(i, ((r, jp), (jc, w)))| linearize_observation(problem, layout, i, r, jp, jc, w));
    let cost = ordered_sum(cost)?;
    lin.constraints = (problem
        .constraints()
        .zip(&layout.constraint_cols)
        .enumerate())
    .map(|(k, ((residual, scale), cols))| {
        constraint_residual(problem, residual, scale, Some(cols)).ok_or(Undefined::Constraint(k))
    })
    .collect::<Result<_, _>>()?;
    let constraints: f64 = (lin.constraints.iter())
        .map(|c| 0.5 * c.r.iter().map(|v| v * v).sum::<f64>())
        .sum();
    lin.cost = cost + constraints;
    Ok(())
}

/// A point projected into an image: the object point `x`, `rx` = R x, `xc` in the camera,
/// and ∂uv/∂xc scaled by the loss and σ.
struct Projected<'a> {
    x: &'a nalgebra::Vector3<f64>,
    rx: nalgebra::Vector3<f64>,
    xc: nalgebra::Vector3<f64>,
    dxc: Matrix2x3<f64>,
}

/// The `i`-th observation in the layout's order: its weighted residual `r`, its point
/// Jacobian `jp`, its reduced Jacobian rows `jc` and their products `w` with `jp`; its cost.
fn linearize_observation(
    problem: &Problem,
    layout: &Layout,
    i: usize,
    r: &mut Vector2<f64>,
    jp: &mut Matrix2x3<f64>,
    jc: &mut [f64],
    w: &mut [f64],
) -> Result<f64, Undefined> {
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
        .ok_or(Undefined::Observation(layout.obs_order[i] as usize))?;
    let res = (uv - o.uv) / o.sigma;
    let (rho, rho1) = problem.loss.evaluate(res.norm_squared());
    let scale = rho1.sqrt() / o.sigma;
    *r = res * rho1.sqrt();
    let dxc = dxc * scale;
    *jp = dxc * im.camera_from_object.rotation;
    let nc = jc.len() / 2;
    let (j0, j1) = jc.split_at_mut(nc);
    let projected = Projected { x, rx, xc, dxc };
    let mut col = pose_columns(problem, layout, o.image.0, &projected, j0, j1);
    if layout.camera_slot[im.camera.0].is_some() {
        for &k in &layout.camera_free[im.camera.0] {
            j0[col] = ji[k] * scale;
            j1[col] = ji[n + k] * scale;
            col += 1;
        }
    }
    // A point in the reduced system: the columns of its free coordinates only.
    for (k, &axis) in layout.point_axes[o.point.0].iter().enumerate() {
        j0[col + k] = jp[(0, axis)];
        j1[col + k] = jp[(1, axis)];
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
    Ok(0.5 * rho)
}

/// The columns of image `image`'s pose (or of its rig's base pose and the rig's
/// member-from-base) in the Jacobian rows `j0`, `j1`; the number of columns written.
fn pose_columns(
    problem: &Problem,
    layout: &Layout,
    image: usize,
    p: &Projected,
    j0: &mut [f64],
    j1: &mut [f64],
) -> usize {
    let (x, rx, xc, dxc) = (p.x, &p.rx, &p.xc, &p.dxc);
    let mut col = 0;
    if let Some((r, base)) = layout.image_rig[image] {
        // xc = R_r (R_b X + t_b) + t_r with left updates of both poses:
        // ∂xc/∂δω_b = −R_r [R_b X]×, ∂xc/∂δt_b = R_r; ∂xc/∂δω_r = −[xc − t_r]×, ∂xc/∂δt_r = I.
        let rig = &problem.rigs[r].member_from_base;
        let b = &problem.images[base].camera_from_object;
        if layout.image_slot[base].is_some() {
            let jr = dxc * rig.rotation;
            match &layout.image_centre_axes[base] {
                None => {
                    let jw = -(jr * skew(&(b.rotation * x)));
                    for k in 0..3 {
                        j0[k] = jw[(0, k)];
                        j1[k] = jw[(1, k)];
                        j0[3 + k] = jr[(0, k)];
                        j1[3 + k] = jr[(1, k)];
                    }
                    col = 6;
                }
                // With (δω_b, δC_b): R_b X + t_b = R_b (X − C_b), so
                // ∂/∂δω_b = −R_r [R_b X + t_b]×, ∂/∂δC_b = −R_r R_b.
                Some(axes) => {
                    let jw = -(jr * skew(&b.transform(x)));
                    let jc = -(jr * b.rotation);
                    col = write_centred(j0, j1, &jw, &jc, axes);
                }
            }
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
    } else if layout.image_slot[image].is_some() {
        match &layout.image_centre_axes[image] {
            None => {
                // ∂xc/∂δω = −[R X]×, ∂xc/∂δt = I.
                let jw = -(dxc * skew(rx));
                for k in 0..3 {
                    j0[k] = jw[(0, k)];
                    j1[k] = jw[(1, k)];
                    j0[3 + k] = dxc[(0, k)];
                    j1[3 + k] = dxc[(1, k)];
                }
                col = 6;
            }
            // With (δω, δC): xc = R (X − C), ∂xc/∂δω = −[xc]×, ∂xc/∂δC = −R.
            Some(axes) => {
                let jw = -(dxc * skew(xc));
                let jc = -(dxc * problem.images[image].camera_from_object.rotation);
                col = write_centred(j0, j1, &jw, &jc, axes);
            }
        }
    }
    col
}

/// The values of `blocks` in `problem` (None for an index out of range).
fn block_values<'a>(problem: &'a Problem, blocks: &[Block]) -> Option<Vec<Value<'a>>> {
    blocks
        .iter()
        .map(|b| match *b {
            Block::Point(PointKey(p)) => problem.points.get(p).map(|x| Value::Point(&x.position)),
            Block::Pose(ImageKey(i)) => problem
                .images
                .get(i)
                .map(|im| Value::Pose(&im.camera_from_object)),
            Block::Parameter(ParameterKey(k)) => problem.parameters.get(k).map(|pb| pb.as_value()),
        })
        .collect()
}
