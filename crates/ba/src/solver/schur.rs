//! The Schur complement: eliminating the 3×3 point blocks to form the reduced camera
//! system `S δc = b`, and recovering the point steps afterwards.
//!
//! With the normal equations `[U W; Wᵀ V] [δc; δp] = −[g_c; g_p]` (V block diagonal, one
//! 3×3 block per free point), `S = U + λD_c − W (V + λD_p)⁻¹ Wᵀ` and
//! `b = −g_c + W (V + λD_p)⁻¹ g_p`; then `δp = (V + λD_p)⁻¹ (−g_p − Wᵀ δc)`.
//!
//! S is assembled in parallel by block column: every task writes only the values of its
//! own column, so no locks are needed.

use super::evaluate::{split_at_offsets, Linearization};
use super::layout::Layout;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

/// Bounds on the Levenberg–Marquardt scaling diagonal (as in Ceres).
const MIN_DIAGONAL: f64 = 1e-6;
const MAX_DIAGONAL: f64 = 1e32;

pub(crate) struct Schur {
    /// Per free point: V = Σ J_pᵀ J_p, g_p = Σ J_pᵀ r, and (V + λD)⁻¹.
    pub v: Vec<Matrix3<f64>>,
    pub gp: Vec<Vector3<f64>>,
    pub vinv: Vec<Matrix3<f64>>,
    /// Per observation: Y = W (V + λD)⁻¹, laid out like W (three columns).
    pub y: Vec<f64>,
    /// diag(U) and the camera-side gradient g_c.
    pub diag_c: Vec<f64>,
    pub gc: Vec<f64>,
    /// Values of S (upper triangle, CSC of the layout) and the right-hand side b.
    pub values: Vec<f64>,
    pub rhs: Vec<f64>,
}

impl Schur {
    pub fn new(layout: &Layout) -> Self {
        let nfp = layout.free_points.len();
        Self {
            v: vec![Matrix3::zeros(); nfp],
            gp: vec![Vector3::zeros(); nfp],
            vinv: vec![Matrix3::zeros(); nfp],
            y: vec![0.0; layout.w_len],
            diag_c: vec![0.0; layout.n_reduced],
            gc: vec![0.0; layout.n_reduced],
            values: vec![0.0; layout.nnz()],
            rhs: vec![0.0; layout.n_reduced],
        }
    }

    /// Computes what depends on the linearization only: V, g_p, diag(U), g_c.
    pub fn prepare(&mut self, layout: &Layout, lin: &Linearization) {
        self.v
            .par_iter_mut()
            .zip(self.gp.par_iter_mut())
            .enumerate()
            .with_min_len(64)
            .for_each(|(f, (v, g))| {
                let mut vv = Matrix3::zeros();
                let mut gg = Vector3::zeros();
                for &o in layout.point_obs(f) {
                    let jp = &lin.jp[o as usize];
                    vv += jp.transpose() * jp;
                    gg += jp.transpose() * lin.r[o as usize];
                }
                *v = vv;
                *g = gg;
            });
        let offsets = &layout.block_offset;
        let diag_parts = split_at_offsets(&mut self.diag_c, offsets);
        let g_parts = split_at_offsets(&mut self.gc, offsets);
        diag_parts
            .into_par_iter()
            .zip(g_parts.into_par_iter())
            .enumerate()
            .for_each(|(b, (d, g))| {
                d.fill(0.0);
                g.fill(0.0);
                for &(o, si) in layout.obs_of_block(b) {
                    let o = o as usize;
                    let s = layout.segs(o)[si as usize];
                    let (j0, j1) = layout.jc_rows(&lin.jc, o, &s);
                    let r = lin.r[o];
                    for k in 0..s.len as usize {
                        let (a, c) = (j0[k], j1[k]);
                        d[s.block_off as usize + k] += a * a + c * c;
                        g[s.block_off as usize + k] += a * r.x + c * r.y;
                    }
                }
            });
    }

    /// Max-norm of the full gradient Jᵀr.
    pub fn gradient_max_norm(&self) -> f64 {
        let a = self.gc.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        self.gp.iter().fold(a, |m, g| m.max(g.amax()))
    }

