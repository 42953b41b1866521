//! Preconditioned conjugate gradients on the reduced camera system, with S never formed.
//!
//! With the notation of `schur` (U the camera-side block of JᵀJ, W = J_cᵀJ_p, V the
//! point blocks, λD the Levenberg–Marquardt damping),
//!
//! ```text
//! S x = (U + λD_c) x − W (V + λD_p)⁻¹ Wᵀ x
//!     = Σ_o J_oᵀ (z_o − J_p,o s_f) + λD_c x + (distances, control)  with
//! z_o = J_c,o x,   s_f = (V_f + λD_f)⁻¹ Σ_{o ∈ f} J_p,oᵀ z_o,
//! ```
//!
//! one pass over the observations, grouped by point (the solver's internal order), with
//! work and memory proportional to the observations: nothing of the size of S is ever
//! allocated. This is Ceres' `ITERATIVE_SCHUR` with `use_explicit_schur_complement =
//! false`.
//!
//! The preconditioner is Schur–Jacobi: the exact diagonal blocks of S (one per image,
//! camera, rig or distance point), each `U_bb + λD_b − Σ_f W_fb (V_f + λD_f)⁻¹ W_fbᵀ`,
//! inverted once per step.
//!
//! The iteration stops by Ceres' inexact-Newton rule (Nash and Sofer's "Q test"): with the
//! quadratic model `Q(x) = ½xᵀSx − bᵀx`, it stops at iteration i when
//! `i · (Q_i − Q_{i−1}) / Q_i < η` (η = 0.1 by default, as in Ceres), or when the residual
//! has fallen to `1e-12 · |b|`. An inexact step is still a descent step of the whole
//! problem (points are back-substituted exactly), and the trust region judges it by the
//! cost it achieves, as for an exact one.

use super::evaluate::{split_at_offsets, Linearization};
use super::layout::Layout;
use super::schur::Schur;
use nalgebra::{DMatrix, Vector2, Vector3};
use rayon::prelude::*;

/// The options of the conjugate-gradient solve.
#[derive(Clone, Copy, Debug)]
pub struct CgOptions {
    /// The forcing constant η of the Q test (Ceres' `eta`).
    pub eta: f64,
    /// Fewest iterations (Ceres' `min_linear_solver_iterations`).
    pub min_iterations: usize,
    /// Most iterations (Ceres' `max_linear_solver_iterations`).
    pub max_iterations: usize,
    /// When the solver was chosen by `Auto` and a factorization fits in memory: a step that
    /// needs more iterations than this moves the adjustment to the factorization.
    pub switch_after: usize,
}

impl Default for CgOptions {
    fn default() -> Self {
        Self {
            eta: 0.1,
            min_iterations: 0,
            max_iterations: 500,
            switch_after: 150,
        }
    }
}

/// The implicit reduced system of one Levenberg–Marquardt step and its preconditioner.
pub(crate) struct ImplicitSchur {
    /// λ·clamp(diag(U)).
    damping: Vec<f64>,
    /// Per block b: the inverse of its diagonal block of S, column-major `dim × dim`,
    /// starting at `precond_offset[b]`.
    precond: Vec<f64>,
    precond_offset: Vec<usize>,
    /// One accumulator of the size of the reduced system per chunk of the Schur
    /// complement's work split (sized by `prepare`).
    work: Vec<Vec<f64>>,
}

/// What one conjugate-gradient solve did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CgSummary {
    pub iterations: usize,
    /// |b − S x| / |b| at the end.
    pub relative_residual: f64,
}

impl ImplicitSchur {
    pub fn new(layout: &Layout) -> Self {
        let mut precond_offset = Vec::with_capacity(layout.num_blocks() + 1);
        let mut acc = 0;
        for &d in &layout.block_dim {
            precond_offset.push(acc);
            acc += d * d;
        }
        precond_offset.push(acc);
        Self {
            damping: vec![0.0; layout.n_reduced],
            precond: vec![0.0; acc],
            precond_offset,
            work: Vec::new(),
        }
    }

