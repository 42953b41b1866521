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
use super::layout::{Layout, Seg};
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
    /// Work split: contiguous ranges of (internal, point-ordered) observations that start
    /// and end on point boundaries, one per worker, each with its own copy of S and b.
    pub chunks: Vec<(usize, usize)>,
    work_values: Vec<Vec<f64>>,
    work_rhs: Vec<Vec<f64>>,
}

impl Schur {
    pub fn new(layout: &Layout) -> Self {
        let nfp = layout.free_points.len();
        Self {
            v: vec![Matrix3::zeros(); nfp],
            gp: vec![Vector3::zeros(); nfp],
            vinv: vec![Matrix3::zeros(); nfp],
            // S's values and Y are allocated by the first explicit assembly: the iterative
            // solver needs neither.
            y: Vec::new(),
            diag_c: vec![0.0; layout.n_reduced],
            gc: vec![0.0; layout.n_reduced],
            values: Vec::new(),
            rhs: vec![0.0; layout.n_reduced],
            chunks: Vec::new(),
            work_values: Vec::new(),
            work_rhs: Vec::new(),
        }
        .with_chunks(layout)
    }

    fn with_chunks(mut self, layout: &Layout) -> Self {
        let n_obs = layout.obs_point.len();
        let workers = rayon::current_num_threads().max(1);
        let mut bounds = vec![0];
        for w in 1..workers {
            let mut k = (n_obs * w / workers).max(*bounds.last().unwrap());
            while k < n_obs && k > 0 && layout.obs_point[k] == layout.obs_point[k - 1] {
                k += 1;
            }
            bounds.push(k);
        }
        bounds.push(n_obs);
        bounds.dedup();
        self.chunks = bounds.windows(2).map(|w| (w[0], w[1])).collect();
        self.work_values = vec![Vec::new(); self.chunks.len()];
        self.work_rhs = vec![Vec::new(); self.chunks.len()];
        self
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
        // diag(U) and g_c: each worker streams its observations into its own vectors.
        let n = layout.n_reduced;
        let chunks = &self.chunks;
        let parts: Vec<(Vec<f64>, Vec<f64>)> = chunks
            .par_iter()
            .map(|&(lo, hi)| {
                let (mut d, mut g) = (vec![0.0; n], vec![0.0; n]);
                for o in lo..hi {
                    let r = lin.r[o];
                    for s in layout.segs(o) {
                        let base = layout.block_offset[s.block as usize] + s.block_off as usize;
                        let (j0, j1) = layout.jc_rows(&lin.jc, o, s);
                        for k in 0..s.len as usize {
                            d[base + k] += j0[k] * j0[k] + j1[k] * j1[k];
                            g[base + k] += j0[k] * r.x + j1[k] * r.y;
                        }
                    }
                }
                (d, g)
            })
            .collect();
        self.diag_c.fill(0.0);
        self.gc.fill(0.0);
        for (d, g) in parts {
            self.diag_c.iter_mut().zip(&d).for_each(|(a, b)| *a += b);
            self.gc.iter_mut().zip(&g).for_each(|(a, b)| *a += b);
        }
        // Distances, control points and the other constraints.
        super::constraints::add_gradient(
            layout,
            lin,
            &mut self.diag_c,
            &mut self.gc,
            &mut self.v,
            &mut self.gp,
        );
    }

    /// Max-norm of the full gradient Jᵀr.
    pub fn gradient_max_norm(&self) -> f64 {
        let a = self.gc.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        self.gp.iter().fold(a, |m, g| m.max(g.amax()))
    }

