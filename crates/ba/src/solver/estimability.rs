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
use super::precision::{invert_or_diagnose, jacobi_scale, linearized, reduced_system};
use super::sigma::PrecisionError;
use crate::datum::{check, Datum};
use crate::problem::Problem;
use nalgebra::DMatrix;

/// An eigenvalue of the Jacobi-scaled T below this is a null direction. In the tests the
/// convergent rolled network's weakest combination of its ten intrinsics is 8e-4, one image
/// of a plane with c alone free 2e-2 and with c, xp, yp free 3e-16 (rounding); intrinsics
/// correlated at 0.9999 would give about 1e-4.
pub const NULL_EIGENVALUE: f64 = 1e-9;

/// The largest reduced system judged before solving: its dense Cholesky (n³/3 flops, about
/// a second at this size) must stay small against the adjustment it precedes.
pub const MAX_CHECK_UNKNOWNS: usize = 1500;

/// A component of a null vector above this share of its largest one names a parameter.
const NAMED_SHARE: f64 = 0.1;

/// What [`check_intrinsics`] found.
#[derive(Clone, Debug, PartialEq)]
pub enum Estimability {
    /// Every free intrinsic is determined (to first order at the start values).
    Determined,
    /// The reduced system is too large for the dense test (more than
    /// [`MAX_CHECK_UNKNOWNS`] unknowns): not judged before solving (the precision after the
    /// adjustment names a defect).
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
    if n > MAX_CHECK_UNKNOWNS {
        return Ok(Estimability::NotChecked(n));
    }
    let lin = linearized(problem, &layout)?;
    let (_, s) = reduced_system(problem, &layout, &lin)?;
    let d = jacobi_scale(&s);
    let scaled = |i: usize, j: usize| s[(i, j)] * d[i] * d[j];
    let c: Vec<usize> = intrinsic_rows.iter().map(|r| r.row).collect();
    let r: Vec<usize> = (0..n).filter(|i| !c.contains(i)).collect();
    let s_rr = DMatrix::from_fn(r.len(), r.len(), |a, b| scaled(r[a], r[b]));
    let s_rc = DMatrix::from_fn(r.len(), c.len(), |a, b| scaled(r[a], c[b]));
    let s_cc = DMatrix::from_fn(c.len(), c.len(), |a, b| scaled(c[a], c[b]));
    let t = if r.is_empty() {
        s_cc
    } else {
        let Some(chol) = s_rr.cholesky() else {
            // the poses themselves are not determined: name what is free
            return invert_or_diagnose(&s, problem, &layout).map(|_| Estimability::Determined);
        };
        &s_cc - s_rc.transpose() * chol.solve(&s_rc)
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
            let images = problem.images.iter().filter(|i| i.camera == *c).count();
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
