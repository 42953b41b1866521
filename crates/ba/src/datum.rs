//! The datum of a network, diagnosed before solving: what fixes its position, orientation
//! and scale (7 degrees of freedom), and whether that is too little or too much.
//!
//! A network's datum comes either from the problem itself — fixed control points, weighted
//! control (point priors), fixed images, a fixed rig — or, when it has none of these, from
//! inner constraints on its object points: a *free network* (the solver's minimum-trace
//! precision, [`crate::solver::precision`]), its scale from distances if any are given.
//! [`check`] says which, or why neither holds:
//!
//! * too little: no control and no free network asked; or control that leaves degrees of
//!   freedom open (fewer than 3 control points, or all on one line; one fixed image and
//!   nothing giving the scale);
//! * too much: a free network asked for a network whose datum is already fixed (inner
//!   constraints on top of control would distort it).
//!
//! Coordinates held one by one ([`crate::problem::Point::fixed_axes`]) are counted by the
//! similarity they fix. With the network moved by `X ↦ X + t + ω × (X − c) + s (X − c)`
//! (c the centroid of what is held, 7 parameters `(t, ω, s)`), each held coordinate a of a
//! point X (or of an image's projection centre) is one linear equation `t_a + (ω × (X − c))_a + s (X − c)_a = 0` on them; a
//! fully fixed or weighted control point gives three, a fixed image six (its centre, and
//! `ω = 0` for its orientation), a distance or a fixed rig one (`s = 0`). The datum is
//! defined when these equations have rank 7: e.g. X, Y, Z of one point, X, Y, Z of another
//! and Z of a third (a *minimal* datum), unless the third lies in the vertical plane through
//! the first two (a rotation about their line then moves it horizontally only). A rank below
//! 7 is too little, and the open motions are named.

use crate::problem::Problem;
use nalgebra::Vector3;

/// How a network's datum is defined.
#[derive(Clone, Debug, PartialEq)]
pub enum Datum {
    /// By the problem: fixed control, weighted control, fixed images or rigs.
    Given {
        /// Control points held fixed.
        fixed_control: usize,
        /// Control points with a prior (weighted control).
        weighted_control: usize,
        /// Images held fixed.
        fixed_images: usize,
        /// Rigs held fixed.
        fixed_rigs: usize,
        /// Single coordinates held: of points that are not held whole, and of the
        /// projection centres of images that are not fixed.
        held_coordinates: usize,
    },
    /// By inner constraints on the object points (a free network).
    FreeNetwork {
        /// Whether distances fix the scale (6 free degrees of freedom rather than 7).
        scale_from_distances: bool,
    },
}

/// Why the datum is not well defined.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum DatumError {
    /// Nothing, or not enough, fixes the network.
    #[error("the datum is not defined: {0}")]
    TooLittle(String),
    /// A free network asked for a network that is already fixed.
    #[error("the datum is defined twice: {0}")]
    TooMuch(String),
}

/// Whether the points lie on one line (or coincide), relative to their spread.
fn collinear(points: &[Vector3<f64>]) -> bool {
    let Some(first) = points.first() else {
        return true;
    };
    let Some(far) = points
        .iter()
        .max_by(|a, b| (*a - first).norm().total_cmp(&(*b - first).norm()))
    else {
        return true;
    };
    let axis = far - first;
    let len = axis.norm();
    if !(len > 0.0) {
        return true;
    }
    let d = axis / len;
    points.iter().all(|p| {
        let v = p - first;
        (v - d * v.dot(&d)).norm() <= 1e-6 * len
    })
}

fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// Whether anything of `problem` itself fixes its datum: a control point (fixed or
/// weighted), a fixed image or rig, or a held coordinate. Without any, the network is a free
/// one, and only distances give it a scale.
pub fn has_datum(problem: &Problem) -> bool {
    problem
        .points
        .iter()
        .any(|p| p.is_held() || p.is_partly_held())
        || !problem.point_priors.is_empty()
        || problem.images.iter().any(|i| i.fixed || i.is_centre_held())
        || problem.rigs.iter().any(|r| r.fixed)
}

