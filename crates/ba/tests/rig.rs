//! A stereo head as a rig: the right image of every station follows the left one through
//! one shared relative pose, adjusted together with both cameras' intrinsics. Over noise
//! realisations the recovered rig (baseline and relative rotation) is unbiased, its
//! reported covariance ([`pingcal_ba::solver::Precision::rig_covariances`]) is honest, and an
//! image not tied to the rig keeps its own pose.

use crate::common;
use pingcal_ba::CameraKey;

use common::{observe, to_convergence, truth, SIGMA_PX};
use nalgebra::{Vector2, Vector3};
use pingcal_ba::problem::{Camera, Image, Problem, Rig, RigMember};
use pingcal_ba::solver::{precision, solve, Options};
use pingcal_ba::{ImageKey, PosePrior, ResidualBlock};
use pingcal_geometry::Rigid3;
use pingcal_geometry::{exp_so3, log_so3};
use rand_distr::{Distribution, Normal};

/// Left network of `common` plus a right camera 120 mm to the right, slightly toed in.
fn stereo_truth() -> (Problem, Rigid3) {
    let mut p = truth();
    let right_cam = Camera::new("right", p.cameras[0].model.clone(), {
        let mut v = p.cameras[0].params.clone();
        v[0] = 2.46;
        v[1] = -0.01;
        v
    });
    p.cameras.push(right_cam);
    // Base (left) camera frame → right camera frame: the right centre is at +120 mm on the
    // left camera's X axis, rotated 1° about its Z (up) axis.
    let rot = exp_so3(&Vector3::new(0.0, 0.0, 1f64.to_radians()));
    let rig = Rigid3::from_rotation_and_centre(rot, Vector3::new(120.0, 0.0, 0.0));
    let n_left = p.images.len();
    let mut members = Vec::new();
    for i in 0..n_left {
        let pose = rig.compose(&p.images[i].camera_from_object);
        p.images.push(Image {
            name: format!("{}-right", p.images[i].name),
            camera: CameraKey(1),
            camera_from_object: pose,
            fixed: false,
            fixed_centre: [false; 3],
        });
        members.push(RigMember {
            image: ImageKey(n_left + i),
            base: ImageKey(i),
        });
    }
    // The right images see through the right camera.
    let n = p.images.len();
    observe(&mut p, n_left..n);
    p.rigs.push(Rig {
        name: "stereo".into(),
        member_from_base: rig,
        fixed: false,
        members,
    });
    (p, rig)
}

#[test]
fn stereo_rig_is_recovered_without_bias() {
    let (t, rig_true) = stereo_truth();
    let runs = 20;
    let mut errs: Vec<[f64; 6]> = Vec::new();
    let mut z2 = [0.0; 6];
    for run in 0..runs {
        let mut rng = pingcal_geometry::consensus::rng(900 + run);
        let n = Normal::new(0.0, 1.0).unwrap();
        let mut p = t.clone();
        for o in &mut p.observations {
            o.uv += Vector2::new(n.sample(&mut rng), n.sample(&mut rng)) * SIGMA_PX;
        }
        // Start from a rough rig (5 mm, 0.5°) and perturbed left poses.
        let r0 = &p.rigs[0].member_from_base;
        p.rigs[0].member_from_base = Rigid3::from_rotation_and_centre(
            exp_so3(&Vector3::new(0.004, -0.006, 0.008)) * r0.rotation,
            r0.centre() + Vector3::new(5.0, -3.0, 2.0),
        );
        for im in p.images.iter_mut().take(14) {
            let c = im.camera_from_object.centre()
                + Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 20.0;
            im.camera_from_object =
                Rigid3::from_rotation_and_centre(im.camera_from_object.rotation, c);
        }
        solve(&mut p, &to_convergence(), |_| {}).unwrap();
        let r = &p.rigs[0].member_from_base;
        let dc = r.centre() - rig_true.centre();
        let dw = log_so3(&(r.rotation * rig_true.rotation.transpose()));
        errs.push([dc.x, dc.y, dc.z, dw.x, dw.y, dw.z]);
        // The rig's reported covariance, in its update's terms (δω, δt of member_from_base)
        let cov = precision(&p).unwrap().rig_covariances[0].unwrap();
        let dt = r.translation - rig_true.translation;
        let e = [dw.x, dw.y, dw.z, dt.x, dt.y, dt.z];
        for (k, ek) in e.iter().enumerate() {
            z2[k] += ek * ek / cov[(k, k)];
        }
        // Members follow: the right pose is the rig composed with the left pose.
        let expect = r.compose(&p.images[3].camera_from_object);
        assert!((p.images[17].camera_from_object.rotation - expect.rotation).norm() < 1e-12);
        assert!((p.images[17].camera_from_object.translation - expect.translation).norm() < 1e-9);
    }
    for k in 0..6 {
        let xs: Vec<f64> = errs.iter().map(|e| e[k]).collect();
        let mean = xs.iter().sum::<f64>() / runs as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (runs as f64 - 1.0)).sqrt();
        println!("rig component {k}: mean error {mean:+.3e}, sd {sd:.3e}");
        // Unbiased: |mean| within 4 standard errors (t with 19 dof: P > 1e-3 false alarm).
        assert!(
            mean.abs() < 4.0 * sd / (runs as f64).sqrt() + 1e-9,
            "component {k}: mean {mean}, sd {sd}"
        );
        // The reported σ is honest: Σz²/runs is χ²(20)/20, within 0.372-2.266 but for 0.1 %
        // in each tail (the six components: about 1.2 % false alarms in all)
        let chi = z2[k] / runs as f64;
        println!("rig update component {k}: mean z² {chi:.3}");
        assert!(
            (0.372..2.266).contains(&chi),
            "component {k}: mean z² {chi}"
        );
        // And far better than the 5 mm / 0.5° start.
        assert!(
            sd < if k < 3 { 1.0 } else { 1e-3 },
            "component {k}: sd {sd}"
        );
    }
}

