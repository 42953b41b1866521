//! Direct solvers for the reduced camera system: dense Cholesky for small or nearly full
//! systems, sparse supernodal/simplicial Cholesky (faer) with the symbolic factorization
//! computed once. The iterative solver is in `iterative`; which one runs is chosen in
//! `choice`.

use super::layout::Layout;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, MatMut, Par, Side};

/// Which factorization solves the reduced camera system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LinearSolverKind {
    /// Dense when the reduced system is small or nearly full, sparse otherwise.
    Auto,
    /// Dense Cholesky of the reduced system.
    Dense,
    /// Sparse Cholesky of the reduced system.
    Sparse,
    /// Preconditioned conjugate gradients on the reduced system, which is never formed
    /// (memory proportional to the observations).
    Iterative,
}

impl std::fmt::Display for LinearSolverKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            LinearSolverKind::Auto => "auto",
            LinearSolverKind::Dense => "dense",
            LinearSolverKind::Sparse => "sparse",
            LinearSolverKind::Iterative => "iterative",
        })
    }
}

pub(crate) enum Factorizer {
    Dense {
        par: Par,
    },
    Sparse {
        /// The row indices of S's pattern (faer reads them at every factorization).
        row_idx: Vec<usize>,
        /// Boxed (the variant would otherwise be ~40 times the dense one): it is built once
        /// per adjustment and dereferenced once per factorization, far from any inner loop.
        symbolic: Box<SymbolicCholesky<usize>>,
        l_values: Vec<f64>,
        mem: MemBuffer,
        par: Par,
    },
}

impl Factorizer {
    /// A dense factorization of the reduced system.
    pub fn dense(par: Par) -> Self {
        Factorizer::Dense { par }
    }

    /// A sparse factorization of the reduced system: its fill-reducing ordering and
    /// symbolic factorization, computed once.
    pub fn sparse(layout: &Layout, par: Par) -> Result<Self, String> {
        let n = layout.n_reduced;
        if n == 0 {
            return Ok(Factorizer::Dense { par });
        }
        let row_idx = layout.row_indices();
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &layout.col_ptr, None, &row_idx);
        // Fill-reducing ordering on the block graph (a few thousand nodes instead of tens of
        // thousands of scalars), expanded to the scalars of each block: cheaper to compute,
        // and it keeps every block's unknowns together, which makes good supernodes.
        let (fwd, inv) = block_amd_ordering(layout)?;
        let perm = faer::perm::PermRef::new_checked(&fwd, &inv, n);
        let symbolic = factorize_symbolic_cholesky(
            sym,
            Side::Upper,
            faer::sparse::linalg::cholesky::SymmetricOrdering::Custom(perm),
            Default::default(),
        )
        .map_err(|e| format!("symbolic Cholesky factorization failed: {e:?}"))?;
        let l_values = vec![0.0; symbolic.len_val()];
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mem = MemBuffer::new(req);
        Ok(Factorizer::Sparse {
            row_idx,
            symbolic: Box::new(symbolic),
            l_values,
            mem,
            par,
        })
    }

    /// Solves S x = rhs in place. Returns `false` if S is not numerically positive definite.
    pub fn solve(&mut self, layout: &Layout, values: &[f64], rhs: &mut [f64]) -> bool {
        let n = layout.n_reduced;
        if n == 0 {
            return true;
        }
        match self {
            Factorizer::Dense { par } => {
                // The lower triangle of S, factorized in place (one n × n matrix).
                let mut m = Mat::<f64>::zeros(n, n);
                for ((row, col), &v) in layout.entries().zip(values) {
                    m[(col, row)] = v;
                }
                let par = *par;
                let mut mem = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
                    n,
                    par,
                    Default::default(),
                ));
                if llt::factor::cholesky_in_place(
                    m.as_mut(),
                    Default::default(),
                    par,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .is_err()
                {
                    return false;
                }
                let x = MatMut::from_column_major_slice_mut(rhs, n, 1);
                llt::solve::solve_in_place_with_conj(
                    m.as_ref(),
                    Conj::No,
                    x,
                    par,
                    MemStack::new(&mut mem),
                );
                rhs.iter().all(|v| v.is_finite())
            }
            Factorizer::Sparse {
                row_idx,
                symbolic,
                l_values,
                mem,
                par,
            } => {
                let sym =
                    SymbolicSparseColMatRef::new_checked(n, n, &layout.col_ptr, None, row_idx);
                let a = SparseColMatRef::new(sym, values);
                let stack = MemStack::new(mem);
                let llt = match symbolic.factorize_numeric_llt::<f64>(
                    l_values,
                    a,
                    Side::Upper,
                    Default::default(),
                    *par,
                    stack,
                    Default::default(),
                ) {
                    Ok(l) => l,
                    Err(_) => return false,
                };
                let llt: LltRef<'_, usize, f64> = llt;
                let x = MatMut::from_column_major_slice_mut(rhs, n, 1);
                llt.solve_in_place_with_conj(Conj::No, x, *par, MemStack::new(mem));
                rhs.iter().all(|v| v.is_finite())
            }
        }
    }
}