/// Diagnoses the datum of `problem`; `free_network`: the caller asks for one (datum by
/// inner constraints). See the module doc.
pub fn check(problem: &Problem, free_network: bool) -> Result<Datum, DatumError> {
    let fixed_control: Vec<Vector3<f64>> = problem
        .points
        .iter()
        .filter(|p| p.is_held())
        .map(|p| p.position)
        .collect();
    let weighted: Vec<Vector3<f64>> = problem.point_priors.iter().map(|p| p.position).collect();
    let fixed_images = problem.images.iter().filter(|i| i.fixed).count();
    let fixed_rigs = problem.rigs.iter().filter(|r| r.fixed).count();
    let mut given = Vec::new();
    if !fixed_control.is_empty() {
        given.push(plural(
            fixed_control.len(),
            "fixed control point",
            "fixed control points",
        ));
    }
    if !weighted.is_empty() {
        given.push(plural(
            weighted.len(),
            "weighted control point",
            "weighted control points",
        ));
    }
    if fixed_images > 0 {
        given.push(plural(fixed_images, "fixed image", "fixed images"));
    }
    if fixed_rigs > 0 {
        given.push(plural(fixed_rigs, "fixed rig", "fixed rigs"));
    }
    let partly: Vec<usize> = (0..problem.points.len())
        .filter(|&p| problem.points[p].is_partly_held())
        .collect();
    let centres: Vec<usize> = (0..problem.images.len())
        .filter(|&i| problem.images[i].is_centre_held())
        .collect();
    let held_coordinates: usize = (partly.iter())
        .map(|&p| 3 - problem.points[p].free_axes().len())
        .chain(
            centres
                .iter()
                .map(|&i| 3 - problem.images[i].free_centre_axes().len()),
        )
        .sum();
    if held_coordinates > 0 {
        given.push(format!(
            "{} ({})",
            plural(held_coordinates, "held coordinate", "held coordinates"),
            held_list(problem, &partly, &centres)
        ));
    }
    if free_network {
        if !given.is_empty() {
            return Err(DatumError::TooMuch(format!(
                "a free network (inner constraints) was asked, but {} already fix the network: leave out one or the other",
                given.join(", ")
            )));
        }
        return Ok(Datum::FreeNetwork {
            scale_from_distances: !problem.distances.is_empty(),
        });
    }
    if given.is_empty() {
        return Err(DatumError::TooLittle(
            "no control point, no fixed image and no free network asked: nothing fixes the network's position, orientation and scale; give control points or ask for a free network".into(),
        ));
    }
    let datum = Datum::Given {
        fixed_control: fixed_control.len(),
        weighted_control: weighted.len(),
        fixed_images,
        fixed_rigs,
        held_coordinates,
    };
    if held_coordinates > 0 {
        let open = open_motions(problem);
        if open.is_empty() {
            return Ok(datum);
        }
        return Err(DatumError::TooLittle(format!(
            "{} leave {} of the network's position, orientation and scale open ({}): 7 independent held coordinates are needed, e.g. X, Y, Z of one point, X, Y, Z of another and one coordinate of a third off their line, or ask for a free network",
            given.join(", "),
            plural(open.len(), "degree of freedom", "degrees of freedom"),
            describe_open(&open)
        )));
    }
    if fixed_rigs > 0 || fixed_images >= 2 {
        return Ok(datum);
    }
    let control: Vec<Vector3<f64>> = fixed_control.iter().chain(&weighted).copied().collect();
    if fixed_images == 1 {
        if control.is_empty() && problem.distances.is_empty() {
            return Err(DatumError::TooLittle(
                "1 fixed image fixes the position and orientation but not the scale: give a distance or control points, or ask for a free network".into(),
            ));
        }
        return Ok(datum);
    }
    if control.len() < 3 {
        return Err(DatumError::TooLittle(format!(
            "{} leave the rotation about {} free: 3 not on one line are needed, or ask for a free network",
            given.join(", "),
            if control.len() == 1 { "that point" } else { "their line" }
        )));
    }
    if collinear(&control) {
        return Err(DatumError::TooLittle(format!(
            "the {} lie on one line, which leaves the rotation about it free: 3 not on one line are needed, or ask for a free network",
            given.join(", ")
        )));
    }
    Ok(datum)
}

