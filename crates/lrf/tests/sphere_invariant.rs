//! Issue 15: a sphere's inliers lie on it. In the real frame `L2_S3` of
//! ../shared/data/spherecalib-vlp16 the finder used to report a sphere whose 781 "inliers"
//! passed 548–685 mm from its centre (radius 300 mm): the along-ray fit's gate was held at
//! its starting centre while the centre moved. Every ball of every real frame must now have
//! each inlier ray meeting the sphere, within kσ of it along the ray.

use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::Cloud;
use pingcal_lrf::sphere_fit::{ray_on_sphere, Ray};
use std::path::Path;

fn read_metres(path: &Path) -> Cloud {
    let text = std::fs::read_to_string(path).unwrap();
    let pts = text
        .lines()
        .filter_map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .filter_map(|t| t.parse().ok())
                .collect();
            (v.len() >= 3).then(|| nalgebra::Vector3::new(v[0], v[1], v[2]) * 1000.0)
        })
        .collect();
    Cloud::from_points(pts)
}

#[test]
fn every_inlier_of_every_real_ball_lies_on_it() {
    let dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/spherecalib-vlp16/scans");
    if !dir.is_dir() {
        println!("skipped: {} is absent", dir.display());
        return;
    }
    let opt = FinderOptions {
        diameter_mm: 600.0,
        ..Default::default()
    };
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    names.sort();
    for f in names {
        let cloud = read_metres(&f);
        let found = find_balls(&cloud, &opt);
        for b in &found.balls {
            for &i in &b.inliers {
                let p = cloud.points[i];
                let ray = Ray::from_point(cloud.origin(i), p, opt.noise.sigma(p.norm()).max(0.5));
                assert!(
                    ray_on_sphere(&ray, &b.centre, 300.0, opt.fit.outlier_k + 0.5),
                    "{}: ball at {:?}: inlier {i} at {p:?} is not on it",
                    f.display(),
                    b.centre
                );
            }
        }
    }
}

/// Issue 15: on each real frame exactly one sphere (the 0.6 m ball), with the VLP-16 noise
/// profile, and its centre where an independent fit puts it
/// (`bench/lrf/vlp16_reference.py`: numpy/scipy RANSAC with a shadow test, then a
/// fixed-radius orthogonal Huber fit; its output is `tests/data/vlp16_reference.csv`).
/// The two fits differ in their model (along the beam, 70° incidence gate, against
/// orthogonal on every facing point), so they agree to their σ only where the ball's real
/// radius is the nominal 300 mm; where a free-radius fit gives r ≠ 300 mm, the two place
/// the fixed-radius centre differently along the mismatch, by up to |r − 300|. Bound:
/// 3 σ (both fits' σ combined) + |r − 300|.
#[test]
fn one_sphere_per_real_frame_where_an_independent_fit_puts_it() {
    let dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/spherecalib-vlp16/scans");
    if !dir.is_dir() {
        println!("skipped: {} is absent", dir.display());
        return;
    }
    let reference = include_str!("data/vlp16_reference.csv");
    let opt = FinderOptions {
        diameter_mm: 600.0,
        noise: pingcal_lrf::sensor::RangeNoise::named("VLP-16").unwrap(),
        ..Default::default()
    };
    println!("frame   pingcal centre (mm)            reference centre (mm)          |Δ| mm  bound  free r  ms");
    for line in reference.lines().skip(1) {
        let v: Vec<&str> = line.split(',').collect();
        let num = |k: usize| v[k].parse::<f64>().unwrap();
        let (c_ref, s_ref) = (
            nalgebra::Vector3::new(num(1), num(2), num(3)),
            nalgebra::Vector3::new(num(4), num(5), num(6)),
        );
        let cloud = read_metres(&dir.join(format!("{}.xyz", v[0])));
        let t0 = std::time::Instant::now();
        let found = find_balls(&cloud, &opt);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        assert_eq!(
            found.balls.len(),
            1,
            "{}: {} spheres: {:?}",
            v[0],
            found.balls.len(),
            found.balls.iter().map(|b| b.centre).collect::<Vec<_>>()
        );
        let b = &found.balls[0];
        let d = b.centre - c_ref;
        let s2 = b.cov.diagonal() * b.sigma0.max(1.0).powi(2) + s_ref.component_mul(&s_ref);
        let mismatch = (b.support.free_radius_mm - 300.0).abs();
        let bound = 3.0 * s2.sum().sqrt() + mismatch;
        println!(
            "{}  ({:8.1}, {:7.1}, {:6.1})  ({:8.1}, {:7.1}, {:6.1})  {:6.1}  {:5.1}  {:6.1}  {:.0}",
            v[0],
            b.centre.x,
            b.centre.y,
            b.centre.z,
            c_ref.x,
            c_ref.y,
            c_ref.z,
            d.norm(),
            bound,
            b.support.free_radius_mm,
            ms
        );
        assert!(
            d.norm() <= bound,
            "{}: centre {:?} is {:.1} mm from the reference {:?} (bound {bound:.1})",
            v[0],
            b.centre,
            d.norm(),
            c_ref
        );
    }
}
