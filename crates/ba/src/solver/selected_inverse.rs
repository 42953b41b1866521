//! The entries of S⁻¹ that the precision needs, for a reduced system too large to invert
//! densely: a sparse Cholesky factorization and the *selected inversion* of Takahashi,
//! Fagan and Chen (1973), which computes `Z = S⁻¹` on the pattern of the factor only.
//!
//! With the Jacobi-scaled, fill-reducing permuted system `A = P D S D Pᵀ = L Lᵀ`
//! (D = diag(1/√S_ii), P from the block AMD ordering that the solver also uses),
//! `Z = A⁻¹ = L⁻ᵀ L⁻¹` satisfies, column by column from the last (Rⱼ the rows of column j
//! of L below its diagonal):
//!
//! ```text
//!   Z_ij = −(1/L_jj) Σ_{k∈Rⱼ} Z_ik L_kj            (i ∈ Rⱼ)
//!   Z_jj = (1/L_jj) (1/L_jj − Σ_{k∈Rⱼ} L_kj Z_kj)
//! ```
//!
//! and every Z_ik it reads (i, k ∈ Rⱼ) lies in the pattern of L, because the rows of a
//! column of L form a clique of the filled graph. The pattern of L contains that of S, and
//! so every pair of unknowns that share an observation, a point or a constraint: exactly
//! the entries of which σ's, eliminated points' cofactors and redundancy numbers are made.
//! An entry outside the pattern (joint covariances of far-apart points, say) is computed by
//! solving with the factor: one column of S⁻¹ at the cost of two triangular solves.
//!
//! The work is Σⱼ Σ_{k∈Rⱼ} |column k|, about the cost of the factorization on a sparse
//! (banded) camera graph; on a dense one the factor is full and it grows as n³, which
//! [`SelectedInverse::new`] estimates from the symbolic factorization and refuses, with
//! the figures, above [`MAX_SELECTED_WORK`] or the memory limit.
//!
//! A minimal datum is given as *held* unknowns: their rows and columns of S are replaced
//! by those of the identity before factorizing, and their rows and columns of S⁻¹ are 0 (a
//! reflexive generalized inverse of the singular S, which the S-transformation of a free
//! network starts from).

use super::layout::Layout;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::solvers::LltError;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};
use nalgebra::DMatrix;

/// Most work (multiply-adds, estimated from the factor's pattern) a selected inversion may
/// take: about a minute on one core.
pub const MAX_SELECTED_WORK: f64 = 1e11;

/// Smallest pivot `L_jj²` of the Jacobi-scaled system (unit diagonal) taken as determined:
/// below it the unknown is a combination of the others to 1e-6 of its own scale.
const MIN_PIVOT: f64 = 1e-12;

/// Entries of a cofactor matrix of the reduced unknowns (dense, or selected).
pub(crate) trait CofactorLookup {
    /// Entry (i, j).
    fn at(&self, i: usize, j: usize) -> f64;

    /// The submatrix on `rows` × `rows`.
    fn restricted(&self, rows: &[usize]) -> DMatrix<f64> {
        DMatrix::from_fn(rows.len(), rows.len(), |a, b| self.at(rows[a], rows[b]))
    }
}

/// A cofactor matrix of S under held unknowns that can also apply itself: `x ← S⁻¹ x`.
pub(crate) trait Factored: CofactorLookup {
    /// `x ← S⁻¹ x` (held unknowns' entries ignored, and 0 on return).
    fn solve_in_place(&self, x: &mut [f64]);
}

impl CofactorLookup for DMatrix<f64> {
    #[inline]
    fn at(&self, i: usize, j: usize) -> f64 {
        self[(i, j)]
    }
}

/// Why a selected inversion cannot be made.
#[derive(Debug)]
pub(crate) enum SelectedError {
    /// S is not positive definite (or nearly singular) at this unknown (reduced index).
    NotPositive(usize),
    /// The factor would need more than the limits allow.
    TooLarge {
        /// Estimated bytes.
        bytes: f64,
        /// Estimated multiply-adds.
        work: f64,
        /// Nonzeros of the factor.
        factor_entries: usize,
    },
    /// faer refused the pattern (not expected for a layout's pattern).
    Internal(String),
}

