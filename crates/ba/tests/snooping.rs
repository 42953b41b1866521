//! Data snooping compares every kind of observation: a typo in a measured distance or in a
//! weighted control point is the observation removed and named, not the image points of
//! its targets, which show only the share of its error the network passes on to them.
//! The network is the self-calibration network of `common` (14 stations, ~80 points) with
//! targets measured to 0.03 px, as pingcal's coded targets are, and its datum given by a
//! fixed image and distances, or by weighted control.
//!
//! What makes a typo detectable is the redundancy number q of the observation: its error ∇
//! shows in its own w as `∇ √q / σ`, and in a correlated observation's w at most that. A
//! caliper distance of σ 0.1 mm over 2–3 m keeps q near ½ when the network itself measures
//! that distance to about 0.1 mm (targets to a few hundredths of a pixel), and the 5 mm typo
//! gives w ≈ 35; in a network of 0.3 px q falls to ~0.005 and 5 mm is at the minimal
//! detectable error (4.1 σ / √q ≈ 5.5 mm): there the network bends to the typo instead.

use crate::common;
use pingcal_ba::problem::{Distance, PointPrior, Problem};
use pingcal_ba::solver::{adjust_with_snooping, SnoopResult};
use pingcal_ba::PointKey;

use common::{realisation, to_convergence, truth, SIGMA_PX};

/// The critical |w| of a two-sided test at 0.1 %.
const CRITICAL: f64 = 3.29;

/// The distances of the network: four of ~2–3.5 m between well-spread points, σ 0.1 mm
/// (a caliper on a scale bar).
const DISTANCES: [(usize, usize); 4] = [(0, 40), (12, 70), (3, 55), (25, 64)];

/// The image σ of the targets, px.
const TARGET_SIGMA_PX: f64 = 0.03;

/// A noise realisation of the network with its targets measured to [`TARGET_SIGMA_PX`]: that
/// of `common`, its image noise scaled down.
fn precise(seed: u64) -> Problem {
    let t = truth();
    let mut p = realisation(&t, seed);
    for (o, to) in p.observations.iter_mut().zip(&t.observations) {
        o.uv = to.uv + (o.uv - to.uv) * (TARGET_SIGMA_PX / SIGMA_PX);
        o.sigma = TARGET_SIGMA_PX;
    }
    p
}

/// A realisation whose datum is the first image fixed at its true pose and the measured
/// distances `DISTANCES` (their true values), as in pingcal's calibration.
fn with_distances(seed: u64) -> Problem {
    let t = truth();
    let mut p = precise(seed);
    p.points.iter_mut().for_each(|pt| pt.fixed = false);
    p.images[0].camera_from_object = t.images[0].camera_from_object;
    p.images[0].fixed = true;
    for (a, b) in DISTANCES {
        p.distances.push(Distance {
            a: PointKey(a),
            b: PointKey(b),
            value: (t.points[a].position - t.points[b].position).norm(),
            sigma: 0.1,
        });
    }
    p
}

/// A realisation whose datum is six weighted control points at their true positions
/// (σ 0.5 mm per axis), no image fixed.
fn with_control(seed: u64) -> Problem {
    let t = truth();
    let mut p = precise(seed);
    p.points.iter_mut().for_each(|pt| pt.fixed = false);
    for k in [0usize, 12, 40, 70, 25, 55] {
        p.point_priors.push(PointPrior {
            point: PointKey(k),
            position: t.points[k].position,
            sigma: nalgebra::Vector3::repeat(0.5),
        });
    }
    p
}

fn snoop(p: &mut Problem) -> SnoopResult {
    let max = p.observations.len() / 20;
    adjust_with_snooping(p, &to_convergence(), CRITICAL, max).expect("adjusted")
}

/// The image points rejected, as (image, point).
fn image_points(r: &SnoopResult) -> Vec<(String, String)> {
    (r.rejected.iter())
        .map(|x| (x.image.clone(), x.point.clone()))
        .collect()
}

/// A clean network loses no distance and no control point, and only the image points a
/// 0.1 % test rejects by chance: ~2,000 good coordinates give 2 on average, and more than 8
/// (Poisson, p < 1e-3) would mean the statistic is wrong.
#[test]
fn a_clean_network_removes_nothing_beyond_the_expected_rate() {
    for (mut p, what) in [
        (with_distances(11), "distances"),
        (with_control(12), "control"),
    ] {
        let r = snoop(&mut p);
        assert!(
            r.rejected_distances.is_empty(),
            "{what}: {:?}",
            r.rejected_distances
        );
        assert!(
            r.rejected_control_points.is_empty(),
            "{what}: {:?}",
            r.rejected_control_points
        );
        assert!(r.rejected.len() <= 8, "{what}: {:?}", image_points(&r));
        assert!(
            (r.precision.sigma0 - 1.0).abs() < 0.1,
            "{what}: σ0 {}",
            r.precision.sigma0
        );
    }
}