/// A rig's base image with held centre coordinates: its members' observations reach the
/// unknowns (δω, δC) of the base, so the minimum is that of the same problem with those
/// coordinates held by a stiff pose prior instead; held centre coordinates on a member
/// (whose pose follows its base) are refused with a reason.
#[test]
fn a_rig_base_with_held_centre_coordinates_agrees_with_a_stiff_prior() {
    let (t, _) = stereo_truth();
    let mut rng = pingcal_geometry::consensus::rng(77);
    let n = Normal::new(0.0, 1.0).unwrap();
    let mut held = t.clone();
    for o in &mut held.observations {
        o.uv += Vector2::new(n.sample(&mut rng), n.sample(&mut rng)) * SIGMA_PX;
    }
    for im in held.images.iter_mut().take(14) {
        let c = im.camera_from_object.centre()
            + Vector3::new(n.sample(&mut rng), n.sample(&mut rng), n.sample(&mut rng)) * 20.0;
        im.camera_from_object = Rigid3::from_rotation_and_centre(im.camera_from_object.rotation, c);
    }
    let (base, axes) = (3usize, [true, true, false]);
    let pose = held.images[base].camera_from_object;
    let mut c = pose.centre();
    let ct = t.images[base].camera_from_object.centre();
    for a in (0..3).filter(|&a| axes[a]) {
        c[a] = ct[a] + 0.7; // held a little off the truth, so that it matters
    }
    held.images[base].camera_from_object = Rigid3::from_rotation_and_centre(pose.rotation, c);
    held.images[base].fixed_centre = axes;
    let mut stiff = held.clone();
    stiff.images[base].fixed_centre = [false; 3];
    stiff.residuals.push(ResidualBlock::new(PosePrior {
        image: ImageKey(base),
        camera_from_object: held.images[base].camera_from_object,
        sigma_rotation: Vector3::repeat(f64::INFINITY),
        sigma_centre: Vector3::from_fn(|a, _| if axes[a] { 1e-5 } else { f64::INFINITY }),
    }));
    let opts = Options {
        function_tolerance: 1e-14,
        gradient_tolerance: 1e-14,
        parameter_tolerance: 1e-14,
        max_iterations: 200,
        threads: 1,
        ..Options::default()
    };
    let mut reference = stiff.clone();
    solve(&mut reference, &opts, |_| {}).unwrap();
    let mut p = held.clone();
    solve(&mut p, &opts, |_| {}).unwrap();
    let (c0, c1) = (c, p.images[base].camera_from_object.centre());
    for a in (0..3).filter(|&a| axes[a]) {
        assert!((c0[a] - c1[a]).abs() < 1e-9, "held centre {a} moved");
    }
    let worst = (p.images.iter().zip(&reference.images))
        .map(|(x, y)| (x.camera_from_object.centre() - y.camera_from_object.centre()).amax())
        .chain(
            (p.points.iter().zip(&reference.points)).map(|(x, y)| (x.position - y.position).amax()),
        )
        .fold(0.0, f64::max);
    println!("rig base with held centre vs stiff prior: largest difference {worst:.2e} mm");
    assert!(worst < 1e-4, "{worst} mm");
    let (r, rr) = (
        &p.rigs[0].member_from_base,
        &reference.rigs[0].member_from_base,
    );
    assert!((r.centre() - rr.centre()).amax() < 1e-6);
    assert_eq!(
        precision(&p).unwrap().poses[base].as_ref().unwrap().centre[0],
        0.0
    );
    // On a member: refused.
    let mut member = t.clone();
    member.images[17].fixed_centre = [false, false, true];
    let e = solve(&mut member, &opts, |_| {}).unwrap_err().to_string();
    assert!(e.contains("rig member") && e.contains("base image"), "{e}");
}

