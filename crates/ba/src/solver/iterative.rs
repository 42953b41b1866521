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
//! work and memory proportional to the observations: nothing of the size of S is
//! allocated. This is Ceres' `ITERATIVE_SCHUR` with `use_explicit_schur_complement =
//! false`.
//!
//! Where S is sparse, a product with S itself is cheaper: `4·nnz(S)` flops against about
//! `4·m_o + 16` per observation o with m_o camera-side columns, once S is assembled (by the
//! same code as the factorizations', once per step). On a street of cameras S has a few
//! neighbours per image and the explicit product is several times cheaper; on a dense camera
//! graph S is a large dense matrix and the implicit one wins. [`SchurProduct`] chooses
//! (by default from the estimates in `choice`), as Ceres' `use_explicit_schur_complement =
//! true` does by hand. With S formed, the preconditioner's cluster matrices are copied from
//! it.
//!
//! The preconditioner is S's exact block diagonal over clusters of blocks
//! ([`super::clusters`]), each `U_ab + λD_a δ_ab − Σ_f W_fa (V_f + λD_f)⁻¹ W_fbᵀ` for the
//! blocks a, b of one cluster, inverted once per step. With one block per cluster (one per
//! image, camera, rig or distance point) it is Schur–Jacobi; with clusters of images that
//! see the same points, cluster-Jacobi ([`Preconditioner`]).
//!
//! The iteration stops by Ceres' inexact-Newton rule (Nash and Sofer's "Q test"): with the
//! quadratic model `Q(x) = ½xᵀSx − bᵀx`, it stops at iteration i when
//! `i · (Q_i − Q_{i−1}) / Q_i < η` (η = 0.1 by default, as in Ceres), or when the residual
//! has fallen to `1e-12 · |b|`. An inexact step is still a descent step of the whole
//! problem (points are back-substituted exactly), and the trust region judges it by the
//! cost it achieves, as for an exact one.

use super::choice::{schur_product, ProductChoice, SchurProduct, TooLarge};
use super::clusters::{ClusterStats, Clusters};
use super::evaluate::{split_at_offsets, Linearization};
use super::layout::Layout;
use super::schur::Schur;
use nalgebra::{Vector2, Vector3};
use rayon::prelude::*;

/// Below this many stored values the preconditioner is applied on one thread.
const PARALLEL_PRECONDITION: usize = 1 << 16;

/// The preconditioner of the conjugate gradients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Preconditioner {
    /// S's diagonal blocks, one per image, camera, rig or reduced point (Ceres'
    /// `SCHUR_JACOBI`).
    SchurJacobi,
    /// S's block diagonal over clusters of blocks that see the same points, none of more
    /// than `max_dim` unknowns ([`super::clusters`]; Ceres' `CLUSTER_JACOBI`).
    ClusterJacobi {
        /// The most unknowns of one cluster (default [`super::clusters::DEFAULT_MAX_DIM`]).
        max_dim: usize,
    },
}

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
    /// The preconditioner (cluster-Jacobi by default, which is Schur–Jacobi where no two
    /// images see enough of the same points).
    pub preconditioner: Preconditioner,
    /// How S is applied (by default the cheaper form).
    pub product: SchurProduct,
}

impl Default for CgOptions {
    fn default() -> Self {
        Self {
            eta: 0.1,
            min_iterations: 0,
            max_iterations: 500,
            switch_after: 150,
            preconditioner: Preconditioner::ClusterJacobi {
                max_dim: super::clusters::DEFAULT_MAX_DIM,
            },
            product: SchurProduct::Auto,
        }
    }
}

/// The reduced system of one Levenberg–Marquardt step as an operator, applied implicitly
/// or explicitly, and its preconditioner.
pub(crate) struct SchurOperator {
    /// S is assembled each step and multiplied as a matrix ([`SchurProduct::Explicit`]).
    explicit: bool,
    /// The product and why.
    pub product: ProductChoice,
    /// With `explicit`: ranges of block columns of S, one per worker, of about equal
    /// numbers of stored values.
    column_chunks: Vec<(usize, usize)>,
    /// λ·clamp(diag(U)).
    damping: Vec<f64>,
    /// The clusters of blocks whose part of S the preconditioner keeps (one block each:
    /// Schur–Jacobi).
    clusters: Clusters,
    /// What the clustering did (`None`: Schur–Jacobi asked for).
    pub cluster_stats: Option<ClusterStats>,
    /// Per cluster c: the inverse of S restricted to its blocks, column-major
    /// `dim × dim`, starting at `clusters.offset[c]`.
    precond: Vec<f64>,
    /// One accumulator of the size of the reduced system per chunk of the work split
    /// (the Schur complement's observations, or `column_chunks`; sized by `prepare`).
    work: Vec<Vec<f64>>,
}