/// D's diagonal, 1/√S_ii from S's values in the layout's order (1 for a held unknown).
pub(crate) fn jacobi_scale(layout: &Layout, values: &[f64], held: &[bool]) -> Vec<f64> {
    (0..layout.n_reduced)
        .map(|c| match held[c] {
            true => 1.0,
            false => jacobi_factor(layout.diagonal(values, c)),
        })
        .collect()
}

/// `1/√S_cc`, the Jacobi scale of one unknown of diagonal `s_cc` (a diagonal that is not
/// positive is taken as the smallest positive number).
#[inline]
pub(crate) fn jacobi_factor(s_cc: f64) -> f64 {
    1.0 / s_cc.max(f64::MIN_POSITIVE).sqrt()
}

/// Entry (i, j) of D S D with the held unknowns' rows and columns those of the identity.
#[inline]
fn scaled_entry(i: usize, j: usize, v: f64, scale: &[f64], held: &[bool]) -> f64 {
    match (held[i] || held[j], i == j) {
        (true, true) => 1.0,
        (true, false) => 0.0,
        (false, _) => v * scale[i] * scale[j],
    }
}

/// The selected inversion's refusal judged from the block pattern alone, before S is
/// assembled: the factor's entries and the work `Σⱼ |column j|²` from a symbolic
/// factorization of the block graph ([`block_factor_columns`](super::linear::block_factor_columns)),
/// its memory as [`SelectedInverse::new`] counts it plus S's values.
pub(crate) fn precheck(layout: &Layout, memory_limit: Option<f64>) -> Result<f64, SelectedError> {
    let Some((entries, work)) = super::linear::block_factor_columns(layout) else {
        return Ok(0.0);
    };
    let bytes = 32.0 * entries + 32.0 * layout.nnz() as f64;
    if work > MAX_SELECTED_WORK || memory_limit.is_some_and(|m| bytes > m) {
        return Err(SelectedError::TooLarge {
            bytes,
            work,
            factor_entries: entries as usize,
        });
    }
    Ok(work)
}

/// S⁻¹ on the pattern of S, and the factor to compute any other entry.
pub(crate) struct SelectedInverse {
    n: usize,
    /// D's diagonal, 1/√S_ii (1 for a held unknown).
    scale: Vec<f64>,
    held: Vec<bool>,
    /// Original index of permuted position k, and the inverse.
    perm_fwd: Vec<usize>,
    perm_inv: Vec<usize>,
    /// L (simplicial CSC, rows sorted, the diagonal first in each column).
    l_col_ptr: Vec<usize>,
    l_row_idx: Vec<usize>,
    l: Vec<f64>,
    /// S⁻¹ (unscaled, held rows and columns 0) in the order of S's values.
    z: Vec<f64>,
    /// Block of each scalar unknown, and the layout's block pattern (to find an entry).
    block_of: Vec<u32>,
    block_offset: Vec<usize>,
    col_blocks: Vec<Vec<u32>>,
    col_row_off: Vec<Vec<usize>>,
    col_ptr: Vec<usize>,
}