/// Two rigs on one base camera (a stereo pair and a third camera): the joint covariance of
/// both rigs' updates ([`pingcal_ba::solver::Precision::rigs_and_parameters_covariance`])
/// has each rig's own covariance on its diagonal and, between them, the cross-covariance a
/// pair's relative pose needs: the same from the sparse selected inversion as from the
/// dense inverse, and not zero (both rest on the same base poses).
#[test]
fn two_rigs_have_one_joint_covariance() {
    use pingcal_ba::solver::{precision_with, CofactorMethod};
    let (mut p, _) = stereo_truth();
    let third = Camera::new(
        "third",
        p.cameras[0].model.clone(),
        p.cameras[0].params.clone(),
    );
    p.cameras.push(third);
    let side = Rigid3::from_rotation_and_centre(
        exp_so3(&Vector3::new(0.0, 0.0, 8f64.to_radians())),
        Vector3::new(-60.0, 10.0, 5.0),
    );
    let n_left = p.rigs[0].members.len();
    let first = p.images.len();
    let mut members = Vec::new();
    for i in 0..n_left {
        p.images.push(Image {
            name: format!("{}-third", p.images[i].name),
            camera: CameraKey(2),
            camera_from_object: side.compose(&p.images[i].camera_from_object),
            fixed: false,
            fixed_centre: [false; 3],
        });
        members.push(RigMember {
            image: ImageKey(first + i),
            base: ImageKey(i),
        });
    }
    let n = p.images.len();
    observe(&mut p, first..n);
    p.rigs.push(Rig {
        name: "third".into(),
        member_from_base: side,
        fixed: false,
        members,
    });
    // Noise, so that σ0 (and every covariance) is not 0; solved again.
    let mut rng = pingcal_geometry::consensus::rng(52);
    let normal = Normal::new(0.0, 1.0).unwrap();
    for o in &mut p.observations {
        o.uv += Vector2::new(normal.sample(&mut rng), normal.sample(&mut rng)) * SIGMA_PX;
    }
    solve(&mut p, &to_convergence(), |_| {}).unwrap();
    let sparse = precision_with(&p, CofactorMethod::Sparse).unwrap();
    let dense = precision_with(&p, CofactorMethod::Dense).unwrap();
    let joint = &sparse.rigs_and_parameters_covariance;
    assert_eq!(joint.shape(), (12, 12));
    let scale = joint.diagonal().max();
    for r in 0..2 {
        let own = sparse.rig_covariances[r].unwrap();
        let block = joint.fixed_view::<6, 6>(6 * r, 6 * r);
        assert!((block - own).norm() <= 1e-9 * scale, "rig {r}'s own block");
    }
    let diff = (joint - &dense.rigs_and_parameters_covariance).norm();
    assert!(
        diff <= 1e-8 * scale,
        "sparse against dense: {diff} (scale {scale})"
    );
    let cross = joint.view((0, 6), (6, 6)).norm();
    assert!(cross > 1e-3 * scale, "the rigs look uncorrelated: {cross}");
}