/// The inverse of the symmetric positive definite `a` (its lower triangle is read), from
/// faer's blocked Cholesky factorization `a = L Lᵀ`, which overwrites `a` with L. The
/// inverse's lower triangle is filled. Fails with the first column whose pivot `L_jj²` was
/// not positive or is below `min_pivot` (then before the inverse's work is done).
pub(super) fn cholesky_inverse(
    mut a: MatMut<'_, f64>,
    par: Par,
    min_pivot: f64,
) -> Result<Mat<f64>, usize> {
    let n = a.nrows();
    let mut mem = MemBuffer::new(
        llt::factor::cholesky_in_place_scratch::<f64>(n, par, Default::default())
            .or(llt::inverse::inverse_scratch::<f64>(n, par)),
    );
    if let Err(llt::factor::LltError::NonPositivePivot { index }) = llt::factor::cholesky_in_place(
        a.as_mut(),
        Default::default(),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    ) {
        return Err(index);
    }
    if let Some(j) = (0..n).find(|&j| !(a[(j, j)] * a[(j, j)] >= min_pivot)) {
        return Err(j);
    }
    let mut inv = Mat::<f64>::zeros(n, n);
    llt::inverse::inverse(inv.as_mut(), a.as_ref(), par, MemStack::new(&mut mem));
    Ok(inv)
}

/// AMD on the block graph of S (forward and inverse block permutations), computed once per
/// layout: the solver choice, the sparse factorization and the selected inversion all use
/// this one ordering.
fn block_amd(layout: &Layout) -> Result<&(Vec<usize>, Vec<usize>), String> {
    layout
        .block_order
        .get_or_init(|| {
            let nb = layout.num_blocks();
            let (col_ptr, row_idx) = block_graph(layout);
            let graph = SymbolicSparseColMatRef::new_checked(nb, nb, &col_ptr, None, &row_idx);
            let (mut perm, mut perm_inv) = (vec![0usize; nb], vec![0usize; nb]);
            let mut mem = MemBuffer::new(faer::sparse::linalg::amd::order_scratch::<usize>(
                nb,
                row_idx.len(),
            ));
            faer::sparse::linalg::amd::order(
                &mut perm,
                &mut perm_inv,
                graph,
                Default::default(),
                MemStack::new(&mut mem),
            )
            .map_err(|e| format!("block ordering failed: {e:?}"))?;
            Ok((perm, perm_inv))
        })
        .as_ref()
        .map_err(Clone::clone)
}