/// What one conjugate-gradient solve did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CgSummary {
    pub iterations: usize,
    /// |b − S x| / |b| at the end.
    pub relative_residual: f64,
}

impl SchurOperator {
    /// The operator for `layout` with `preconditioner` and `product` (under `Auto` chosen
    /// by `choice::schur_product` once the clusters are known). Cluster-Jacobi clusters
    /// whose matrices (one copy per worker and their sum) would not fit in `memory_limit`
    /// bytes are not used: the preconditioner is then Schur–Jacobi, and the statistics say
    /// why. Fails when the explicit product is asked for and S does not fit.
    pub fn new(
        layout: &Layout,
        preconditioner: Preconditioner,
        product: SchurProduct,
        workers: usize,
        memory_limit: Option<f64>,
    ) -> Result<Self, TooLarge> {
        let bytes = |c: &Clusters| 8.0 * c.storage() as f64 * (1 + workers.max(1)) as f64;
        let (clusters, cluster_stats) = match preconditioner {
            Preconditioner::SchurJacobi => (Clusters::singletons(layout), None),
            Preconditioner::ClusterJacobi { max_dim } => {
                let (c, mut stats) = Clusters::by_visibility(layout, max_dim);
                let limit = memory_limit.unwrap_or(f64::INFINITY);
                if bytes(&c) > limit && c.blocks.len() < layout.num_blocks() {
                    stats.too_large_bytes = bytes(&c);
                    (Clusters::singletons(layout), Some(stats))
                } else {
                    (c, Some(stats))
                }
            }
        };
        let product = schur_product(layout, &clusters, product, workers, memory_limit)?;
        let explicit = product.product == SchurProduct::Explicit;
        Ok(Self {
            explicit,
            product,
            column_chunks: if explicit {
                column_chunks(layout, workers.max(1))
            } else {
                Vec::new()
            },
            damping: vec![0.0; layout.n_reduced],
            // Allocated by the first step, after the caller has judged its size.
            precond: Vec::new(),
            clusters,
            cluster_stats,
            work: Vec::new(),
        })
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
        if self.explicit {
            schur.assemble(layout, lin, lambda)?;
            self.work.resize_with(self.column_chunks.len(), Vec::new);
            self.preconditioner_from_s(layout, &schur.values);
            return Ok(());
        }
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
        if self.explicit {
            self.apply_explicit(layout, &schur.values, x, y);
            return;
        }
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

    /// y = S x with S's assembled upper triangle (`values`, in the layout's order), both
    /// triangles applied: each worker takes a range of block columns, gathering
    /// `y_c = Σ_r S_rc x_r` and scattering `y_r += S_rc x_c` (r < c) into its own
    /// accumulator.
    fn apply_explicit(&mut self, layout: &Layout, values: &[f64], x: &[f64], y: &mut [f64]) {
        let n = layout.n_reduced;
        self.column_chunks
            .par_iter()
            .zip(self.work.par_iter_mut())
            .for_each(|(&(lo, hi), acc)| {
                acc.clear();
                acc.resize(n, 0.0);
                for b in lo..hi {
                    let (rows_of_b, row_off) = (&layout.col_blocks[b], &layout.col_row_off[b]);
                    for j in 0..layout.block_dim[b] {
                        let c = layout.block_offset[b] + j;
                        let (ptr, xc) = (layout.col_ptr[c], x[c]);
                        // The diagonal, the last value of the column.
                        let mut yc = values[layout.col_ptr[c + 1] - 1] * xc;
                        for (&a, &off) in rows_of_b.iter().zip(row_off) {
                            let a = a as usize;
                            // Strictly above the diagonal: block a's rows, or the first j
                            // rows of the diagonal block.
                            let len = if a == b { j } else { layout.block_dim[a] };
                            let r0 = layout.block_offset[a];
                            let v = &values[ptr + off..ptr + off + len];
                            yc += dot(v, &x[r0..r0 + len]);
                            axpy(xc, v, &mut acc[r0..r0 + len]);
                        }
                        acc[c] += yc;
                    }
                }
            });
        y.fill(0.0);
        sum_into(&self.work, y);
    }

    /// The preconditioner from the assembled S (damping and constraints included): each
    /// cluster's matrix copied from S's values, then inverted.
    fn preconditioner_from_s(&mut self, layout: &Layout, values: &[f64]) {
        let cl = &self.clusters;
        self.precond.clear();
        self.precond.resize(cl.storage(), 0.0);
        let matrices = split_at_offsets(&mut self.precond, &cl.offset[..cl.offset.len() - 1]);
        let par = inversion_par(cl);
        matrices.into_par_iter().enumerate().for_each(|(c, m)| {
            let dc = cl.dim[c];
            for &b in &cl.blocks[c] {
                let b = b as usize;
                let rows_of_b = layout.col_blocks[b].iter().zip(&layout.col_row_off[b]);
                for (&a, &off) in rows_of_b.filter(|(&a, _)| cl.together(a, b as u32)) {
                    let a = a as usize;
                    let (row0, col0) = (cl.local[a], cl.local[b]);
                    for j in 0..layout.block_dim[b] {
                        let ptr = layout.col_ptr[layout.block_offset[b] + j] + off;
                        let rows = if a == b { j + 1 } else { layout.block_dim[a] };
                        for (i, &v) in values[ptr..ptr + rows].iter().enumerate() {
                            m[(col0 + j) * dc + row0 + i] = v;
                            m[(row0 + i) * dc + col0 + j] = v;
                        }
                    }
                }
            }
            invert_spd(m, par);
        });
    }

    /// S's block diagonal over the clusters, each block inverted.
    fn build_preconditioner(&mut self, schur: &Schur, layout: &Layout, lin: &Linearization) {
        let cl = &self.clusters;
        let parts: Vec<Vec<f64>> = schur
            .chunks
            .par_iter()
            .map(|&(lo, hi)| {
                let mut blocks = vec![0.0; cl.storage()];
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
                            let c = cl.of_block[b] as usize;
                            let dc = cl.dim[c];
                            let m = &mut blocks[cl.offset[c]..cl.offset[c] + dc * dc];
                            let col0 = cl.local[b] + s2.block_off as usize;
                            let (a0, a1) = layout.jc_rows(&lin.jc, o, s2);
                            for s1 in segs.iter().filter(|s1| cl.together(s1.block, s2.block)) {
                                let row0 = cl.local[s1.block as usize] + s1.block_off as usize;
                                let (l0, l1) = layout.jc_rows(&lin.jc, o, s1);
                                for (j, (&c0, &c1)) in a0.iter().zip(a1).enumerate() {
                                    let col = &mut m[(col0 + j) * dc + row0..];
                                    for (v, (&r0, &r1)) in col.iter_mut().zip(l0.iter().zip(l1)) {
                                        *v += r0 * c0 + r1 * c1;
                                    }
                                }
                            }
                            if f == u32::MAX {
                                continue;
                            }
                            let d = layout.block_dim[b];
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
                        for &(b2, at2) in &touched {
                            let (b2u, d2) = (b2 as usize, layout.block_dim[b2 as usize]);
                            let c = cl.of_block[b2u] as usize;
                            let dc = cl.dim[c];
                            let ws2 = &wsum[at2..at2 + 3 * d2];
                            let col0 = cl.local[b2u];
                            for &(b1, at1) in touched.iter().filter(|t| cl.together(t.0, b2)) {
                                let d1 = layout.block_dim[b1 as usize];
                                let ws1 = &wsum[at1..at1 + 3 * d1];
                                let row0 = cl.local[b1 as usize];
                                let m = &mut blocks[cl.offset[c]..cl.offset[c] + dc * dc];
                                // M[b1, b2] −= Ws₁ (V + λD)⁻¹ Ws₂ᵀ, Ws column k at ws[k d ..].
                                for j in 0..d2 {
                                    let t: [f64; 3] = std::array::from_fn(|k| {
                                        (0..3).map(|q| vi[(k, q)] * ws2[q * d2 + j]).sum()
                                    });
                                    let col = &mut m[(col0 + j) * dc + row0..][..d1];
                                    for (i, v) in col.iter_mut().enumerate() {
                                        *v -= ws1[i] * t[0]
                                            + ws1[d1 + i] * t[1]
                                            + ws1[2 * d1 + i] * t[2];
                                    }
                                }
                            }
                        }
                    }
                }
                blocks
            })
            .collect();
        self.precond.clear();
        self.precond.resize(cl.storage(), 0.0);
        sum_into(&parts, &mut self.precond);
        for (b, &off) in layout.block_offset.iter().enumerate() {
            let c = cl.of_block[b] as usize;
            let (dc, base) = (cl.dim[c], cl.offset[c] + cl.local[b] * (cl.dim[c] + 1));
            for i in 0..layout.block_dim[b] {
                self.precond[base + i * (dc + 1)] += self.damping[off + i];
            }
        }
        super::constraints::add_to_cluster_blocks(layout, lin, cl, &mut self.precond);
        // Invert each cluster's matrix; one that is not positive definite (possible only
        // through rounding) falls back to its diagonal. A few large clusters get the
        // threads within each inversion, many small ones one thread each.
        let blocks = split_at_offsets(&mut self.precond, &cl.offset[..cl.offset.len() - 1]);
        let par = inversion_par(cl);
        blocks.into_par_iter().for_each(|blk| invert_spd(blk, par));
    }

    /// z = M⁻¹ r, cluster by cluster (gathering each cluster's blocks' rows). Each M⁻¹
    /// is symmetric, so its row i is read as its column i, contiguously.
    fn precondition(&self, layout: &Layout, r: &[f64], z: &mut [f64]) {
        let cl = &self.clusters;
        let one = |c: usize, rc: &mut Vec<f64>, zc: &mut Vec<f64>| {
            let d = cl.dim[c];
            let m = &self.precond[cl.offset[c]..cl.offset[c] + d * d];
            rc.clear();
            for &b in &cl.blocks[c] {
                let (off, db) = (
                    layout.block_offset[b as usize],
                    layout.block_dim[b as usize],
                );
                rc.extend_from_slice(&r[off..off + db]);
            }
            zc.clear();
            zc.extend(m.chunks_exact(d).map(|row| dot(row, rc)));
        };
        let scatter = |c: usize, zc: &[f64], z: &mut [f64]| {
            for &b in &cl.blocks[c] {
                let (off, db) = (
                    layout.block_offset[b as usize],
                    layout.block_dim[b as usize],
                );
                let row0 = cl.local[b as usize];
                z[off..off + db].copy_from_slice(&zc[row0..row0 + db]);
            }
        };
        if cl.storage() < PARALLEL_PRECONDITION {
            let (mut rc, mut zc) = (Vec::new(), Vec::new());
            for c in 0..cl.blocks.len() {
                one(c, &mut rc, &mut zc);
                scatter(c, &zc, z);
            }
        } else {
            let parts: Vec<Vec<f64>> = (0..cl.blocks.len())
                .into_par_iter()
                .map_init(Vec::new, |rc, c| {
                    let mut zc = Vec::new();
                    one(c, rc, &mut zc);
                    zc
                })
                .collect();
            for (c, zc) in parts.iter().enumerate() {
                scatter(c, zc, z);
            }
        }
    }

    #[cfg(test)]
    pub fn clusters_for_test(&self) -> &Clusters {
        &self.clusters
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

/// The threads within each cluster's inversion: all of them for fewer clusters than
/// threads, one otherwise (the clusters then run side by side).
fn inversion_par(cl: &Clusters) -> faer::Par {
    if cl.blocks.len() < rayon::current_num_threads() {
        faer::Par::rayon(0)
    } else {
        faer::Par::Seq
    }
}

/// Ranges of block columns of S with about `1/workers` of its stored values each.
fn column_chunks(layout: &Layout, workers: usize) -> Vec<(usize, usize)> {
    let nnz = layout.nnz();
    let mut bounds = vec![0];
    let mut next = 1;
    for b in 0..layout.num_blocks() {
        let end = layout.col_ptr[layout.block_offset[b] + layout.block_dim[b]];
        if next < workers && end * workers >= next * nnz {
            bounds.push(b + 1);
            next += 1;
        }
    }
    bounds.push(layout.num_blocks());
    bounds.dedup();
    bounds.windows(2).map(|w| (w[0], w[1])).collect()
}

/// Replaces the column-major symmetric `d × d` matrix `m` (its lower triangle is read) by
/// its inverse, both triangles, through faer's blocked Cholesky factorization. A matrix
/// that is not numerically positive definite is replaced by the inverse of its diagonal
/// (zero where the diagonal is not positive).
fn invert_spd(m: &mut [f64], par: faer::Par) {
    let d = (m.len() as f64).sqrt().round() as usize;
    let diagonal: Vec<f64> = (0..d).map(|i| m[i * d + i]).collect();
    let inverse = super::linear::cholesky_inverse(
        faer::MatMut::from_column_major_slice_mut(m, d, d),
        par,
        0.0,
    );
    let factored = inverse.is_ok();
    if let Ok(inv) = inverse {
        for j in 0..d {
            for i in j..d {
                let v = inv[(i, j)];
                m[j * d + i] = v;
                m[i * d + j] = v;
            }
        }
    }
    if !factored || !m.iter().all(|v| v.is_finite()) {
        m.fill(0.0);
        for (i, v) in diagonal.into_iter().enumerate() {
            m[i * d + i] = if v > 0.0 { 1.0 / v } else { 0.0 };
        }
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