impl SelectedInverse {
    /// Factorizes S (its upper triangle `values` in the layout's order) with the unknowns
    /// `held` replaced by identity rows, and computes S⁻¹ on S's pattern; refused above
    /// `memory_limit` bytes (`None`: no limit known) or [`MAX_SELECTED_WORK`].
    pub fn new(
        layout: &Layout,
        values: &[f64],
        held: &[bool],
        memory_limit: Option<f64>,
        par: Par,
    ) -> Result<Self, SelectedError> {
        let n = layout.n_reduced;
        let scale = jacobi_scale(layout, values, held);
        let scaled: Vec<f64> = (layout.entries().zip(values))
            .map(|((i, j), &v)| scaled_entry(i, j, v, &scale, held))
            .collect();
        let row_idx = layout.row_indices();
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &layout.col_ptr, None, &row_idx);
        let (perm_fwd, perm_inv) = super::linear::block_amd_ordering(layout)?;
        let perm = faer::perm::PermRef::new_checked(&perm_fwd, &perm_inv, n);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
            ..Default::default()
        };
        let symbolic =
            factorize_symbolic_cholesky(sym, Side::Upper, SymmetricOrdering::Custom(perm), params)
                .map_err(|e| SelectedError::Internal(format!("{e:?}")))?;
        let SymbolicCholeskyRaw::Simplicial(simplicial) = symbolic.raw() else {
            return Err(SelectedError::Internal("not a simplicial factor".into()));
        };
        let l_col_ptr: Vec<usize> = simplicial.col_ptr().to_vec();
        let factor_entries = symbolic.len_val();
        let work: f64 = (0..n)
            .map(|j| {
                let c = (l_col_ptr[j + 1] - l_col_ptr[j]) as f64;
                c * c
            })
            .sum();
        // L, Z on L's pattern, its row indices (faer's and ours), and S's scaled copy, row
        // indices and Z.
        let bytes = 32.0 * factor_entries as f64 + 24.0 * values.len() as f64;
        if work > MAX_SELECTED_WORK || memory_limit.is_some_and(|m| bytes > m) {
            return Err(SelectedError::TooLarge {
                bytes,
                work,
                factor_entries,
            });
        }
        let l_row_idx: Vec<usize> = simplicial.row_idx().to_vec();
        let mut l = vec![0.0; factor_entries];
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mut mem = MemBuffer::new(req);
        let a = SparseColMatRef::new(sym, &scaled);
        match symbolic.factorize_numeric_llt::<f64>(
            &mut l,
            a,
            Side::Upper,
            Default::default(),
            par,
            MemStack::new(&mut mem),
            Default::default(),
        ) {
            Ok(_) => {}
            Err(LltError::NonPositivePivot { index }) => {
                return Err(SelectedError::NotPositive(perm_fwd[index]))
            }
        }
        if let Some(j) = (0..n).find(|&j| {
            let d = l[l_col_ptr[j]];
            !(d * d >= MIN_PIVOT)
        }) {
            return Err(SelectedError::NotPositive(perm_fwd[j]));
        }
        let zl = takahashi(&l_col_ptr, &l_row_idx, &l);
        let mut block_of = vec![0u32; n];
        for b in 0..layout.num_blocks() {
            let o = layout.block_offset[b];
            block_of[o..o + layout.block_dim[b]].fill(b as u32);
        }
        let find = |r: usize, c: usize| -> f64 {
            let (s, e) = (l_col_ptr[c], l_col_ptr[c + 1]);
            match l_row_idx[s..e].binary_search(&r) {
                Ok(k) => zl[s + k],
                Err(_) => unreachable!("S's pattern lies in the factor's"),
            }
        };
        let z: Vec<f64> = layout
            .entries()
            .map(|(i, j)| {
                if held[i] || held[j] {
                    return 0.0;
                }
                let (pi, pj) = (perm_inv[i], perm_inv[j]);
                find(pi.max(pj), pi.min(pj)) * scale[i] * scale[j]
            })
            .collect();
        Ok(Self {
            n,
            scale,
            held: held.to_vec(),
            perm_fwd,
            perm_inv,
            l_col_ptr,
            l_row_idx,
            l,
            z,
            block_of,
            block_offset: layout.block_offset.clone(),
            col_blocks: layout.col_blocks.clone(),
            col_row_off: layout.col_row_off.clone(),
            col_ptr: layout.col_ptr.clone(),
        })
    }

    /// Position of (i, j) in S's values, if S has it.
    fn position(&self, i: usize, j: usize) -> Option<usize> {
        let (mut i, mut j) = (i, j);
        let (mut bi, mut bj) = (self.block_of[i], self.block_of[j]);
        if bi > bj || (bi == bj && i > j) {
            std::mem::swap(&mut i, &mut j);
            std::mem::swap(&mut bi, &mut bj);
        }
        let bj_ = bj as usize;
        let k = self.col_blocks[bj_].binary_search(&bi).ok()?;
        Some(self.col_ptr[j] + self.col_row_off[bj_][k] + (i - self.block_offset[bi as usize]))
    }

    /// `x ← S⁻¹ x` (the held unknowns' entries of x are ignored and come back 0).
    fn solve_with_factor(&self, x: &mut [f64]) {
        let n = self.n;
        let mut y: Vec<f64> = (0..n)
            .map(|k| {
                let i = self.perm_fwd[k];
                if self.held[i] {
                    0.0
                } else {
                    x[i] * self.scale[i]
                }
            })
            .collect();
        // L y' = y
        for j in 0..n {
            let (s, e) = (self.l_col_ptr[j], self.l_col_ptr[j + 1]);
            y[j] /= self.l[s];
            let yj = y[j];
            for t in s + 1..e {
                y[self.l_row_idx[t]] -= self.l[t] * yj;
            }
        }
        // Lᵀ x' = y'
        for j in (0..n).rev() {
            let (s, e) = (self.l_col_ptr[j], self.l_col_ptr[j + 1]);
            let mut v = y[j];
            for t in s + 1..e {
                v -= self.l[t] * y[self.l_row_idx[t]];
            }
            y[j] = v / self.l[s];
        }
        for (i, xi) in x.iter_mut().enumerate() {
            *xi = if self.held[i] {
                0.0
            } else {
                y[self.perm_inv[i]] * self.scale[i]
            };
        }
    }

    /// Column j of S⁻¹.
    pub fn column(&self, j: usize) -> Vec<f64> {
        let mut e = vec![0.0; self.n];
        e[j] = 1.0;
        self.solve_with_factor(&mut e);
        e
    }
}

