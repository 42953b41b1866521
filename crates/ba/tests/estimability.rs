//! Issue 17: a camera-model parameter that the network cannot determine is named before
//! solving ([`pingcal_ba::solver::check_intrinsics`]), and a network that determines them
//! is not refused.

use crate::common;
use pingcal_ba::CameraKey;
use pingcal_ba::ImageKey;

use pingcal_ba::problem::Problem;
use pingcal_ba::solver::{
    check_intrinsics, precision, solve, Estimability, Options, PrecisionError,
};

/// Indices of the back wall's points in [`common::truth`] (y = 3000 mm, a plane).
fn back_wall(p: &Problem) -> Vec<usize> {
    (0..p.points.len())
        .filter(|&j| (p.points[j].position.y - 3000.0).abs() < 1e-9)
        .collect()
}

/// The first image of `truth` alone with the points `keep`, all held as control, and only
/// the intrinsics named in `free` free. The lens has no distortion (its centre would tie
/// the principal point down) and the image points are exact.
fn single_image(truth: &Problem, keep: &[usize], free: &[&str]) -> Problem {
    let mut p = truth.clone();
    p.images.truncate(1);
    p.observations
        .retain(|o| o.image == ImageKey(0) && keep.contains(&o.point.0));
    p.cameras[0].params[3..].iter_mut().for_each(|v| *v = 0.0);
    let (model, params) = (p.cameras[0].model.clone(), p.cameras[0].params.clone());
    for o in &mut p.observations {
        let xc = p.images[0]
            .camera_from_object
            .transform(&p.points[o.point].position);
        o.uv = model.project(&params, &xc, None, None).expect("in front");
    }
    for pt in &mut p.points {
        pt.fixed = true;
    }
    let names = model.parameter_names();
    p.cameras[0].fixed = names.iter().map(|n| !free.contains(n)).collect();
    p
}

fn not_determinable(p: &Problem) -> String {
    match check_intrinsics(p) {
        Err(PrecisionError::NotDeterminable(why)) => why,
        other => panic!("expected a named defect, got {other:?}"),
    }
}

#[test]
fn a_convergent_rolled_network_determines_every_intrinsic() {
    let truth = common::truth();
    assert_eq!(check_intrinsics(&truth).unwrap(), Estimability::Determined);
    // the same network as a free one (no control): still determined
    let mut free = truth.clone();
    free.points.iter_mut().for_each(|p| p.fixed = false);
    assert_eq!(check_intrinsics(&free).unwrap(), Estimability::Determined);
}

#[test]
fn one_image_of_a_plane_cannot_give_the_principal_distance_and_point_together() {
    let truth = common::truth();
    let wall = back_wall(&truth);
    let p = single_image(&truth, &wall, &["c", "xp", "yp"]);
    assert!(
        p.observations.len() >= 20,
        "{} observations",
        p.observations.len()
    );
    let why = not_determinable(&p);
    assert!(
        why.contains("of camera 'left' (1 image)") && why.contains("cannot be determined"),
        "{why}"
    );
    // c alone is determined by one image of a plane (its 8 homography parameters against 7)
    let c_only = single_image(&truth, &wall, &["c"]);
    assert_eq!(check_intrinsics(&c_only).unwrap(), Estimability::Determined);
    // points in depth (the three walls) determine all three: a DLT has 11 parameters
    let all: Vec<usize> = (0..truth.points.len()).collect();
    let depth = single_image(&truth, &all, &["c", "xp", "yp"]);
    assert_eq!(check_intrinsics(&depth).unwrap(), Estimability::Determined);
}

/// What the check names before solving, the precision names after: the same defect, so the
/// test is not stricter than the network's own rank.
#[test]
fn the_defect_named_before_solving_is_the_one_the_precision_finds_after() {
    let truth = common::truth();
    let mut p = single_image(&truth, &back_wall(&truth), &["c", "xp", "yp"]);
    let why = not_determinable(&p);
    assert!(why.starts_with("c, xp and yp of camera 'left'"), "{why}");
    let _ = solve(&mut p, &Options::default(), |_| {});
    match precision(&p) {
        Err(PrecisionError::DatumDefect(why)) => assert!(why.contains("intrinsic"), "{why}"),
        other => panic!("the precision found no defect: {other:?}"),
    }
}

/// Above the dense test's size (a street of 300 images of one shared BAL camera: 1,803
/// reduced unknowns) the check runs with the sparse factor: the shared camera is
/// determined; a second camera given to one image that keeps only 4 of its points (8
/// observations for its 6 pose and 3 camera unknowns; the pose alone is determined) is
/// named, both before solving.
#[test]
fn a_large_network_is_judged_with_the_sparse_factor() {
    use pingcal_ba::solver::MAX_CHECK_UNKNOWNS;
    let spec = pingcal_ba::synthetic::SyntheticBal {
        cameras: 300,
        points: 6000,
        ..Default::default()
    };
    let mut p = spec.generate().unwrap().problem;
    p.cameras.truncate(1);
    p.cameras[0].name = "street".into();
    for im in &mut p.images {
        im.camera = CameraKey(0);
    }
    let n = 6 * p.images.len() + p.cameras[0].params.len();
    assert!(n > MAX_CHECK_UNKNOWNS);
    assert_eq!(check_intrinsics(&p).unwrap(), Estimability::Determined);
    let mut spare = p.cameras[0].clone();
    spare.name = "spare".into();
    p.cameras.push(spare);
    let lone = 150;
    p.images[lone].camera = CameraKey(1);
    let mut kept = 0;
    p.observations.retain(|o| {
        if o.image != ImageKey(lone) {
            return true;
        }
        kept += 1;
        kept <= 4
    });
    let why = not_determinable(&p);
    assert!(why.contains("'spare'"), "{why}");
    assert!(!why.contains("'street'"), "{why}");
}