    /// Prepares the step for damping `lambda`: (V + λD)⁻¹ of every point, the right-hand
    /// side `schur.rhs` (as the explicit assembly gives it) and the preconditioner. Fails
    /// with the free-point index of a point block that is not positive definite.
    pub fn prepare(
        &mut self,
        schur: &mut Schur,
        layout: &Layout,
        lin: &Linearization,
        lambda: f64,
    ) -> Result<(), usize> {
        schur.invert_points(lambda)?;
        self.work.resize_with(schur.chunks.len(), Vec::new);
        self.damping = schur.damping(lambda);
        // b = −g_c + Σ_f W_f (V_f + λD_f)⁻¹ g_p,f = −g_c + Σ_o J_c,oᵀ J_p,o s_f.
        let s: Vec<Vector3<f64>> = (schur.vinv.par_iter().zip(&schur.gp))
            .map(|(vi, g)| vi * g)
            .collect();
        let mut b = vec![0.0; layout.n_reduced];
        self.accumulate(layout, &lin.jc, &schur.chunks, &mut b, |o| {
            let f = layout.free_point_index[layout.obs_point[o] as usize];
            if f == u32::MAX {
                Vector2::zeros()
            } else {
                lin.jp[o] * s[f as usize]
            }
        });
        for (bk, g) in b.iter_mut().zip(&schur.gc) {
            *bk -= g;
        }
        schur.rhs.copy_from_slice(&b);
        self.build_preconditioner(schur, layout, lin);
        Ok(())
    }

    /// `sum += Σ_o J_c,oᵀ u(o)` over every observation; parallel over the chunks.
    fn accumulate(
        &mut self,
        layout: &Layout,
        jc: &[f64],
        chunks: &[(usize, usize)],
        sum: &mut [f64],
        u: impl Fn(usize) -> Vector2<f64> + Sync,
    ) {
        let n = layout.n_reduced;
        chunks
            .par_iter()
            .zip(self.work.par_iter_mut())
            .for_each(|(&(lo, hi), acc)| {
                acc.clear();
                acc.resize(n, 0.0);
                for o in lo..hi {
                    add_jc_transpose(layout, jc, o, u(o), acc);
                }
            });
        sum_into(&self.work, sum);
    }

    /// y = S x.
    pub fn apply(
        &mut self,
        schur: &Schur,
        layout: &Layout,
        lin: &Linearization,
        x: &[f64],
        y: &mut [f64],
    ) {
        let n = layout.n_reduced;
        let jc = &lin.jc;
        schur
            .chunks
            .par_iter()
            .zip(self.work.par_iter_mut())
            .for_each(|(&(lo, hi), acc)| {
                acc.clear();
                acc.resize(n, 0.0);
                let mut z: Vec<Vector2<f64>> = Vec::new();
                for (point, run) in layout.point_runs(lo..hi) {
                    let (start, end) = (run.start, run.end);
                    z.clear();
                    z.extend((start..end).map(|o| jc_times(layout, jc, o, x)));
                    let f = layout.free_point_index[point as usize];
                    if f != u32::MAX {
                        let t: Vector3<f64> = (start..end)
                            .zip(&z)
                            .map(|(o, zo)| lin.jp[o].transpose() * zo)
                            .sum();
                        let s = schur.vinv[f as usize] * t;
                        for (o, zo) in (start..end).zip(z.iter_mut()) {
                            *zo -= lin.jp[o] * s;
                        }
                    }
                    for (o, zo) in (start..end).zip(&z) {
                        add_jc_transpose(layout, jc, o, *zo, acc);
                    }
                }
            });
        y.fill(0.0);
        sum_into(&self.work, y);
        for ((yk, xk), d) in y.iter_mut().zip(x).zip(&self.damping) {
            *yk += d * xk;
        }
        // The constraints between blocks of the reduced system.
        super::constraints::add_product(layout, lin, x, y);
    }