impl CofactorLookup for SelectedInverse {
    fn at(&self, i: usize, j: usize) -> f64 {
        if self.held[i] || self.held[j] {
            return 0.0;
        }
        match self.position(i, j) {
            Some(p) => self.z[p],
            None => self.column(j)[i],
        }
    }

    /// Sorted rows are read run by run (consecutive unknowns of one block: one search per
    /// pair of runs); a pair outside S's pattern, or unsorted rows, by solving a column per
    /// row.
    fn restricted(&self, rows: &[usize]) -> DMatrix<f64> {
        let k = rows.len();
        if rows.windows(2).all(|w| w[0] < w[1]) {
            if let Some(m) = self.restricted_in_pattern(rows) {
                return m;
            }
        }
        let mut out = DMatrix::zeros(k, k);
        for (b, &j) in rows.iter().enumerate() {
            let col = self.column(j);
            for (a, &i) in rows.iter().enumerate() {
                out[(a, b)] = col[i];
            }
        }
        out
    }
}

impl SelectedInverse {
    /// [`CofactorLookup::restricted`] of sorted `rows` when every pair lies in S's pattern.
    fn restricted_in_pattern(&self, rows: &[usize]) -> Option<DMatrix<f64>> {
        let k = rows.len();
        let mut runs = Vec::new();
        let mut start = 0;
        for t in 1..=k {
            if t == k
                || rows[t] != rows[t - 1] + 1
                || self.block_of[rows[t]] != self.block_of[rows[start]]
            {
                runs.push(start..t);
                start = t;
            }
        }
        let mut out = DMatrix::zeros(k, k);
        for (x, ra) in runs.iter().enumerate() {
            for rb in &runs[x..] {
                // Rows sorted: run a's block comes first (or is run b's).
                let ba = self.block_of[rows[ra.start]];
                let bb = self.block_of[rows[rb.start]] as usize;
                let pos = self.col_blocks[bb].binary_search(&ba).ok()?;
                let roff = self.col_row_off[bb][pos];
                let off_a = self.block_offset[ba as usize];
                for tb in rb.clone() {
                    let j = rows[tb];
                    for ta in ra.clone() {
                        let i = rows[ta];
                        let v = if self.held[i] || self.held[j] {
                            0.0
                        } else if i > j {
                            // Same block, below its diagonal: stored as (j, i).
                            self.z[self.col_ptr[i] + roff + (j - off_a)]
                        } else {
                            self.z[self.col_ptr[j] + roff + (i - off_a)]
                        };
                        out[(ta, tb)] = v;
                        out[(tb, ta)] = v;
                    }
                }
            }
        }
        Some(out)
    }
}

impl Factored for SelectedInverse {
    fn solve_in_place(&self, x: &mut [f64]) {
        self.solve_with_factor(x);
    }
}

