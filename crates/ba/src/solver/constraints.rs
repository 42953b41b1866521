//! The normal-equation algebra of the constraints ([`crate::residual::Residual`]s: distances,
//! control points, pose priors, kinds defined outside the crate), in one place for every
//! solver path: the gradient and V blocks, the explicit S, the implicit product and its
//! preconditioner, the linear model's decrease, and the redundancy numbers.
//!
//! Each constraint k has its whitened residual `r_k` and, per block, `J_k,a` restricted to
//! the block's free columns ([`super::evaluate::ConstraintLin`]); the layout says where each
//! block lives ([`Place`]). A constraint whose only block is an eliminated point adds
//! `J_pᵀ J_p` to that point's V (and `J_pᵀ r` to g_p); every other constraint has all of its
//! blocks in the reduced system and adds `J_aᵀ J_b` to S for every pair of its blocks.

use super::clusters::Clusters;
use super::evaluate::{ConstraintLin, Linearization};
use super::layout::{BlockCols, Layout, Place, Slot};
use nalgebra::{DMatrix, Matrix3, Vector3};

/// The reduced-system blocks of constraint `k` with their Jacobians.
fn reduced<'a>(
    lin: &'a Linearization,
    layout: &'a Layout,
    k: usize,
) -> impl Iterator<Item = (Slot, &'a DMatrix<f64>)> + 'a {
    (layout.constraint_cols[k].iter().zip(&lin.constraints[k].j)).filter_map(|(bc, j)| {
        match bc.place {
            Place::Reduced(s) if !bc.cols.is_empty() => Some((s, j)),
            _ => None,
        }
    })
}

/// Adds every constraint's `diag(JᵀJ)` and `Jᵀr` to the reduced system's (`diag_c`, `gc`),
/// or `JᵀJ` and `Jᵀr` to an eliminated point's (`v`, `gp`).
pub(crate) fn add_gradient(
    layout: &Layout,
    lin: &Linearization,
    diag_c: &mut [f64],
    gc: &mut [f64],
    v: &mut [Matrix3<f64>],
    gp: &mut [Vector3<f64>],
) {
    for (cols, c) in layout.constraint_cols.iter().zip(&lin.constraints) {
        for (bc, j) in cols.iter().zip(&c.j) {
            match bc.place {
                Place::Reduced(s) => {
                    let o = layout.slot_offset(s);
                    for col in 0..j.ncols() {
                        let jc = j.column(col);
                        diag_c[o + col] += jc.norm_squared();
                        gc[o + col] += jc.iter().zip(&c.r).map(|(a, b)| a * b).sum::<f64>();
                    }
                }
                Place::Eliminated(f) => {
                    let f = f as usize;
                    v[f] += Matrix3::from_fn(|a, b| j.column(a).dot(&j.column(b)));
                    gp[f] += Vector3::from_fn(|a, _| {
                        j.column(a)
                            .iter()
                            .zip(&c.r)
                            .map(|(x, y)| x * y)
                            .sum::<f64>()
                    });
                }
                Place::Fixed => {}
            }
        }
    }
}

/// Adds every constraint's `J_aᵀ J_b` (its blocks in the reduced system) to S's values.
pub(crate) fn add_to_s(layout: &Layout, lin: &Linearization, values: &mut [f64]) {
    for k in 0..lin.constraints.len() {
        let blocks: Vec<(Slot, &DMatrix<f64>)> = reduced(lin, layout, k).collect();
        for (i, &(sa, ja)) in blocks.iter().enumerate() {
            for &(sb, jb) in &blocks[i..] {
                layout.add_to_s(values, sa, sb, &(ja.transpose() * jb));
            }
        }
    }
}

/// `y += Σ_k J_kᵀ J_k x` over the constraints' reduced-system blocks.
pub(crate) fn add_product(layout: &Layout, lin: &Linearization, x: &[f64], y: &mut [f64]) {
    for k in 0..lin.constraints.len() {
        let blocks: Vec<(Slot, &DMatrix<f64>)> = reduced(lin, layout, k).collect();
        if blocks.is_empty() {
            continue;
        }
        let mut z = vec![0.0; lin.constraints[k].r.len()];
        for &(s, j) in &blocks {
            let o = layout.slot_offset(s);
            for (row, zr) in z.iter_mut().enumerate() {
                *zr += (0..j.ncols()).map(|c| j[(row, c)] * x[o + c]).sum::<f64>();
            }
        }
        for &(s, j) in &blocks {
            let o = layout.slot_offset(s);
            for c in 0..j.ncols() {
                y[o + c] += j.column(c).iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
            }
        }
    }
}

/// Adds every constraint's `J_aᵀ J_b`, for its blocks a and b in one cluster, to the
/// clusters' matrices (column-major from `clusters.offset[c]`: the preconditioner).
pub(crate) fn add_to_cluster_blocks(
    layout: &Layout,
    lin: &Linearization,
    clusters: &Clusters,
    matrices: &mut [f64],
) {
    for k in 0..lin.constraints.len() {
        let blocks: Vec<(Slot, &DMatrix<f64>)> = reduced(lin, layout, k).collect();
        for &(sa, ja) in &blocks {
            for &(sb, jb) in blocks
                .iter()
                .filter(|b| clusters.together(sa.block, b.0.block))
            {
                let c = clusters.of_block[sa.block as usize] as usize;
                let d = clusters.dim[c];
                let row0 = clusters.local[sa.block as usize] + sa.off as usize;
                let col0 = clusters.local[sb.block as usize] + sb.off as usize;
                for j in 0..jb.ncols() {
                    for i in 0..ja.ncols() {
                        matrices[clusters.offset[c] + (col0 + j) * d + row0 + i] +=
                            ja.column(i).dot(&jb.column(j));
                    }
                }
            }
        }
    }
}

/// The step of one block's free columns.
fn block_delta(layout: &Layout, bc: &BlockCols, dc: &[f64], dp: &[Vector3<f64>]) -> Vec<f64> {
    match bc.place {
        Place::Reduced(s) => {
            let o = layout.slot_offset(s);
            dc[o..o + bc.cols.len()].to_vec()
        }
        Place::Eliminated(f) => dp[f as usize].iter().copied().collect(),
        Place::Fixed => Vec::new(),
    }
}

/// The linear model's decrease `−rᵀJδ − ½|Jδ|²` summed over the constraints.
pub(crate) fn decrease(
    layout: &Layout,
    lin: &Linearization,
    dc: &[f64],
    dp: &[Vector3<f64>],
) -> f64 {
    (layout.constraint_cols.iter().zip(&lin.constraints))
        .map(|(cols, c)| {
            let jd = c.apply(cols, |bc| block_delta(layout, bc, dc, dp));
            let rjd: f64 = c.r.iter().zip(&jd).map(|(a, b)| a * b).sum();
            -rjd - 0.5 * jd.iter().map(|v| v * v).sum::<f64>()
        })
        .sum()
}

/// `diag(A Q Aᵀ)` of constraint `k`: `q` the cofactors of the reduced unknowns, `q_point`
/// those of the eliminated points (by free index).
pub(crate) fn cofactor_diagonal(
    layout: &Layout,
    c: &ConstraintLin,
    k: usize,
    q: &dyn super::selected_inverse::CofactorLookup,
    q_point: impl Fn(usize) -> Matrix3<f64>,
) -> Vec<f64> {
    let cols = &layout.constraint_cols[k];
    let mut out = vec![0.0; c.r.len()];
    for (row, o) in out.iter_mut().enumerate() {
        for (bca, ja) in cols.iter().zip(&c.j) {
            for (bcb, jb) in cols.iter().zip(&c.j) {
                let cell = |a: usize, b: usize| -> f64 {
                    match (bca.place, bcb.place) {
                        (Place::Reduced(sa), Place::Reduced(sb)) => {
                            q.at(layout.slot_offset(sa) + a, layout.slot_offset(sb) + b)
                        }
                        (Place::Eliminated(fa), Place::Eliminated(fb)) if fa == fb => {
                            q_point(fa as usize)[(a, b)]
                        }
                        _ => 0.0,
                    }
                };
                for a in 0..ja.ncols() {
                    for b in 0..jb.ncols() {
                        *o += ja[(row, a)] * cell(a, b) * jb[(row, b)];
                    }
                }
            }
        }
    }
    out
}