    /// (V + λD)⁻¹ per free point; fails with the free-point index of a block that is not
    /// positive definite.
    pub fn invert_points(&mut self, lambda: f64) -> Result<(), usize> {
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
            })
    }

    /// λ·clamp(diag(U)): the damping of the reduced system.
    pub fn damping(&self, lambda: f64) -> Vec<f64> {
        (self.diag_c.iter())
            .map(|d| lambda * d.clamp(MIN_DIAGONAL, MAX_DIAGONAL))
            .collect()
    }

    /// Forms S and b for the damping `lambda`. Fails if a damped point block is not
    /// positive definite (returns the free-point index).
    pub fn assemble(
        &mut self,
        layout: &Layout,
        lin: &Linearization,
        lambda: f64,
    ) -> Result<(), usize> {
        self.invert_points(lambda)?;
        if self.y.len() != layout.w_len {
            self.y = vec![0.0; layout.w_len];
        }
        if self.values.len() != layout.nnz() {
            self.values = vec![0.0; layout.nnz()];
        }
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
        // S and b: each worker streams a contiguous range of points into its own copy.
        let (y, gp) = (&self.y, &self.gp);
        let (nnz, n) = (layout.nnz(), layout.n_reduced);
        self.chunks
            .par_iter()
            .zip(
                self.work_values
                    .par_iter_mut()
                    .zip(self.work_rhs.par_iter_mut()),
            )
            .for_each(|(&(lo, hi), (vals, rhs))| {
                vals.clear();
                vals.resize(nnz, 0.0);
                rhs.clear();
                rhs.resize(n, 0.0);
                accumulate_range(layout, lin, y, gp, lo..hi, vals, rhs);
            });
        // Sum the copies, then −g_c and the damping.
        let works = &self.work_values;
        self.values
            .par_chunks_mut(1 << 14)
            .enumerate()
            .for_each(|(c, out)| {
                let base = c << 14;
                out.copy_from_slice(&works[0][base..base + out.len()]);
                for w in &works[1..] {
                    out.iter_mut().zip(&w[base..]).for_each(|(a, b)| *a += b);
                }
            });
        for (k, r) in self.rhs.iter_mut().enumerate() {
            *r = -self.gc[k] + self.work_rhs.iter().map(|w| w[k]).sum::<f64>();
        }
        // The constraints' blocks in the reduced system go straight into S.
        super::constraints::add_to_s(layout, lin, &mut self.values);
        for b in 0..layout.num_blocks() {
            let off_b = layout.block_offset[b];
            let roff = *layout.col_row_off[b].last().unwrap();
            for j in 0..layout.block_dim[b] {
                let d = self.diag_c[off_b + j].clamp(MIN_DIAGONAL, MAX_DIAGONAL);
                self.values[layout.col_ptr[off_b + j] + roff + j] += lambda * d;
            }
        }
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

/// Adds to `vals` (S, upper triangle) and `rhs` the contributions of the observations
/// `obs` (whole points): J_cᵀJ_c of every observation, −Y Wᵀ and +Y g_p of every free
/// point.
fn accumulate_range(
    layout: &Layout,
    lin: &Linearization,
    y: &[f64],
    gp: &[Vector3<f64>],
    obs: std::ops::Range<usize>,
    vals: &mut [f64],
    rhs: &mut [f64],
) {
    for (point, run) in layout.point_runs(obs) {
        let (start, end) = (run.start, run.end);
        let f = layout.free_point_index[point as usize];
        for o2 in start..end {
            for s2 in layout.segs(o2) {
                let b = s2.block as usize;
                let (l2, off2) = (s2.len as usize, s2.block_off as usize);
                let mut col = Column::new(layout, vals, b);
                // U = Σ J_cᵀ J_c.
                let (a0, a1) = layout.jc_rows(&lin.jc, o2, s2);
                for s1 in layout.segs(o2) {
                    if s1.block as usize <= b {
                        let (l0, l1) = layout.jc_rows(&lin.jc, o2, s1);
                        col.add([l0, l1], [a0, a1], s1, s2, 1.0);
                    }
                }
                if f == u32::MAX {
                    continue;
                }
                // − Y Wᵀ over every pair of this point's observations, and + Y g_p.
                let w2 = layout.w_cols(&lin.w, o2, s2);
                for o1 in start..end {
                    for s1 in layout.segs(o1) {
                        if s1.block as usize <= b {
                            let y1 = layout.w_cols(y, o1, s1);
                            col.add(y1, w2, s1, s2, -1.0);
                        }
                    }
                }
                let y2 = layout.w_cols(y, o2, s2);
                let g = gp[f as usize];
                let base = layout.block_offset[b] + off2;
                for k in 0..l2 {
                    rhs[base + k] += y2[0][k] * g.x + y2[1][k] * g.y + y2[2][k] * g.z;
                }
            }
        }
    }
}

/// Block column b of S, inside the full value array.
struct Column<'a> {
    vals: &'a mut [f64],
    col_ptr: &'a [usize],
    v0: usize,
    rows: &'a [u32],
    roffs: &'a [usize],
    b: usize,
}

