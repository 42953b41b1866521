//! The other range sensors of the head (`[[lrfs]]`, issue 52) in the main calibration's
//! outputs: each was calibrated against the same camera side as a project of its own
//! ([`pingcal_project::Project::range_sensors`]; its outputs are written under
//! `lrfs/<id>/`); here its pose joins results.json's `sensors`, its pairs with the cameras
//! (from its own adjustment with them: σ's with the cross-covariances) and with the range
//! sensors before it (composed) join `sensor_pairs`, and a sensor not calibrated, or whose
//! own verdict is not `ok`, is a reason of the main verdict.
//!
//! **Two range sensors' pair.** Each range sensor was adjusted with the cameras on its own;
//! their relative pose's σ needs the covariance between their extrinsics, which neither
//! adjustment has. The two adjustments are of one bundle, so their problems are joined into
//! one ([`pingcal_ba::Problem::append_sensor`]: the bundle's images, points and observations
//! once, each sensor's blocks and observations at their own variance components) and its
//! covariance is taken at the two solutions ([`joint_pairs`]): the poses stay those each
//! adjustment gave (as every other output has them), their pair's σ's come from the one
//! problem. Where that cannot be had (a sensor without its adjustment, a covariance that
//! fails) the pair's σ's stay null.

use crate::head::WithSigma;
use crate::outcome::RangeSensor;
use crate::results::sensors::{json, pose};
use crate::results::{Results, SensorJson, SensorPairJson};
use crate::verdict::{Status, Verdict};

/// The main verdict with a reason for each of `others` not calibrated or not `ok`
/// (`doubtful` at least then).
pub fn judge(verdict: &mut Verdict, others: &[RangeSensor]) {
    let reasons = in_doubt(others);
    if !reasons.is_empty() && verdict.status == Status::Ok {
        verdict.status = Status::Doubtful;
    }
    verdict.reasons.extend(reasons);
}

/// The other range sensors (`[[lrfs]]`) not calibrated, or whose own verdict is not `ok`:
/// one reason each, with its first reason and where its results are.
fn in_doubt(others: &[RangeSensor]) -> Vec<String> {
    (others.iter())
        .filter_map(|r| match &r.outcome {
            Err(e) => Some(format!(
                "range sensor '{}' ([[lrfs]]) was not calibrated: {e}",
                r.id
            )),
            Ok(o) if o.results.verdict.status != Status::Ok => Some(format!(
                "range sensor '{}' ([[lrfs]]): verdict {} (lrfs/{}/results.json): {}",
                r.id,
                o.results.verdict.status.as_str(),
                r.id,
                o.results.verdict.reasons.first().map_or("", String::as_str)
            )),
            Ok(_) => None,
        })
        .collect()
}

/// The report's summary lines of `others`: each one's verdict and translation, or why it
/// was not calibrated, and where its own report is.
pub fn summary(others: &[RangeSensor]) -> Vec<(String, String)> {
    (others.iter())
        .map(|r| {
            let line = match &r.outcome {
                Ok(o) => {
                    let t = o.results.extrinsic.translation_mm;
                    format!(
                        "a {} 2D LRF, verdict {}; t = ({:.1}, {:.1}, {:.1}) mm; its report: lrfs/{}/report.html",
                        r.kind,
                        o.results.verdict.status.as_str(),
                        t[0],
                        t[1],
                        t[2],
                        r.id
                    )
                }
                Err(e) => format!("not calibrated: {e}"),
            };
            (format!("range sensor '{}'", r.id), line)
        })
        .collect()
}

/// `results`' `sensors` and `sensor_pairs` with each of `others`.
pub fn add_sensors(results: &mut Results, others: &[RangeSensor]) {
    for other in others {
        add_range_sensor(other, &mut results.sensors, &mut results.sensor_pairs);
    }
}

/// One of `[[lrfs]]` into `sensors` and `pairs`: its entry and its pairs with the cameras
/// as its own calibration gave them (one adjustment with the cameras: σ's with the
/// cross-covariances), and its pairs with the range sensors before it composed from the two
/// entries (their σ's from [`joint_pairs`]).
fn add_range_sensor(
    other: &crate::outcome::RangeSensor,
    sensors: &mut Vec<SensorJson>,
    pairs: &mut Vec<SensorPairJson>,
) {
    let Ok(o) = &other.outcome else { return };
    let Some(entry) = o.results.sensors.iter().find(|s| s.id == other.id) else {
        return;
    };
    for s in sensors.iter() {
        let a_from_b = if s.kind == "camera" {
            (o.results.sensor_pairs.iter())
                .find(|p| p.a == s.id && p.b == other.id)
                .map(|p| p.a_from_b.clone())
        } else {
            None
        };
        let a_from_b = a_from_b.unwrap_or_else(|| {
            let relative = pose(&s.camera_from_sensor)
                .inverse()
                .compose(&pose(&entry.camera_from_sensor));
            json(&WithSigma {
                pose: relative,
                sigma_rotation_deg: None,
                sigma_translation_mm: None,
            })
        });
        pairs.push(SensorPairJson {
            a: s.id.clone(),
            b: other.id.clone(),
            a_from_b,
        });
    }
    sensors.push(entry.clone());
}

/// The σ's of every pair of range sensors (`[lrf]`'s, `main`, and `others`') from one problem
/// holding every range sensor's adjustment of the bundle (`base`: the bundle problem's
/// parameter blocks and residuals, which every adjustment begins with); null where a sensor
/// has no adjustment or the covariance cannot be had.
pub fn joint_pairs(
    results: &mut Results,
    (main, others): (Option<&crate::head::HeadPoses>, &[RangeSensor]),
    (base_parameters, base_residuals): (usize, usize),
) {
    let Some(first) = main.and_then(|h| h.adjustment.as_ref()) else {
        return;
    };
    let mut problem = (*first.problem).clone();
    let mut keys = vec![(
        results.sensors.iter().find(|s| s.kind != "camera"),
        first.extrinsic,
    )];
    for other in others {
        let Ok(o) = &other.outcome else { continue };
        let Some(adj) = o.head.as_ref().and_then(|h| h.adjustment.as_ref()) else {
            continue;
        };
        let offset = problem.append_sensor(&adj.problem, base_parameters, base_residuals);
        let key = pingcal_ba::ParameterKey(adj.extrinsic.0 + offset);
        keys.push((results.sensors.iter().find(|s| s.id == other.id), key));
    }
    if keys.len() < 2 {
        return;
    }
    let Ok(prec) = pingcal_ba::solver::precision(&problem) else {
        return;
    };
    let rows: Vec<usize> = (keys.iter())
        .flat_map(|(_, k)| (0..6).map(move |i| (k.0, i)))
        .map(|(k, i)| prec.parameter_offsets[k] + i)
        .collect();
    let cov = nalgebra::DMatrix::from_fn(rows.len(), rows.len(), |a, b| {
        prec.parameters_covariance[(rows[a], rows[b])]
    });
    let Some(poses) = (keys.iter())
        .map(|(s, _)| s.map(|s| (s.id.clone(), s.kind.clone(), pose(&s.camera_from_sensor))))
        .collect::<Option<Vec<_>>>()
    else {
        return;
    };
    let head = crate::head::HeadPoses::of_range_sensors(poses, cov);
    for a in 0..head.sensors.len() {
        for b in a + 1..head.sensors.len() {
            let (ia, ib) = (&head.sensors[a].id, &head.sensors[b].id);
            if let Some(p) = (results.sensor_pairs.iter_mut()).find(|p| &p.a == ia && &p.b == ib) {
                p.a_from_b = json(&head.pair(a, b));
            }
        }
    }
}