    /// Forms S and b for the damping `lambda`. Fails if a damped point block is not
    /// positive definite (returns the free-point index).
    pub fn assemble(
        &mut self,
        layout: &Layout,
        lin: &Linearization,
        lambda: f64,
    ) -> Result<(), usize> {
        // (V + λD)⁻¹ per point.
        self.vinv
            .par_iter_mut()
            .zip(self.v.par_iter())
            .enumerate()
            .with_min_len(64)
            .try_for_each(|(f, (vi, v))| {
                let mut m = *v;
                for k in 0..3 {
                    m[(k, k)] += lambda * m[(k, k)].clamp(MIN_DIAGONAL, MAX_DIAGONAL);
                }
                *vi = m.cholesky().ok_or(f)?.inverse();
                Ok::<(), usize>(())
            })?;
        // Y = W (V + λD)⁻¹ per observation of a free point.
        let y_parts = split_at_offsets(&mut self.y, &layout.obs_w_offset);
        let vinv = &self.vinv;
        y_parts
            .into_par_iter()
            .enumerate()
            .with_min_len(256)
            .for_each(|(o, y)| {
                let f = layout.free_point_index[lin_point(layout, o)];
                if f == u32::MAX {
                    return;
                }
                let m = &vinv[f as usize];
                let nc = y.len() / 3;
                if nc == 0 {
                    return;
                }
                let w = &lin.w[layout.obs_w_offset[o]..layout.obs_w_offset[o] + 3 * nc];
                let (w0, w12) = w.split_at(nc);
                let (w1, w2) = w12.split_at(nc);
                for (c, yc) in y.chunks_exact_mut(nc).enumerate() {
                    let (a, b, d) = (m[(0, c)], m[(1, c)], m[(2, c)]);
                    for (k, v) in yc.iter_mut().enumerate() {
                        *v = w0[k] * a + w1[k] * b + w2[k] * d;
                    }
                }
            });
        // S and b by block column.
        let value_starts: Vec<usize> = (0..layout.num_blocks())
            .map(|b| layout.block_value_range(b).0)
            .collect();
        let val_parts = split_at_offsets(&mut self.values, &value_starts);
        let rhs_parts = split_at_offsets(&mut self.rhs, &layout.block_offset);
        let (y, gp, diag_c, gc) = (&self.y, &self.gp, &self.diag_c, &self.gc);
        val_parts
            .into_par_iter()
            .zip(rhs_parts.into_par_iter())
            .enumerate()
            .for_each(|(b, (vals, rhs))| {
                assemble_column(layout, lin, y, gp, diag_c, gc, lambda, b, vals, rhs);
            });
        Ok(())
    }

    /// δp for every free point, given δc.
    pub fn back_substitute(
        &self,
        layout: &Layout,
        lin: &Linearization,
        dc: &[f64],
        dp: &mut [Vector3<f64>],
    ) {
        dp.par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .for_each(|(f, d)| {
                let mut rhs = -self.gp[f];
                for &o in layout.point_obs(f) {
                    let o = o as usize;
                    for s in layout.segs(o) {
                        let base = layout.block_offset[s.block as usize] + s.block_off as usize;
                        let x = &dc[base..base + s.len as usize];
                        let w = layout.w_cols(&lin.w, o, s);
                        for m in 0..3 {
                            rhs[m] -= w[m].iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
                        }
                    }
                }
                *d = self.vinv[f] * rhs;
            });
    }
}

#[inline]
fn lin_point(layout: &Layout, o: usize) -> usize {
    layout.obs_point[o] as usize
}