/// A 5 mm typo in any one distance (50 σ): that distance is the observation removed, its
/// given and estimated values are reported, and the image points rejected are exactly those
/// of the clean network (none in its place).
#[test]
fn a_typo_in_a_distance_is_removed_and_named_not_its_targets_image_points() {
    let seed = 21;
    let clean = image_points(&snoop(&mut with_distances(seed)));
    for (k, &(a, b)) in DISTANCES.iter().enumerate() {
        let mut p = with_distances(seed);
        p.distances[k].value += 5.0;
        let (given, truth_value) = (p.distances[k].value, p.distances[k].value - 5.0);
        let r = snoop(&mut p);
        assert_eq!(
            r.rejected_distances.len(),
            1,
            "distance {k}: {:?}",
            r.rejected_distances
        );
        let d = &r.rejected_distances[0];
        println!(
            "distance {k} +5 mm: w {:.1}, given {:.3}, estimated {:.3} (truth {truth_value:.3}), image points rejected {:?}",
            d.w, d.given, d.estimated, image_points(&r)
        );
        assert_eq!(
            (d.a.as_str(), d.b.as_str()),
            (&*format!("P{a}"), &*format!("P{b}"))
        );
        assert_eq!(d.given, given);
        // w: the 50 σ error times √q_vv, q_vv below 1 as the other distances and the rays
        // share the scale
        assert!(d.w.abs() > 10.0, "distance {k}: w {}", d.w);
        // estimated without it, from the other distances: within a few of their σ
        assert!(
            (d.estimated - truth_value).abs() < 0.5,
            "distance {k}: estimated {} for {truth_value}",
            d.estimated
        );
        assert_eq!(image_points(&r), clean, "distance {k}");
        assert_eq!(p.distances.len(), DISTANCES.len() - 1);
    }
}

/// A 5 mm typo in one coordinate of a control point (10 σ): that control point is removed
/// and named, with the coordinates given and estimated; the image points rejected are
/// those of the clean network.
#[test]
fn a_typo_in_a_control_point_is_removed_and_named_not_its_image_points() {
    let seed = 31;
    let clean = image_points(&snoop(&mut with_control(seed)));
    for (k, axis) in [(1usize, 0usize), (3, 2)] {
        let mut p = with_control(seed);
        let truth_value = p.point_priors[k].position;
        p.point_priors[k].position[axis] += 5.0;
        let name = p.points[p.point_priors[k].point].name.clone();
        let r = snoop(&mut p);
        assert_eq!(
            r.rejected_control_points.len(),
            1,
            "control {k}: {:?}",
            r.rejected_control_points
        );
        let c = &r.rejected_control_points[0];
        println!(
            "control {name} +5 mm in axis {axis}: w {:?}, estimated {:?}, image points rejected {:?}",
            c.w, c.estimated, image_points(&r)
        );
        assert_eq!(c.point, name);
        assert_eq!(c.given[axis], truth_value[axis] + 5.0);
        assert!(c.w[axis].abs() > 5.0, "control {k}: w {:?}", c.w);
        assert!(
            (c.estimated[axis] - truth_value[axis]).abs() < 2.0,
            "control {k}: estimated {:?} for {truth_value:?}",
            c.estimated
        );
        assert!(r.rejected_distances.is_empty());
        assert_eq!(image_points(&r), clean, "control {k}");
    }
}

/// A typo in one of three control points that alone fix the datum (7 degrees of freedom
/// from 9 coordinates): data snooping finds it, but without it the datum is lost, and the
/// adjustment is refused naming the control point and the defect rather than ending with a
/// datum defect that does not say why.
#[test]
fn a_typo_in_a_control_point_the_datum_needs_is_refused_by_name() {
    let t = truth();
    let mut p = precise(41);
    p.points.iter_mut().for_each(|pt| pt.fixed = false);
    for k in [0usize, 40, 70] {
        p.point_priors.push(PointPrior {
            point: PointKey(k),
            position: t.points[k].position,
            sigma: nalgebra::Vector3::repeat(0.5),
        });
    }
    p.point_priors[1].position.x += 5.0;
    let max = p.observations.len() / 20;
    let e = adjust_with_snooping(&mut p, &to_convergence(), CRITICAL, max)
        .expect_err("the datum's control point was removed");
    let text = e.to_string();
    println!("{text}");
    assert!(
        matches!(e, pingcal_ba::solver::SnoopError::DatumLost { .. }),
        "{text}"
    );
    assert!(text.contains("control point P40"), "{text}");
    assert!(
        text.contains("datum defect") || text.contains("free"),
        "{text}"
    );
}
