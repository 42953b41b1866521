//! Whether the network can determine the camera models' free parameters, judged before
//! solving, at the start values.
//!
//! A parameter is *not determinable* when some change of it, together with changes of the
//! other unknowns, changes no observation to first order: the normal matrix then has a null
//! vector with a component on the intrinsics. A single image of a plane cannot give the
//! principal distance and the principal point together (a homography has 8 degrees of
//! freedom, the pose and c, xp, yp are 9); a parameter of a camera whose every image is
//! held and whose points are all control moves nothing the adjustment could see… The
//! adjustment would otherwise run, its damping holding the undetermined combination
//! wherever it started, and only the precision afterwards would say so.
//!
//! With S the reduced camera system (points eliminated) in Jacobi scaling (unit diagonal),
//! split into the intrinsics `c` and the rest `r` (poses, rigs, the points of distances),
//! the intrinsics' own Schur complement
//!
//! `T = S_cc − S_cr S_rr⁻¹ S_rc`
//!
//! is the information on the intrinsics with every other unknown free. An eigenvalue of T
//! below [`NULL_EIGENVALUE`] (T's diagonal is at most 1) is a combination of intrinsics the
//! network does not see; its eigenvector names them. A network without a datum of its own
//! is given a minimal one for the test, the first image and one coordinate of a point:
//! intrinsics do not change under a similarity of the object, so the test does not depend
//! on the datum chosen.

use super::layout::Layout;
use super::precision::{
    invert_or_diagnose, jacobi_scale, linearized, reduced_schur, reduced_system, selected,
    selected_fits,
};
use super::selected_inverse::Factored;
use super::sigma::PrecisionError;
use crate::datum::{check, Datum};
use crate::problem::Problem;
use nalgebra::DMatrix;

/// An eigenvalue of the Jacobi-scaled T below this is a null direction. In the tests the
/// convergent rolled network's weakest combination of its ten intrinsics is 8e-4, one image
/// of a plane with c alone free 2e-2 and with c, xp, yp free 3e-16 (rounding); intrinsics
/// correlated at 0.9999 would give about 1e-4.
pub const NULL_EIGENVALUE: f64 = 1e-9;

/// The largest reduced system judged densely before solving (its dense Cholesky, n³/3
/// flops, is about a second at this size); larger ones are judged with S's sparse factor,
/// one solve per free intrinsic, unless the factor is too large
/// ([`Estimability::NotChecked`]).
pub const MAX_CHECK_UNKNOWNS: usize = 1500;

/// Most free intrinsics judged with the sparse factor (one solve each, and T's n·k² terms).
const MAX_SPARSE_CHECK_INTRINSICS: usize = 300;

/// A component of a null vector above this share of its largest one names a parameter.
const NAMED_SHARE: f64 = 0.1;

/// What [`check_intrinsics`] found.
#[derive(Clone, Debug, PartialEq)]
pub enum Estimability {
    /// Every free intrinsic is determined (to first order at the start values).
    Determined,
    /// The reduced system (this many unknowns) is too large for the test: its sparse factor
    /// would exceed the memory or the work limit of the selected inversion
    /// ([`MAX_SELECTED_WORK`](super::MAX_SELECTED_WORK)), or it has more than 300 free
    /// intrinsics. Not judged before solving (the precision after the adjustment names a
    /// defect).
    NotChecked(usize),
}