/// S⁻¹ formed whole from a dense Cholesky factorization (faer, parallel): for a camera graph
/// whose sparse factor is too full for the selected inversion (its n³/3 scattered
/// operations against the dense factorization's blocked ones). Needs 3 n² values (S, the
/// inverse of L, S⁻¹), estimated before anything is allocated.
pub(crate) struct DenseInverse {
    /// The lower triangle of S⁻¹ (unscaled; held rows and columns 0).
    inv: faer::Mat<f64>,
    held: Vec<bool>,
}

impl DenseInverse {
    /// Bytes [`DenseInverse::new`] needs for `n` unknowns.
    pub fn bytes(n: usize) -> f64 {
        24.0 * (n as f64) * (n as f64)
    }

    /// S⁻¹ of the layout's S (`values`) with the unknowns `held` replaced by identity rows.
    pub fn new(
        layout: &Layout,
        values: &[f64],
        held: &[bool],
        memory_limit: Option<f64>,
        par: Par,
    ) -> Result<Self, SelectedError> {
        let n = layout.n_reduced;
        let bytes = Self::bytes(n);
        if memory_limit.is_some_and(|m| bytes > m) {
            return Err(SelectedError::TooLarge {
                bytes,
                work: (n as f64).powi(3),
                factor_entries: n * (n + 1) / 2,
            });
        }
        let scale = jacobi_scale(layout, values, held);
        let mut m = faer::Mat::<f64>::zeros(n, n);
        for ((i, j), &v) in layout.entries().zip(values) {
            // upper (i ≤ j) stored as the lower (j, i)
            m[(j, i)] = scaled_entry(i, j, v, &scale, held);
        }
        // m becomes L; a pivot below MIN_PIVOT is as good as not positive.
        let mut inv = super::linear::cholesky_inverse(m.as_mut(), par, MIN_PIVOT)
            .map_err(SelectedError::NotPositive)?;
        drop(m);
        for j in 0..n {
            for i in j..n {
                inv[(i, j)] = if held[i] || held[j] {
                    0.0
                } else {
                    inv[(i, j)] * scale[i] * scale[j]
                };
            }
        }
        Ok(Self {
            inv,
            held: held.to_vec(),
        })
    }
}

impl CofactorLookup for DenseInverse {
    #[inline]
    fn at(&self, i: usize, j: usize) -> f64 {
        if self.held[i] || self.held[j] {
            return 0.0;
        }
        self.inv[(i.max(j), i.min(j))]
    }
}

impl Factored for DenseInverse {
    fn solve_in_place(&self, x: &mut [f64]) {
        let n = x.len();
        let b: Vec<f64> = (0..n)
            .map(|i| if self.held[i] { 0.0 } else { x[i] })
            .collect();
        x.fill(0.0);
        for j in 0..n {
            for i in j..n {
                let q = self.inv[(i, j)];
                x[i] += q * b[j];
                if i != j {
                    x[j] += q * b[i];
                }
            }
        }
    }
}

/// Takahashi's recurrences: `Z = (L Lᵀ)⁻¹` on the pattern of L (the module doc).
fn takahashi(col_ptr: &[usize], row_idx: &[usize], l: &[f64]) -> Vec<f64> {
    let n = col_ptr.len() - 1;
    let mut z = vec![0.0; l.len()];
    // mark[r] == j: r is a row of column j; pos[r]: its place among them.
    let mut mark = vec![usize::MAX; n];
    let mut pos = vec![0usize; n];
    let widest = (0..n)
        .map(|j| col_ptr[j + 1] - col_ptr[j])
        .max()
        .unwrap_or(0);
    let mut acc = vec![0.0; widest];
    for j in (0..n).rev() {
        let (s, e) = (col_ptr[j], col_ptr[j + 1]);
        let ljj = l[s];
        let m = e - s - 1;
        for (t, &r) in row_idx[s + 1..e].iter().enumerate() {
            mark[r] = j;
            pos[r] = t;
        }
        acc[..m].fill(0.0);
        // acc[i] = Σ_k Z_ik L_kj over the pairs (i, k) of column j's rows; each pair
        // r > k is met once, in column k of Z, and counts for both.
        for t in 0..m {
            let k = row_idx[s + 1 + t];
            let lkj = l[s + 1 + t];
            let (ks, ke) = (col_ptr[k], col_ptr[k + 1]);
            let mut own = z[ks] * lkj;
            for u in ks + 1..ke {
                let r = row_idx[u];
                if mark[r] == j {
                    let zrk = z[u];
                    let pr = pos[r];
                    acc[pr] += zrk * lkj;
                    own += zrk * l[s + 1 + pr];
                }
            }
            acc[t] += own;
        }
        let mut sum = 0.0;
        for t in 0..m {
            let zij = -acc[t] / ljj;
            z[s + 1 + t] = zij;
            sum += l[s + 1 + t] * zij;
        }
        z[s] = (1.0 / ljj - sum) / ljj;
    }
    z
}

