//! The other range sensors of the head (`[[lrfs]]`, issue 52) in the main calibration's
//! outputs: each was calibrated against the same camera side as a project of its own
//! ([`pingcal_project::Project::range_sensors`]; its outputs are written under
//! `lrfs/<id>/`); here its pose joins results.json's `sensors`, its pairs with the cameras
//! (from its own adjustment with them: σ's with the cross-covariances) and with the range
//! sensors before it (composed, σ's null: separate adjustments) join `sensor_pairs`, and a
//! sensor not calibrated, or whose own verdict is not `ok`, is a reason of the main verdict.

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

/// `results`' `sensors` and `sensor_pairs` with each of `others`.
pub fn add_sensors(results: &mut Results, others: &[RangeSensor]) {
    for other in others {
        add_range_sensor(other, &mut results.sensors, &mut results.sensor_pairs);
    }
}

/// One of `[[lrfs]]` into `sensors` and `pairs`: its entry and its pairs with the cameras
/// as its own calibration gave them (one adjustment with the cameras: σ's with the
/// cross-covariances), and its pairs with the range sensors before it composed from the two
/// entries, with null σ's (separate adjustments).
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