/// Judges, at the problem's current values, whether its free intrinsics are determined by
/// the network (see the module doc). `Err(PrecisionError::NotDeterminable)` names the
/// combination that is not, with what would determine it. A network without a datum of its
/// own (a free network, or one whose control the start-up did not reach) is judged with a
/// minimal one; a pose that is not determined is named as the precision names it.
pub fn check_intrinsics(problem: &Problem) -> Result<Estimability, PrecisionError> {
    problem.validate()?;
    let with_datum;
    let problem = if let Ok(Datum::Given { .. }) = check(problem, false) {
        problem
    } else {
        with_datum = with_minimal_datum(problem);
        &with_datum
    };
    let layout = Layout::new(problem);
    let n = layout.n_reduced;
    let intrinsic_rows = intrinsic_rows(problem, &layout);
    if intrinsic_rows.is_empty() {
        return Ok(Estimability::Determined);
    }
    let lin = linearized(problem, &layout)?;
    let c: Vec<usize> = intrinsic_rows.iter().map(|r| r.row).collect();
    let t = if n <= MAX_CHECK_UNKNOWNS {
        let (_, s) = reduced_system(problem, &layout, &lin)?;
        match dense_complement(&s, &c) {
            Some(t) => t,
            // the poses themselves are not determined: name what is free
            None => {
                return invert_or_diagnose(&s, problem, &layout).map(|_| Estimability::Determined)
            }
        }
    } else if c.len() > MAX_SPARSE_CHECK_INTRINSICS {
        return Ok(Estimability::NotChecked(n));
    } else {
        if selected_fits(&layout, problem).is_err() {
            return Ok(Estimability::NotChecked(n));
        }
        let schur = reduced_schur(problem, &layout, &lin)?;
        match sparse_complement(problem, &layout, &schur.values, &c) {
            Ok(t) => t,
            Err(PrecisionError::TooLarge(_)) => return Ok(Estimability::NotChecked(n)),
            Err(e) => return Err(e),
        }
    };
    let eig = t.symmetric_eigen();
    let Some(k) = (0..c.len()).min_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]))
    else {
        return Ok(Estimability::Determined);
    };
    if eig.eigenvalues[k] >= NULL_EIGENVALUE {
        return Ok(Estimability::Determined);
    }
    let v = eig.eigenvectors.column(k);
    let largest = v.amax();
    let named: Vec<&IntrinsicRow> = (intrinsic_rows.iter().enumerate())
        .filter(|(a, _)| v[*a].abs() >= NAMED_SHARE * largest)
        .map(|(_, row)| row)
        .collect();
    Err(PrecisionError::NotDeterminable(describe(problem, &named)))
}

/// T of the Jacobi-scaled dense S on the intrinsics' rows `c`; `None` when S_rr is not
/// positive definite.
fn dense_complement(s: &DMatrix<f64>, c: &[usize]) -> Option<DMatrix<f64>> {
    let n = s.nrows();
    let d = jacobi_scale(s);
    let scaled = |i: usize, j: usize| s[(i, j)] * d[i] * d[j];
    let r: Vec<usize> = (0..n).filter(|i| !c.contains(i)).collect();
    let s_cc = DMatrix::from_fn(c.len(), c.len(), |a, b| scaled(c[a], c[b]));
    if r.is_empty() {
        return Some(s_cc);
    }
    let s_rr = DMatrix::from_fn(r.len(), r.len(), |a, b| scaled(r[a], r[b]));
    let s_rc = DMatrix::from_fn(r.len(), c.len(), |a, b| scaled(r[a], c[b]));
    let chol = s_rr.cholesky()?;
    Some(&s_cc - s_rc.transpose() * chol.solve(&s_rc))
}

/// T from the sparse S (its upper triangle `values` in the layout's order): S_rr factorized
/// sparsely (the intrinsics held out), one solve per intrinsic, then Jacobi-scaled as the
/// dense form. A pose-side defect is named as the precision names it; a factor too large
/// is [`PrecisionError::TooLarge`].
fn sparse_complement(
    problem: &Problem,
    layout: &Layout,
    values: &[f64],
    c: &[usize],
) -> Result<DMatrix<f64>, PrecisionError> {
    let n = layout.n_reduced;
    let mut held = vec![false; n];
    let mut index = vec![usize::MAX; n];
    for (a, &row) in c.iter().enumerate() {
        held[row] = true;
        index[row] = a;
    }
    let s_rr = selected(layout, values, &held, problem)?;
    // S's columns of the intrinsics (both triangles).
    let mut cols = vec![vec![0.0; n]; c.len()];
    for ((i, j), &v) in layout.entries().zip(values) {
        if index[j] != usize::MAX {
            cols[index[j]][i] = v;
        }
        if i != j && index[i] != usize::MAX {
            cols[index[i]][j] = v;
        }
    }
    let d = super::selected_inverse::jacobi_scale(layout, values, &vec![false; n]);
    let solved: Vec<Vec<f64>> = cols
        .iter()
        .map(|col| {
            let mut x = col.clone();
            s_rr.solve_in_place(&mut x); // the intrinsics' rows are ignored and come back 0
            x
        })
        .collect();
    Ok(DMatrix::from_fn(c.len(), c.len(), |a, b| {
        let coupling: f64 = (0..n)
            .filter(|&i| !held[i])
            .map(|i| cols[a][i] * solved[b][i])
            .sum();
        (cols[b][c[a]] - coupling) * d[c[a]] * d[c[b]]
    }))
}

