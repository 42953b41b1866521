//! Precision of a free network: the datum by inner constraints on the object points
//! (the minimum-trace solution), for networks with no fixed image, no control point, no
//! held coordinate and no fixed rig, whose normal matrix is singular by the 7 degrees of freedom of a
//! similarity transform (6 when distances fix the scale).
//!
//! With N = JᵀJ the normal matrix, G (n × d) a basis of its null space (the similarity's
//! effect on every unknown) and C = G restricted to the point coordinates (the inner
//! constraints Cᵀδx = 0), the cofactor matrix is
//! `Q = (N + C Cᵀ)⁻¹ − G (CᵀG)⁻¹ (GᵀC)⁻¹ Gᵀ` (Koch, *Parameter Estimation and Hypothesis
//! Testing in Linear Models*, §3.2.6). It is formed densely for networks of at most
//! [`MAX_FREE_NETWORK_UNKNOWNS`] unknowns; larger ones are solved in Schur form by
//! bordering (`precision::free_network_bordered`): Q is also the upper-left block of
//! `[N C; Cᵀ 0]⁻¹`, and since C touches only points, eliminating the points leaves the
//! reduced system bordered by d rows, `[S, C_c − W V⁻¹ C_p; ·ᵀ, −C_pᵀ V⁻¹ C_p]`, of the size
//! of the camera-side unknowns plus d. Intrinsic parameters are estimable: their standard
//! deviations do not depend on the datum.

use super::evaluate::Linearization;
use super::layout::Layout;
use super::layout::Place;
use super::sigma::{
    intrinsics_precision, parameters_covariance, pose_sigmas, rig_covariances,
    rigs_and_parameters_covariance, Precision, PrecisionError,
};
use crate::problem::Problem;
use nalgebra::{DMatrix, Matrix3, Vector3};

/// Largest free network (unknowns) whose precision is formed densely; larger ones are
/// solved by bordering the reduced system.
pub const MAX_FREE_NETWORK_UNKNOWNS: usize = 4000;

/// The `d` inner-constraint columns (translation 3, rotation 3, scale 1 when `d` is 7) at
/// a point X: row a of the 3 × d block, `[e_a | (e_k × X)_a | X_a]`.
pub(crate) fn point_constraints(x: &Vector3<f64>, d: usize) -> [[f64; 7]; 3] {
    let mut c = [[0.0; 7]; 3];
    for k in 0..3 {
        let rot = Vector3::ith(k, 1.0).cross(x);
        for a in 0..3 {
            c[a][k] = if a == k { 1.0 } else { 0.0 };
            c[a][3 + k] = rot[a];
        }
    }
    if d == 7 {
        for a in 0..3 {
            c[a][6] = x[a];
        }
    }
    c
}

/// Whether `problem` has no datum of its own (then inner constraints define one).
pub(crate) fn is_free(problem: &Problem) -> bool {
    problem
        .images
        .iter()
        .all(|i| !i.fixed && !i.is_centre_held())
        && problem.points.iter().all(|p| !p.held().iter().any(|h| *h))
        && problem.point_priors.is_empty()
        && problem.residuals.is_empty()
        && problem.rigs.iter().all(|r| !r.fixed)
}

/// Column of unknown groups in the dense system: reduced first, then eliminated points.
fn point_col(layout: &Layout, p: usize) -> Option<usize> {
    if let Some(s) = layout.point_slot[p] {
        Some(layout.slot_offset(s))
    } else if layout.free_point_index[p] != u32::MAX {
        Some(layout.n_reduced + 3 * layout.free_point_index[p] as usize)
    } else {
        None
    }
}

/// The precision of a free network, its datum by inner constraints on the points (see the
/// module doc); refused when the network is too large to be formed densely.
pub(crate) fn precision(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
) -> Result<Precision, PrecisionError> {
    let n = layout.n_reduced + 3 * layout.free_points.len();
    let (j, r) = dense_system(problem, layout, lin, n);
    let m = j.nrows();
    // Translation, rotation and scale (unless distances fix it).
    let d = if problem.distances.is_empty() { 7 } else { 6 };
    let (g, c) = similarity_null_space(problem, layout, n, d);
    let q = inner_constraint_cofactors(&(j.transpose() * &j), &g, &c)?;

    let redundancy = m as i64 - n as i64 + d as i64;
    if redundancy <= 0 {
        return Err(PrecisionError::NoRedundancy(redundancy));
    }
    let sigma0 = (2.0 * lin.cost / redundancy as f64).sqrt();
    let s02 = sigma0 * sigma0;

    let intrinsics = intrinsics_precision(problem, layout, s02, |i, j| q[(i, j)]);
    let poses = pose_sigmas(problem, layout, s02, |i, j| q[(i, j)]);
    let rig_covariances = rig_covariances(layout, s02, |i, j| q[(i, j)]);
    let point_covariances = (0..problem.points.len())
        .map(|p| point_col(layout, p).map(|c| Matrix3::from_fn(|a, b| s02 * q[(c + a, c + b)])))
        .collect();
    let (standardized_residuals, redundancy_numbers, constraint_q) =
        standardized_residuals(layout, lin, &j, &q, &r);
    let by_kind = super::sigma::split_constraint_redundancy(problem, lin, constraint_q);
    let (parameters_covariance, parameter_offsets) =
        parameters_covariance(problem, layout, s02, &q);
    Ok(Precision {
        cofactors: super::sigma::DENSE_INNER,
        sigma0,
        redundancy,
        observations: m,
        unknowns: n,
        rms_image_px: problem.rms_px(),
        intrinsics,
        poses,
        rig_covariances,
        point_covariances,
        standardized_residuals,
        redundancy_numbers,
        distance_redundancy_numbers: by_kind.distance_redundancy_numbers,
        distance_standardized: by_kind.distance_standardized,
        control_redundancy_numbers: by_kind.control_redundancy_numbers,
        control_standardized: by_kind.control_standardized,
        residual_redundancy_numbers: by_kind.residual_redundancy_numbers,
        residual_standardized: by_kind.residual_standardized,
        parameters_covariance,
        parameter_offsets,
        rigs_and_parameters_covariance: rigs_and_parameters_covariance(problem, layout, s02, &q),
    })
}

