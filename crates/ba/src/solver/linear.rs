//! Linear solvers for the reduced camera system: dense Cholesky for small systems, sparse
//! supernodal/simplicial Cholesky (faer) with the symbolic factorization computed once.

use super::layout::Layout;
use faer::dyn_stack::{MemBuffer, MemStack};
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
}

pub(crate) enum Factorizer {
    Dense {
        par: Par,
    },
    Sparse {
        symbolic: SymbolicCholesky<usize>,
        l_values: Vec<f64>,
        mem: MemBuffer,
        par: Par,
    },
}

impl Factorizer {
    pub fn new(layout: &Layout, kind: LinearSolverKind, par: Par) -> Result<Self, String> {
        let n = layout.n_reduced;
        let dense = match kind {
            LinearSolverKind::Dense => true,
            LinearSolverKind::Sparse => false,
            LinearSolverKind::Auto => {
                n <= 600 || layout.nnz() as f64 >= 0.25 * (n * (n + 1) / 2) as f64
            }
        };
        if dense || n == 0 {
            return Ok(Factorizer::Dense { par });
        }
        let sym =
            SymbolicSparseColMatRef::new_checked(n, n, &layout.col_ptr, None, &layout.row_idx);
        let symbolic =
            factorize_symbolic_cholesky(sym, Side::Upper, Default::default(), Default::default())
                .map_err(|e| format!("symbolic Cholesky factorization failed: {e:?}"))?;
        let l_values = vec![0.0; symbolic.len_val()];
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mem = MemBuffer::new(req);
        Ok(Factorizer::Sparse {
            symbolic,
            l_values,
            mem,
            par,
        })
    }

    pub fn is_dense(&self) -> bool {
        matches!(self, Factorizer::Dense { .. })
    }

    /// Solves S x = rhs in place. Returns `false` if S is not numerically positive definite.
    pub fn solve(&mut self, layout: &Layout, values: &[f64], rhs: &mut [f64]) -> bool {
        let n = layout.n_reduced;
        if n == 0 {
            return true;
        }
        match self {
            Factorizer::Dense { par } => {
                let mut m = Mat::<f64>::zeros(n, n);
                for j in 0..n {
                    for k in layout.col_ptr[j]..layout.col_ptr[j + 1] {
                        let i = layout.row_idx[k];
                        m[(i, j)] = values[k];
                        m[(j, i)] = values[k];
                    }
                }
                let _ = par;
                let Ok(llt) = m.llt(Side::Lower) else {
                    return false;
                };
                let mut x = Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
                use faer::linalg::solvers::SolveCore;
                llt.solve_in_place_with_conj(Conj::No, x.as_mut());
                for i in 0..n {
                    rhs[i] = x[(i, 0)];
                }
                rhs.iter().all(|v| v.is_finite())
            }
            Factorizer::Sparse {
                symbolic,
                l_values,
                mem,
                par,
            } => {
                let sym = SymbolicSparseColMatRef::new_checked(
                    n,
                    n,
                    &layout.col_ptr,
                    None,
                    &layout.row_idx,
                );
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