impl<'a> Column<'a> {
    #[inline(always)]
    fn new(layout: &'a Layout, vals: &'a mut [f64], b: usize) -> Self {
        let off_b = layout.block_offset[b];
        Column {
            vals,
            col_ptr: &layout.col_ptr[off_b..=off_b + layout.block_dim[b]],
            v0: 0,
            rows: &layout.col_blocks[b],
            roffs: &layout.col_row_off[b],
            b,
        }
    }

    /// Adds `scale · Σ_k left[k][i] · right[k][j]` to S[(block a, row off1 + i), (block b,
    /// col off2 + j)] for j < len2, upper triangle only: the rows are the segment
    /// `row_seg` (block a, offset off1), the columns the segment `col_seg` (block b, offset
    /// off2, len2 columns). Each column update is a contiguous axpy, which the compiler
    /// vectorizes.
    #[inline(always)]
    fn add<const K: usize>(
        &mut self,
        left: [&[f64]; K],
        right: [&[f64]; K],
        row_seg: &Seg,
        col_seg: &Seg,
        scale: f64,
    ) {
        debug_assert_eq!(
            col_seg.block as usize, self.b,
            "column segment of another block"
        );
        let (a, off1) = (row_seg.block, row_seg.block_off as usize);
        let (off2, len2) = (col_seg.block_off as usize, col_seg.len as usize);
        let ai = self
            .rows
            .binary_search(&a)
            .expect("block pair in the pattern");
        let roff = self.roffs[ai];
        let diag = a as usize == self.b;
        let len1 = left[0].len();
        let base = roff + off1;
        // Off-diagonal blocks of the common sizes go through fully unrolled kernels.
        if !diag {
            macro_rules! fixed {
                ($($m:literal x $n:literal),*) => {
                    match (len1, len2) {
                        $(($m, $n) => {
                            return self.add_fixed::<K, $m, $n, false>(left, right, base, off2, scale);
                        })*
                        _ => {}
                    }
                };
            }
            fixed!(9 x 9, 6 x 6, 6 x 9, 9 x 6);
        } else if off1 == off2 && len1 == len2 {
            match len1 {
                9 => return self.add_fixed::<K, 9, 9, true>(left, right, base, off2, scale),
                6 => return self.add_fixed::<K, 6, 6, true>(left, right, base, off2, scale),
                _ => {}
            }
        }
        // j walks column j of all K right-hand rows and of S together.
        #[allow(clippy::needless_range_loop)]
        for j in 0..len2 {
            let col = off2 + j;
            let start = self.col_ptr[col] - self.v0 + base;
            let n = if diag {
                len1.min((col + 1).saturating_sub(off1))
            } else {
                len1
            };
            let dst = &mut self.vals[start..start + n];
            let c: [f64; K] = std::array::from_fn(|k| scale * right[k][j]);
            for (i, d) in dst.iter_mut().enumerate() {
                let mut acc = 0.0;
                for k in 0..K {
                    acc += left[k][i] * c[k];
                }
                *d += acc;
            }
        }
    }

    /// A fixed-size block; with `UPPER` (a square block on the diagonal of S) only its
    /// upper triangle, which is all that is stored there.
    #[inline(always)]
    fn add_fixed<const K: usize, const M: usize, const N: usize, const UPPER: bool>(
        &mut self,
        left: [&[f64]; K],
        right: [&[f64]; K],
        base: usize,
        off2: usize,
        scale: f64,
    ) {
        let l: [[f64; M]; K] = std::array::from_fn(|k| left[k][..M].try_into().unwrap());
        let r: [[f64; N]; K] = std::array::from_fn(|k| right[k][..N].try_into().unwrap());
        // j walks column j of all K right-hand rows and of S together.
        #[allow(clippy::needless_range_loop)]
        for j in 0..N {
            let start = self.col_ptr[off2 + j] - self.v0 + base;
            let rows = if UPPER { j + 1 } else { M };
            let dst = &mut self.vals[start..start + rows];
            for (i, d) in dst.iter_mut().enumerate() {
                let mut acc = 0.0;
                for k in 0..K {
                    acc += l[k][i] * r[k][j];
                }
                *d += scale * acc;
            }
        }
    }
}