#[allow(clippy::too_many_arguments)]
fn assemble_column(
    layout: &Layout,
    lin: &Linearization,
    y: &[f64],
    gp: &[Vector3<f64>],
    diag_c: &[f64],
    gc: &[f64],
    lambda: f64,
    b: usize,
    vals: &mut [f64],
    rhs: &mut [f64],
) {
    vals.fill(0.0);
    let off_b = layout.block_offset[b];
    let dim_b = layout.block_dim[b];
    let v0 = layout.col_ptr[off_b];
    let col_ptr = &layout.col_ptr[off_b..=off_b + dim_b];
    let rows = &layout.col_blocks[b];
    let roffs = &layout.col_row_off[b];
    for k in 0..dim_b {
        rhs[k] = -gc[off_b + k];
    }
    let mut col = Column {
        vals,
        col_ptr,
        v0,
        rows,
        roffs,
        b,
    };
    for &(o2, s2i) in layout.obs_of_block(b) {
        let o2 = o2 as usize;
        let s2 = layout.segs(o2)[s2i as usize];
        let (l2, off2) = (s2.len as usize, s2.block_off as usize);
        let (a0, a1) = layout.jc_rows(&lin.jc, o2, &s2);
        // U = Σ J_cᵀ J_c.
        for s1 in layout.segs(o2) {
            if s1.block as usize > b {
                continue;
            }
            let (l0, l1) = layout.jc_rows(&lin.jc, o2, s1);
            col.add(
                [l0, l1],
                [a0, a1],
                s1.block,
                s1.block_off as usize,
                off2,
                l2,
                1.0,
            );
        }
        // − W V⁻¹ Wᵀ and + W V⁻¹ g_p.
        let f = layout.free_point_index[layout.obs_point[o2] as usize];
        if f == u32::MAX {
            continue;
        }
        let f = f as usize;
        let w2 = layout.w_cols(&lin.w, o2, &s2);
        let y2 = layout.w_cols(y, o2, &s2);
        let g = gp[f];
        for k in 0..l2 {
            rhs[off2 + k] += y2[0][k] * g.x + y2[1][k] * g.y + y2[2][k] * g.z;
        }
        for &o1 in layout.point_obs(f) {
            let o1 = o1 as usize;
            for s1 in layout.segs(o1) {
                if s1.block as usize > b {
                    continue;
                }
                let y1 = layout.w_cols(y, o1, s1);
                col.add(y1, w2, s1.block, s1.block_off as usize, off2, l2, -1.0);
            }
        }
    }
    // Levenberg–Marquardt damping on the diagonal (the diagonal block is the last row block).
    let roff = *roffs.last().unwrap();
    for j in 0..dim_b {
        let d = diag_c[off_b + j].clamp(MIN_DIAGONAL, MAX_DIAGONAL);
        col.vals[col_ptr[j] - v0 + roff + j] += lambda * d;
    }
}

/// The values of one block column of S.
struct Column<'a> {
    vals: &'a mut [f64],
    col_ptr: &'a [usize],
    v0: usize,
    rows: &'a [u32],
    roffs: &'a [usize],
    b: usize,
}

impl Column<'_> {
    /// Adds `scale · Σ_k left[k][i] · right[k][j]` to S[(block a, row off1 + i), (block b,
    /// col off2 + j)] for j < len2, upper triangle only. Each column update is a
    /// contiguous axpy, which the compiler vectorizes.
    #[inline(always)]
    fn add<const K: usize>(
        &mut self,
        left: [&[f64]; K],
        right: [&[f64]; K],
        a: u32,
        off1: usize,
        off2: usize,
        len2: usize,
        scale: f64,
    ) {
        let ai = self
            .rows
            .binary_search(&a)
            .expect("block pair in the pattern");
        let roff = self.roffs[ai];
        let diag = a as usize == self.b;
        let len1 = left[0].len();
        for j in 0..len2 {
            let col = off2 + j;
            let base = self.col_ptr[col] - self.v0 + roff + off1;
            let n = if diag {
                len1.min((col + 1).saturating_sub(off1))
            } else {
                len1
            };
            let dst = &mut self.vals[base..base + n];
            let c: [f64; K] = std::array::from_fn(|k| scale * right[k][j]);
            if K == 2 {
                let (l0, l1) = (&left[0][..n], &left[1][..n]);
                for ((d, x), y) in dst.iter_mut().zip(l0).zip(l1) {
                    *d += x * c[0] + y * c[1];
                }
            } else {
                let (l0, l1, l2) = (&left[0][..n], &left[1][..n], &left[2][..n]);
                for (((d, x), y), z) in dst.iter_mut().zip(l0).zip(l1).zip(l2) {
                    *d += x * c[0] + y * c[1] + z * c[2];
                }
            }
        }
    }
}