impl From<String> for SelectedError {
    fn from(e: String) -> Self {
        SelectedError::Internal(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The block pattern's figures are the scalar factor's, on a banded and on a dense
    /// camera graph.
    #[test]
    fn the_block_estimate_is_the_scalar_factor() {
        use crate::synthetic::{SyntheticBal, Visibility};
        for visibility in [Visibility::Banded, Visibility::Random] {
            let spec = SyntheticBal {
                cameras: 40,
                points: 2000,
                visibility,
                ..Default::default()
            };
            let problem = spec.generate().unwrap().problem;
            let layout = Layout::new(&problem);
            let n = layout.n_reduced;
            let row_idx = layout.row_indices();
            let sym = SymbolicSparseColMatRef::new_checked(n, n, &layout.col_ptr, None, &row_idx);
            let (fwd, inv) = super::super::linear::block_amd_ordering(&layout).unwrap();
            let perm = faer::perm::PermRef::new_checked(&fwd, &inv, n);
            let params = CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
                ..Default::default()
            };
            let symbolic = factorize_symbolic_cholesky(
                sym,
                Side::Upper,
                SymmetricOrdering::Custom(perm),
                params,
            )
            .unwrap();
            let SymbolicCholeskyRaw::Simplicial(l) = symbolic.raw() else {
                panic!("simplicial")
            };
            let cp = l.col_ptr();
            let lens = (0..n).map(|j| (cp[j + 1] - cp[j]) as f64);
            let (entries, work) = lens.fold((0.0, 0.0), |(e, w), c| (e + c, w + c * c));
            let (be, bw) = super::super::linear::block_factor_columns(&layout).unwrap();
            assert_eq!((be, bw), (entries, work), "{visibility:?}");
        }
    }

    /// Takahashi's Z equals the dense inverse on the factor's pattern, for a random sparse
    /// positive definite matrix with fill.
    #[test]
    fn takahashi_matches_the_dense_inverse() {
        use rand::Rng;
        let n = 40;
        let mut rng = pingcal_geometry::consensus::rng(3);
        let mut a = DMatrix::<f64>::identity(n, n) * 4.0;
        for _ in 0..60 {
            let (i, j) = (rng.random_range(0..n), rng.random_range(0..n));
            if i != j {
                let v: f64 = rng.random_range(-0.5..0.5);
                a[(i, j)] += v;
                a[(j, i)] += v;
            }
        }
        let chol = a.clone().cholesky().expect("positive definite");
        let ld = chol.l();
        // The pattern of L: what is numerically nonzero, plus the diagonal.
        let mut col_ptr = vec![0];
        let (mut rows, mut vals) = (Vec::new(), Vec::new());
        for j in 0..n {
            for i in j..n {
                if i == j || ld[(i, j)].abs() > 1e-300 {
                    rows.push(i);
                    vals.push(ld[(i, j)]);
                }
            }
            col_ptr.push(rows.len());
        }
        let z = takahashi(&col_ptr, &rows, &vals);
        let inv = a.try_inverse().unwrap();
        for j in 0..n {
            for t in col_ptr[j]..col_ptr[j + 1] {
                let i = rows[t];
                assert!(
                    (z[t] - inv[(i, j)]).abs() < 1e-12,
                    "Z[{i},{j}] {} vs {}",
                    z[t],
                    inv[(i, j)]
                );
            }
        }
    }
}