/// The whitened Jacobian (dense, `n` columns: reduced unknowns, then eliminated points)
/// and residuals: two rows per image observation in internal order, then the constraints'
/// rows.
fn dense_system(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
    n: usize,
) -> (DMatrix<f64>, Vec<f64>) {
    let nc = layout.n_reduced;
    let n_img_obs = problem.observations.len();
    let m = 2 * n_img_obs + lin.constraints.iter().map(|c| c.r.len()).sum::<usize>();
    let mut j = DMatrix::<f64>::zeros(m, n);
    let mut r = vec![0.0; m];
    for o in 0..n_img_obs {
        r[2 * o] = lin.r[o].x;
        r[2 * o + 1] = lin.r[o].y;
        for sg in layout.segs(o) {
            let base = layout.block_offset[sg.block as usize] + sg.block_off as usize;
            let (j0, j1) = layout.jc_rows(&lin.jc, o, sg);
            for k in 0..sg.len as usize {
                j[(2 * o, base + k)] = j0[k];
                j[(2 * o + 1, base + k)] = j1[k];
            }
        }
        let f = layout.free_point_index[layout.obs_point[o] as usize];
        if f != u32::MAX {
            let c = nc + 3 * f as usize;
            for k in 0..3 {
                j[(2 * o, c + k)] = lin.jp[o][(0, k)];
                j[(2 * o + 1, c + k)] = lin.jp[o][(1, k)];
            }
        }
    }
    let mut row = 2 * n_img_obs;
    for (cols, c) in layout.constraint_cols.iter().zip(&lin.constraints) {
        for (i, ri) in c.r.iter().enumerate() {
            r[row + i] = *ri;
            for (bc, jb) in cols.iter().zip(&c.j) {
                let col = match bc.place {
                    Place::Reduced(s) => layout.slot_offset(s),
                    Place::Eliminated(f) => nc + 3 * f as usize,
                    Place::Fixed => continue,
                };
                for a in 0..jb.ncols() {
                    j[(row + i, col + a)] = jb[(i, a)];
                }
            }
        }
        row += c.r.len();
    }
    (j, r)
}

/// G, the `d` (7, or 6 without scale) directions of the similarity transform in the
/// unknowns, and C, G restricted to the point coordinates (the inner constraints).
///
/// Translation (3), rotation (3), scale (1). For a pose (left update R ← exp(δω)R,
/// t ← t + δt): translation T → δt = −R T; rotation ω → δω = −R ω; scale s → δt = s·t.
fn similarity_null_space(
    problem: &Problem,
    layout: &Layout,
    n: usize,
    d: usize,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let mut g = DMatrix::<f64>::zeros(n, d);
    let mut c = DMatrix::<f64>::zeros(n, d);
    for (i, slot) in layout.image_slot.iter().enumerate() {
        let Some(s) = slot else { continue };
        let o = layout.slot_offset(*s);
        let pose = &problem.images[i].camera_from_object;
        for k in 0..3 {
            let e = Vector3::ith(k, 1.0);
            let dt = -(pose.rotation * e);
            let dw = -(pose.rotation * e);
            for a in 0..3 {
                g[(o + 3 + a, k)] = dt[a];
                g[(o + a, 3 + k)] = dw[a];
            }
        }
        if d == 7 {
            for a in 0..3 {
                g[(o + 3 + a, 6)] = pose.translation[a];
            }
        }
    }
    for (rg, slot) in layout.rig_slot.iter().enumerate() {
        if let (Some(s), 7) = (slot, d) {
            let o = layout.slot_offset(*s);
            for a in 0..3 {
                g[(o + 3 + a, 6)] = problem.rigs[rg].member_from_base.translation[a];
            }
        }
    }
    for (p, pt) in problem.points.iter().enumerate() {
        let Some(col) = point_col(layout, p).filter(|&c| c < n) else {
            continue;
        };
        let pc = point_constraints(&pt.position, d);
        for (a, row) in pc.iter().enumerate() {
            for (k, &v) in row.iter().enumerate().take(d) {
                g[(col + a, k)] = v;
                c[(col + a, k)] = v;
            }
        }
    }
    (g, c)
}

