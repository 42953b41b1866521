//! `sensors` and `sensor_pairs` of `results.json` (issue 52): every sensor of the head but
//! the reference (main) camera — the cameras that follow it, then the LRF — with its
//! `camera_from_sensor` in the reference camera's photogrammetric frame, and every pair's
//! `a_from_b` composed from them, each with σ's from the joint covariance ([`crate::head`]).

use super::transforms::{extrinsic_json, ExtrinsicJson};
use crate::head::{HeadPoses, WithSigma};
use crate::stages::Stages;
use pingcal_geometry::{Rigid3, Sim3};
use pingcal_project::LrfKind;
use serde::Serialize;

/// A sensor of the head.
#[derive(Clone, Debug, Serialize)]
pub struct SensorJson {
    /// A camera's id, or `lrf`.
    pub id: String,
    /// `camera`, or the LRF's kind: `rotating`, `fixed`.
    pub kind: String,
    /// `p_reference = R · p_sensor + t` (the LRF's is `extrinsic`, the same values).
    pub camera_from_sensor: ExtrinsicJson,
}

/// Two sensors' relative pose.
#[derive(Clone, Debug, Serialize)]
pub struct SensorPairJson {
    /// The sensor the transform maps into.
    pub a: String,
    /// The sensor it maps from.
    pub b: String,
    /// `p_a = R · p_b + t`: `camera_from_a⁻¹ · camera_from_b`, with the σ's of its ω, φ, κ
    /// and t from the joint covariance of both (null where the two came from separate
    /// adjustments: the LRF when the joint adjustment did not give the result).
    pub a_from_b: ExtrinsicJson,
}

/// The head's sensors from the joint adjustment when it gave the result, else the bundle's
/// rigs with the LRF of `extrinsic` (the result given) beside them. The cameras' poses are
/// the bundle's in both, as `bundle.rig`, the overlays and every export have them (the
/// joint adjustment's beams move them by about a thousandth of their σ); their covariance
/// is the joint adjustment's.
fn head_of(st: &Stages, extrinsic: &ExtrinsicJson) -> HeadPoses {
    if let Some(Ok(j)) = st.joint {
        if !j.head.sensors.is_empty() {
            let mut head = j.head.clone();
            for s in head.sensors.iter_mut().filter(|s| s.kind == "camera") {
                if let Some((pose, _)) = st.adjusted.rig_of(&s.id, st.project) {
                    s.block = pose;
                }
            }
            return head;
        }
    }
    let adj = st.adjusted;
    let kind = match st.project.file.lrf.kind {
        Some(LrfKind::Fixed) => "fixed",
        _ => "rotating",
    };
    let lrf = pose(extrinsic);
    HeadPoses::with_separate_lrf(st.project, &adj.solved.problem, &adj.precision, (lrf, kind))
}

/// `t` as results.json writes a transform.
pub fn json(t: &WithSigma) -> ExtrinsicJson {
    let sim = Sim3::new(1.0, t.pose.rotation, t.pose.translation);
    extrinsic_json(&sim, t.sigma_translation_mm, t.sigma_rotation_deg)
}

/// `sensors` and `sensor_pairs`; `extrinsic` is results.json's (the LRF's entry repeats it).
pub fn sensors_json(
    st: &Stages,
    extrinsic: &ExtrinsicJson,
) -> (Vec<SensorJson>, Vec<SensorPairJson>) {
    let head = head_of(st, extrinsic);
    let sensors = (head.sensors.iter().enumerate())
        .map(|(k, s)| SensorJson {
            id: s.id.clone(),
            kind: s.kind.clone(),
            camera_from_sensor: if s.kind != "camera" {
                extrinsic.clone()
            } else {
                json(&head.sensor(k))
            },
        })
        .collect();
    let n = head.sensors.len();
    let pairs = (0..n)
        .flat_map(|a| (a + 1..n).map(move |b| (a, b)))
        .map(|(a, b)| SensorPairJson {
            a: head.sensors[a].id.clone(),
            b: head.sensors[b].id.clone(),
            a_from_b: json(&head.pair(a, b)),
        })
        .collect();
    (sensors, pairs)
}

/// The transform of `e`.
pub fn pose(e: &ExtrinsicJson) -> Rigid3 {
    Rigid3::new(
        nalgebra::Matrix3::from_fn(|a, b| e.rotation[a][b]),
        nalgebra::Vector3::from(e.translation_mm),
    )
}