    /// The diagonal blocks of S, inverted.
    fn build_preconditioner(&mut self, schur: &Schur, layout: &Layout, lin: &Linearization) {
        let offsets = &self.precond_offset;
        let total = *offsets.last().unwrap();
        let parts: Vec<Vec<f64>> = schur
            .chunks
            .par_iter()
            .map(|&(lo, hi)| {
                let mut blocks = vec![0.0; total];
                // Per point run: Σ_o W_o restricted to each block it touches (dim × 3).
                let mut touched: Vec<(u32, usize)> = Vec::new();
                let mut wsum: Vec<f64> = Vec::new();
                for (point, run) in layout.point_runs(lo..hi) {
                    let f = layout.free_point_index[point as usize];
                    touched.clear();
                    wsum.clear();
                    for o in run {
                        let segs = layout.segs(o);
                        for s2 in segs {
                            let b = s2.block as usize;
                            let d = layout.block_dim[b];
                            let blk = &mut blocks[offsets[b]..offsets[b] + d * d];
                            let (a0, a1) = layout.jc_rows(&lin.jc, o, s2);
                            for s1 in segs.iter().filter(|s1| s1.block == s2.block) {
                                let (l0, l1) = layout.jc_rows(&lin.jc, o, s1);
                                for (j, (&c0, &c1)) in a0.iter().zip(a1).enumerate() {
                                    let col = &mut blk[(s2.block_off as usize + j) * d..];
                                    for (i, (&r0, &r1)) in l0.iter().zip(l1).enumerate() {
                                        col[s1.block_off as usize + i] += r0 * c0 + r1 * c1;
                                    }
                                }
                            }
                            if f == u32::MAX {
                                continue;
                            }
                            let at = match touched.iter().find(|t| t.0 == s2.block) {
                                Some(t) => t.1,
                                None => {
                                    touched.push((s2.block, wsum.len()));
                                    wsum.resize(wsum.len() + 3 * d, 0.0);
                                    wsum.len() - 3 * d
                                }
                            };
                            let w = layout.w_cols(&lin.w, o, s2);
                            for (m, wm) in w.iter().enumerate() {
                                let dst = &mut wsum[at + m * d + s2.block_off as usize..];
                                for (dv, wv) in dst.iter_mut().zip(wm.iter()) {
                                    *dv += wv;
                                }
                            }
                        }
                    }
                    if f != u32::MAX {
                        let vi = &schur.vinv[f as usize];
                        for &(b, at) in &touched {
                            let b = b as usize;
                            let d = layout.block_dim[b];
                            let ws = &wsum[at..at + 3 * d];
                            let blk = &mut blocks[offsets[b]..offsets[b] + d * d];
                            // B −= Ws (V + λD)⁻¹ Wsᵀ, Ws column m at ws[m d ..].
                            for j in 0..d {
                                let c: [f64; 3] = std::array::from_fn(|m| {
                                    (0..3).map(|q| vi[(m, q)] * ws[q * d + j]).sum()
                                });
                                let col = &mut blk[j * d..(j + 1) * d];
                                for (i, v) in col.iter_mut().enumerate() {
                                    *v -= ws[i] * c[0] + ws[d + i] * c[1] + ws[2 * d + i] * c[2];
                                }
                            }
                        }
                    }
                }
                blocks
            })
            .collect();
        self.precond.fill(0.0);
        sum_into(&parts, &mut self.precond);
        let diag = |b: usize, i: usize, v: f64, p: &mut [f64]| {
            let d = layout.block_dim[b];
            p[offsets[b] + i * d + i] += v;
        };
        for (b, &off) in layout.block_offset.iter().enumerate() {
            for i in 0..layout.block_dim[b] {
                diag(b, i, self.damping[off + i], &mut self.precond);
            }
        }
        super::constraints::add_to_diagonal_blocks(layout, lin, offsets, &mut self.precond);
        // Invert each block; one that is not positive definite (possible only through
        // rounding) falls back to its diagonal.
        let blocks = split_at_offsets(&mut self.precond, &offsets[..offsets.len() - 1]);
        blocks.into_par_iter().for_each(|blk| {
            let d = (blk.len() as f64).sqrt().round() as usize;
            let m = DMatrix::from_column_slice(d, d, blk);
            match m.clone().cholesky() {
                Some(c) => blk.copy_from_slice(c.inverse().as_slice()),
                None => {
                    for j in 0..d {
                        for i in 0..d {
                            let v = m[(i, i)];
                            blk[j * d + i] = if i == j && v > 0.0 { 1.0 / v } else { 0.0 };
                        }
                    }
                }
            }
        });
    }

    /// z = M⁻¹ r.
    fn precondition(&self, layout: &Layout, r: &[f64], z: &mut [f64]) {
        for (b, &off) in layout.block_offset.iter().enumerate() {
            let d = layout.block_dim[b];
            let m = &self.precond[self.precond_offset[b]..self.precond_offset[b] + d * d];
            let rb = &r[off..off + d];
            for (i, zi) in z[off..off + d].iter_mut().enumerate() {
                *zi = (0..d).map(|j| m[j * d + i] * rb[j]).sum();
            }
        }
    }

