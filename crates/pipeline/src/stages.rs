//! What the steps produced, handed to the steps that judge and write it ([`crate::verdict`],
//! [`crate::results`], [`crate::report`], [`crate::overlays`]).

use crate::{bundle, extrinsic, ids, joint, lrf, scene};
use pingcal_project::Project;

/// What the steps produced, for the results and the report.
pub struct Stages<'a> {
    /// The project.
    pub project: &'a Project,
    /// Step 1.
    pub dets: &'a scene::Detections,
    /// Steps 2–4 (the final scene).
    pub scene: &'a scene::Scene,
    /// Step 4.
    pub adjusted: &'a bundle::Adjusted,
    /// Step 5.
    pub lrf: &'a lrf::LrfData,
    /// Step 6.
    pub ext: &'a extrinsic::Extrinsics,
    /// Step 7 (None when the method does not ask for it), or why it failed.
    pub joint: &'a Option<std::result::Result<joint::JointOutcome, joint::JointError>>,
    /// The LRF side every output uses (step 7b): the cloud through the joint adjustment's
    /// estimated model when its result is the one given, else [`Self::lrf`].
    pub lrf_out: &'a lrf::LrfData,
    /// The spheres of [`Self::lrf_out`] matched to balls of the scene.
    pub pairs_out: &'a [(ids::SphereId, ids::PointId)],
}