/// The symbolic Cholesky factorization of S's block graph under [`block_amd`].
fn block_symbolic(
    layout: &Layout,
    params: faer::sparse::linalg::cholesky::CholeskySymbolicParams<'_>,
) -> Option<SymbolicCholesky<usize>> {
    let nb = layout.num_blocks();
    let (fwd, inv) = block_amd(layout).ok()?;
    let (col_ptr, row_idx) = block_graph(layout);
    let graph = SymbolicSparseColMatRef::new_checked(nb, nb, &col_ptr, None, &row_idx);
    let perm = faer::perm::PermRef::new_checked(fwd, inv, nb);
    factorize_symbolic_cholesky(
        graph,
        Side::Upper,
        faer::sparse::linalg::cholesky::SymmetricOrdering::Custom(perm),
        params,
    )
    .ok()
}

/// [`block_amd`] expanded to scalar indices (forward and inverse).
pub(super) fn block_amd_ordering(layout: &Layout) -> Result<(Vec<usize>, Vec<usize>), String> {
    let (perm, _) = block_amd(layout)?;
    let n = layout.n_reduced;
    let mut fwd = Vec::with_capacity(n);
    for &b in perm {
        fwd.extend(layout.block_offset[b]..layout.block_offset[b] + layout.block_dim[b]);
    }
    let mut inv = vec![0usize; n];
    for (k, &i) in fwd.iter().enumerate() {
        inv[i] = k;
    }
    Ok((fwd, inv))
}

/// Stored entries of the Cholesky factor of S's *block* graph under AMD (each a block of
/// the scalar factor), from its symbolic factorization: what the solver choice scales to
/// estimate the scalar fill before anything of that size is allocated.
pub(crate) fn block_factor_entries(layout: &Layout) -> Option<f64> {
    let nb = layout.num_blocks();
    if nb == 0 {
        return Some(0.0);
    }
    Some(block_symbolic(layout, Default::default())?.len_val() as f64)
}

/// The scalar entries of S's Cholesky factor and the selected inversion's work
/// `Σⱼ |column j|²`, exactly as the block ordering's scalar factor has them (S's blocks are
/// dense, so its pattern is the block factor's, expanded), from a symbolic factorization of
/// the block graph alone: nothing of the scalar size is allocated.
pub(crate) fn block_factor_columns(layout: &Layout) -> Option<(f64, f64)> {
    use faer::sparse::linalg::cholesky::{CholeskySymbolicParams, SymbolicCholeskyRaw};
    let nb = layout.num_blocks();
    if nb == 0 {
        return Some((0.0, 0.0));
    }
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold:
            faer::sparse::linalg::SupernodalThreshold::FORCE_SIMPLICIAL,
        ..Default::default()
    };
    let symbolic = block_symbolic(layout, params)?;
    let SymbolicCholeskyRaw::Simplicial(l) = symbolic.raw() else {
        return None;
    };
    let fwd: Vec<usize> = match symbolic.perm() {
        Some(p) => p.arrays().0.to_vec(),
        None => (0..nb).collect(),
    };
    let dim = |k: usize| layout.block_dim[fwd[k]];
    let (cp, ri) = (l.col_ptr(), l.row_idx());
    let (mut entries, mut work) = (0.0, 0.0);
    for b in 0..nb {
        let below: usize = (ri[cp[b]..cp[b + 1]].iter())
            .filter(|&&a| a != b)
            .map(|&a| dim(a))
            .sum();
        for k in 0..dim(b) {
            let c = (below + dim(b) - k) as f64;
            entries += c;
            work += c * c;
        }
    }
    Some((entries, work))
}

/// The upper triangle of S's block graph as CSC (column pointers, row blocks).
fn block_graph(layout: &Layout) -> (Vec<usize>, Vec<usize>) {
    let mut col_ptr = Vec::with_capacity(layout.num_blocks() + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for rows in &layout.col_blocks {
        row_idx.extend(rows.iter().map(|&a| a as usize));
        col_ptr.push(row_idx.len());
    }
    (col_ptr, row_idx)
}