/// The held coordinates of the partly held points `partly` and of the image centres
/// `centres`, by name: `Z of 'P3'; X, Y of 'P7'; X, Y, Z of the centre of 'S00'` (the first
/// 6, then how many more).
fn held_list(problem: &Problem, partly: &[usize], centres: &[usize]) -> String {
    let axes = |h: [bool; 3]| -> String {
        let names: Vec<&str> = (0..3).filter(|&a| h[a]).map(|a| AXES[a]).collect();
        names.join(", ")
    };
    let points = partly.iter().map(|&p| {
        let pt = &problem.points[p];
        format!("{} of '{}'", axes(pt.held()), pt.name)
    });
    let images = centres.iter().map(|&i| {
        let im = &problem.images[i];
        format!("{} of the centre of '{}'", axes(im.fixed_centre), im.name)
    });
    let all: Vec<String> = points.chain(images).collect();
    let mut parts: Vec<String> = all.iter().take(6).cloned().collect();
    if all.len() > 6 {
        parts.push(format!("{} more", all.len() - 6));
    }
    parts.join("; ")
}

const AXES: [&str; 3] = ["X", "Y", "Z"];

/// The 7 motions of a similarity, in the order of the parameters `(t, ω, s)`.
const MOTIONS: [&str; 7] = [
    "translation along X",
    "translation along Y",
    "translation along Z",
    "rotation about X",
    "rotation about Y",
    "rotation about Z",
    "scale",
];