/// One free intrinsic's row of the reduced system.
struct IntrinsicRow {
    row: usize,
    camera: usize,
    parameter: usize,
}

fn intrinsic_rows(problem: &Problem, layout: &Layout) -> Vec<IntrinsicRow> {
    let mut rows = Vec::new();
    for c in 0..problem.cameras.len() {
        if let Some(slot) = layout.camera_slot[c] {
            let o = layout.slot_offset(slot);
            for (k, &parameter) in layout.camera_free[c].iter().enumerate() {
                rows.push(IntrinsicRow {
                    row: o + k,
                    camera: c,
                    parameter,
                });
            }
        }
    }
    rows
}

/// "c, xp and yp of camera 'left' …" with what would determine them.
fn describe(problem: &Problem, named: &[&IntrinsicRow]) -> String {
    let mut by_camera: Vec<(usize, Vec<&str>)> = Vec::new();
    for r in named {
        let name = problem.cameras[r.camera].model.parameter_names()[r.parameter];
        match by_camera.iter_mut().find(|(c, _)| *c == r.camera) {
            Some((_, list)) => list.push(name),
            None => by_camera.push((r.camera, vec![name])),
        }
    }
    let parts: Vec<String> = by_camera
        .iter()
        .map(|(c, list)| {
            let images = problem.images.iter().filter(|i| i.camera.0 == *c).count();
            format!(
                "{} of camera '{}' ({} image{})",
                and_list(list),
                problem.cameras[*c].name,
                images,
                if images == 1 { "" } else { "s" }
            )
        })
        .collect();
    let single = named.len() == 1;
    format!(
        "{} cannot be determined by this network: {} changes no observation (with the poses adjusted to it); hold {} (leave it out of the calibrated parameters), or add what determines {}: images from other directions and rolled 90°, points in depth, control",
        parts.join(" and "),
        if single { "a change of it" } else { "a combination of them" },
        if single { "it" } else { "one of them" },
        if single { "it" } else { "them" },
    )
}

fn and_list(items: &[&str]) -> String {
    match items {
        [] => String::new(),
        [one] => one.to_string(),
        [init @ .., last] => format!("{} and {last}", init.join(", ")),
    }
}

/// A copy of a free network with a minimal datum: the first image held, and the coordinate
/// of the point farthest from its centre along which it is farthest (the scale).
fn with_minimal_datum(problem: &Problem) -> Problem {
    let mut p = problem.clone();
    if let Some(im) = p.images.first_mut() {
        im.fixed = true;
        let c0 = im.camera_from_object.centre();
        let far = (0..p.points.len()).max_by(|&a, &b| {
            let da = (p.points[a].position - c0).norm();
            let db = (p.points[b].position - c0).norm();
            da.total_cmp(&db)
        });
        if let Some(j) = far {
            let d = p.points[j].position - c0;
            p.points[j].fixed_axes[d.iamax()] = true;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sparse form of T (one solve per intrinsic with S_rr's factor) equals the dense
    /// one, on a street of BAL cameras (each its own f, k1, k2) with a minimal datum.
    #[test]
    fn sparse_complement_equals_the_dense() {
        let spec = crate::synthetic::SyntheticBal {
            cameras: 30,
            points: 1500,
            ..Default::default()
        };
        let problem = with_minimal_datum(&spec.generate().unwrap().problem);
        let layout = Layout::new(&problem);
        let lin = linearized(&problem, &layout).unwrap();
        let c: Vec<usize> = intrinsic_rows(&problem, &layout)
            .iter()
            .map(|r| r.row)
            .collect();
        assert_eq!(c.len(), 90);
        let (schur, s) = reduced_system(&problem, &layout, &lin).unwrap();
        let dense = dense_complement(&s, &c).unwrap();
        let sparse = sparse_complement(&problem, &layout, &schur.values, &c).unwrap();
        let diff = (&dense - &sparse).amax();
        // T's diagonal is at most 1 (Jacobi scaling): rounding of two factorizations.
        assert!(diff < 1e-9, "largest difference {diff}");
        assert!(dense.diagonal().min() > 1e-3, "a non-trivial T");
    }
}