/// The null space of the reduced system S of a free network: [`similarity_null_space`]'s
/// rows of the reduced unknowns (n_reduced × d).
pub(crate) fn reduced_null_space(problem: &Problem, layout: &Layout, d: usize) -> DMatrix<f64> {
    similarity_null_space(problem, layout, layout.n_reduced, d).0
}

/// The cofactor matrix of the minimum-trace datum: the upper-left block of
/// `[N C; Cᵀ 0]⁻¹`, which equals `(N + C Cᵀ)⁻¹ − G (CᵀG)⁻¹ (GᵀC)⁻¹ Gᵀ` but is computed by
/// the bordered inverse (Jacobi-scaled LU): the closed form cancels badly when a direction
/// outside G is weakly determined (a scale from one loose distance lost 5e-4 of the pose σ).
fn inner_constraint_cofactors(
    normal: &DMatrix<f64>,
    g: &DMatrix<f64>,
    c: &DMatrix<f64>,
) -> Result<DMatrix<f64>, PrecisionError> {
    let (n, d) = (normal.nrows(), c.ncols());
    if (c.transpose() * g).try_inverse().is_none() {
        return Err(PrecisionError::DatumDefect(
            "the inner constraints do not fix the datum (all points coincide?)".into(),
        ));
    }
    let mut k = DMatrix::<f64>::zeros(n + d, n + d);
    k.view_mut((0, 0), (n, n)).copy_from(normal);
    k.view_mut((0, n), (n, d)).copy_from(c);
    k.view_mut((n, 0), (d, n)).copy_from(&c.transpose());
    let Some(inv) = bordered_inverse(&k, n) else {
        return Err(PrecisionError::DatumDefect(
            "the network is free and, beyond position, orientation and scale, still not determined (too few points per image, or disconnected pieces)".into(),
        ));
    };
    Ok(inv.view((0, 0), (n, n)).into_owned())
}

/// The inverse of a bordered matrix `[A B; Bᵀ D]` (A the first `n` rows and columns):
/// Jacobi-scaled (A's diagonal, the border rows' norms: unknowns of very different units
/// meet here), LU-factorized and unscaled; `None` if it is singular or not finite.
pub(crate) fn bordered_inverse(k: &DMatrix<f64>, n: usize) -> Option<DMatrix<f64>> {
    let m = k.nrows();
    let scale: Vec<f64> = (0..m)
        .map(|i| {
            let v = if i < n { k[(i, i)] } else { k.row(i).norm() };
            1.0 / v.abs().max(f64::MIN_POSITIVE).sqrt()
        })
        .collect();
    let scaled = DMatrix::from_fn(m, m, |i, j| k[(i, j)] * scale[i] * scale[j]);
    let inv = scaled.lu().try_inverse()?;
    let inv = DMatrix::from_fn(m, m, |i, j| inv[(i, j)] * scale[i] * scale[j]);
    inv.iter().all(|v| v.is_finite()).then_some(inv)
}

/// The image observations' standardized residuals and redundancy numbers, and each
/// constraint's redundancy numbers (see [`standardized_residuals`]).
type Snooping = (Vec<[f64; 2]>, Vec<[f64; 2]>, Vec<Vec<f64>>);

/// The standardized residuals of the image observations (in the problem's order):
/// `r / √q_vv` with `q_vv = 1 − (J Q Jᵀ)_ii`; NaN where q_vv vanishes. Beside them the
/// redundancy numbers `q_vv` of the image observations and, per constraint, of its rows (0
/// where there is no redundancy).
fn standardized_residuals(
    layout: &Layout,
    lin: &Linearization,
    j: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &[f64],
) -> Snooping {
    let jq = j * q;
    let qvv = |row: usize| 1.0 - jq.row(row).dot(&j.row(row));
    let n_img_obs = layout.obs_order.len();
    let mut standardized = vec![[f64::NAN; 2]; n_img_obs];
    let mut redundancy = vec![[0.0; 2]; n_img_obs];
    for o in 0..n_img_obs {
        let q_index = layout.obs_order[o] as usize;
        for a in 0..2 {
            let row = 2 * o + a;
            let qvv = qvv(row);
            if qvv > 1e-9 {
                standardized[q_index][a] = r[row] / qvv.sqrt();
                redundancy[q_index][a] = qvv;
            }
        }
    }
    let mut row = 2 * n_img_obs;
    let constraints = (lin.constraints.iter())
        .map(|c| {
            let q: Vec<f64> = (row..row + c.r.len()).map(|i| qvv(i).max(0.0)).collect();
            row += c.r.len();
            q
        })
        .collect();
    (standardized, redundancy, constraints)
}