/// A basis of the similarity motions `(t, ω, s)` (see the module doc; ω and s in units of
/// the spread of what is held) that nothing in `problem` fixes: empty when the datum is
/// defined.
fn open_motions(problem: &Problem) -> Vec<nalgebra::SVector<f64, 7>> {
    // What is held as points: (position, held axes).
    let mut held: Vec<(Vector3<f64>, [bool; 3])> = (problem.points.iter())
        .filter(|p| p.held().iter().any(|h| *h))
        .map(|p| (p.position, p.held()))
        .collect();
    held.extend((problem.point_priors.iter()).map(|c| (c.position, [true; 3])));
    let fixed_images: Vec<Vector3<f64>> = (problem.images.iter())
        .filter(|i| i.fixed)
        .map(|i| i.camera_from_object.centre())
        .collect();
    held.extend(fixed_images.iter().map(|c| (*c, [true; 3])));
    // A held centre coordinate moves with the network as a point's does.
    held.extend(
        (problem.images.iter())
            .filter(|i| i.is_centre_held())
            .map(|i| (i.camera_from_object.centre(), i.fixed_centre)),
    );
    let n = held.len().max(1) as f64;
    let c = held.iter().map(|(x, _)| x).sum::<Vector3<f64>>() / n;
    let spread = (held
        .iter()
        .map(|(x, _)| (x - c).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let spread = if spread > 0.0 { spread } else { 1.0 };
    let mut rows: Vec<[f64; 7]> = Vec::new();
    for (x, axes) in &held {
        let x = (x - c) / spread;
        for a in (0..3).filter(|&a| axes[a]) {
            let mut row = [0.0; 7];
            row[a] = 1.0;
            for k in 0..3 {
                row[3 + k] = Vector3::ith(k, 1.0).cross(&x)[a];
            }
            row[6] = x[a];
            rows.push(row);
        }
    }
    for _ in &fixed_images {
        for k in 0..3 {
            let mut row = [0.0; 7];
            row[3 + k] = 1.0;
            rows.push(row);
        }
    }
    let fixed_rigs = problem.rigs.iter().filter(|r| r.fixed).count();
    if !problem.distances.is_empty() || fixed_rigs > 0 {
        let mut row = [0.0; 7];
        row[6] = 1.0;
        rows.push(row);
    }
    // The null space of the equations, from the eigenvectors of AᵀA.
    let mut ata = nalgebra::SMatrix::<f64, 7, 7>::zeros();
    for r in &rows {
        let v = nalgebra::SVector::<f64, 7>::from_column_slice(r);
        ata += v * v.transpose();
    }
    let eig = ata.symmetric_eigen();
    let max = eig.eigenvalues.max().max(1.0);
    (0..7)
        .filter(|&k| eig.eigenvalues[k] < 1e-12 * max)
        .map(|k| eig.eigenvectors.column(k).into_owned())
        .collect()
}

/// The motions of [`MOTIONS`] that take part in the open ones (a share of at least 10 %
/// of a unit motion in their span).
fn describe_open(open: &[nalgebra::SVector<f64, 7>]) -> String {
    let involved: Vec<&str> = (0..7)
        .filter(|&j| open.iter().map(|v| v[j] * v[j]).sum::<f64>() >= 0.1)
        .map(|j| MOTIONS[j])
        .collect();
    involved.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keys::{CameraKey, PointKey};
    use crate::problem::{Distance, Image, Point, PointPrior};

    fn points(xyz: &[[f64; 3]], fixed: bool) -> Vec<Point> {
        xyz.iter()
            .enumerate()
            .map(|(k, p)| Point {
                name: format!("p{k}"),
                position: Vector3::from(*p),
                fixed,
                fixed_axes: [false; 3],
            })
            .collect()
    }

    #[test]
    fn no_control_needs_a_free_network() {
        let p = Problem {
            points: points(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], false),
            ..Problem::default()
        };
        let e = check(&p, false).unwrap_err();
        assert!(matches!(e, DatumError::TooLittle(_)));
        assert!(e.to_string().contains("free network"), "{e}");
        assert_eq!(
            check(&p, true),
            Ok(Datum::FreeNetwork {
                scale_from_distances: false
            })
        );
        let with_distance = Problem {
            distances: vec![metre()],
            ..p
        };
        assert_eq!(
            check(&with_distance, true),
            Ok(Datum::FreeNetwork {
                scale_from_distances: true
            })
        );
    }

    #[test]
    fn a_datum_is_had_from_control_or_a_fixed_image_not_from_free_points() {
        let free = Problem {
            points: points(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], false),
            ..Problem::default()
        };
        assert!(!has_datum(&free));
        let control = Problem {
            points: points(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], true),
            ..Problem::default()
        };
        assert!(has_datum(&control));
    }

    #[test]
    fn control_and_a_free_network_is_too_much() {
        let p = Problem {
            points: points(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], true),
            ..Problem::default()
        };
        assert!(matches!(
            check(&p, false),
            Ok(Datum::Given {
                fixed_control: 3,
                ..
            })
        ));
        let e = check(&p, true).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the datum is defined twice: a free network (inner constraints) was asked, but 3 fixed control points already fix the network: leave out one or the other"
        );
    }

    /// A distance of 1 ± 0.01 between points 0 and 1.
    fn metre() -> Distance {
        Distance {
            a: PointKey(0),
            b: PointKey(1),
            value: 1.0,
            sigma: 0.01,
        }
    }

    /// Why `p`'s datum is refused (the test fails if it is accepted).
    fn refusal(p: &Problem) -> String {
        check(p, false).unwrap_err().to_string()
    }

    #[test]
    fn too_few_or_collinear_control_is_too_little() {
        let two = Problem {
            points: points(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], true),
            ..Problem::default()
        };
        assert!(refusal(&two)
            .contains("2 fixed control points leave the rotation about their line free"));
        let line = Problem {
            points: points(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], true),
            ..Problem::default()
        };
        assert!(refusal(&line).contains("on one line"));
        // Two fixed and one weighted point off their line fix it.
        let mut mixed = two.clone();
        mixed.points.extend(points(&[[0.0, 1.0, 0.0]], false));
        mixed.point_priors.push(PointPrior {
            point: PointKey(2),
            position: Vector3::new(0.0, 1.0, 0.0),
            sigma: Vector3::repeat(0.1),
        });
        assert!(check(&mixed, false).is_ok());
    }

    #[test]
    fn one_fixed_image_needs_a_scale() {
        let p = Problem {
            images: vec![Image {
                name: "main".into(),
                camera: CameraKey(0),
                camera_from_object: Default::default(),
                fixed: true,
                fixed_centre: [false; 3],
            }],
            points: points(&[[0.0, 0.0, 5.0], [1.0, 0.0, 5.0]], false),
            ..Problem::default()
        };
        assert!(refusal(&p).contains("not the scale"));
        let scaled = Problem {
            distances: vec![metre()],
            ..p
        };
        assert!(check(&scaled, false).is_ok());
    }
}