    #[cfg(test)]
    pub fn precondition_for_test(&self, layout: &Layout, r: &[f64], z: &mut [f64]) {
        self.precondition(layout, r, z)
    }

    /// Solves S x = `schur.rhs` approximately (the forcing rule of the module doc),
    /// starting from x = 0. Returns `None` when S is found not positive definite.
    pub fn solve(
        &mut self,
        schur: &Schur,
        layout: &Layout,
        lin: &Linearization,
        options: &CgOptions,
        x: &mut [f64],
    ) -> Option<CgSummary> {
        let n = layout.n_reduced;
        let b = &schur.rhs;
        x.fill(0.0);
        let b_norm = norm(b);
        if n == 0 || b_norm == 0.0 {
            return Some(CgSummary::default());
        }
        let mut r = b.clone();
        let mut z = vec![0.0; n];
        let mut q = vec![0.0; n];
        self.precondition(layout, &r, &mut z);
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let mut q_prev = 0.0;
        let mut summary = CgSummary {
            iterations: 0,
            relative_residual: 1.0,
        };
        for i in 1..=options.max_iterations {
            self.apply(schur, layout, lin, &p, &mut q);
            let pq = dot(&p, &q);
            if !(pq > 0.0) {
                // Not positive definite along p (or not finite).
                return (i > 1 && pq.is_finite()).then_some(summary);
            }
            let alpha = rz / pq;
            axpy(alpha, &p, x);
            axpy(-alpha, &q, &mut r);
            summary.iterations = i;
            summary.relative_residual = norm(&r) / b_norm;
            // Q(x) = ½xᵀSx − bᵀx = −½ xᵀ(b + r).
            let q_now = -0.5
                * x.iter()
                    .zip(b)
                    .zip(&r)
                    .map(|((x, b), r)| x * (b + r))
                    .sum::<f64>();
            let zeta = i as f64 * (q_now - q_prev) / q_now;
            q_prev = q_now;
            if i >= options.min_iterations
                && (zeta < options.eta || summary.relative_residual <= 1e-12)
            {
                break;
            }
            self.precondition(layout, &r, &mut z);
            let rz_new = dot(&r, &z);
            let beta = rz_new / rz;
            rz = rz_new;
            for (pk, zk) in p.iter_mut().zip(&z) {
                *pk = zk + beta * *pk;
            }
        }
        x.iter().all(|v| v.is_finite()).then_some(summary)
    }
}

/// J_c,o x: the observation's camera-side Jacobian times the reduced-system vector.
#[inline]
fn jc_times(layout: &Layout, jc: &[f64], o: usize, x: &[f64]) -> Vector2<f64> {
    let mut z = Vector2::zeros();
    for s in layout.segs(o) {
        let base = layout.block_offset[s.block as usize] + s.block_off as usize;
        let (j0, j1) = layout.jc_rows(jc, o, s);
        let xs = &x[base..base + s.len as usize];
        for ((a, b), v) in j0.iter().zip(j1).zip(xs) {
            z.x += a * v;
            z.y += b * v;
        }
    }
    z
}

/// acc[segments of o] += J_c,oᵀ u.
#[inline]
fn add_jc_transpose(layout: &Layout, jc: &[f64], o: usize, u: Vector2<f64>, acc: &mut [f64]) {
    for s in layout.segs(o) {
        let base = layout.block_offset[s.block as usize] + s.block_off as usize;
        let (j0, j1) = layout.jc_rows(jc, o, s);
        for ((a, b), y) in j0.iter().zip(j1).zip(&mut acc[base..base + s.len as usize]) {
            *y += a * u.x + b * u.y;
        }
    }
}

fn sum_into(parts: &[Vec<f64>], out: &mut [f64]) {
    out.par_chunks_mut(1 << 14)
        .enumerate()
        .for_each(|(c, dst)| {
            let base = c << 14;
            for p in parts {
                if p.len() >= base + dst.len() {
                    dst.iter_mut().zip(&p[base..]).for_each(|(a, b)| *a += b);
                }
            }
        });
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += alpha * x);
}
