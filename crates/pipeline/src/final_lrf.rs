//! Step 7b: the LRF as the calibration's own model sees it. Once the joint adjustment has
//! estimated the LRF's mount and range model, every output that shows the LRF side —
//! `cloud.ply`, `results.json`'s `balls[].lrf_mm`, the check and control tables, the
//! report's cloud and the overlays — must use that model: the extrinsic it gives is valid
//! only with it. (Under the project's nominal mount a ball's centre lands 15–22 mm from
//! where the extrinsic puts it, and a ball whose two half-sweeps do not coincide is not
//! found at all.)
//!
//! So the cloud is made again from its readings through the estimated model
//! ([`super::lrf::through_mount`]), its spheres are found, and each is matched to the ball
//! of the photogrammetric model nearest to where the estimated extrinsic puts it:
//! `d = |T · c_lrf − X_ball| ≤ r` (the ball's radius), one sphere per ball, nearest pairs
//! first. With the model estimated, a sphere of the right ball is within a few millimetres
//! of it, and another ball is at least a diameter away, so the rule is unambiguous. A
//! matched ball's LRF side is its sphere as found in that cloud (the fit
//! [`pingcal_lrf::ball_finder`] makes, with its covariance), the very sphere `cloud.ply`
//! carries and `pingcal cloud --lrf-model results.json` finds again; its camera side is the
//! joint adjustment's centre. The check table (the project's check balls) and the
//! control table are computed from these, and they replace the joint pass's own.
//!
//! Without a joint adjustment (it did not run, or failed) the outputs use the cloud of the
//! project's mount, the two-step method's view.

use super::extrinsic::{match_by_extrinsic, unmeasured_labels};
use super::ids::{PointId, SphereId};
use super::joint::{JointOutcome, LrfView};
use super::lrf::{self, LrfData};
use super::scene::Scene;
use crate::context::Options;
use crate::progress::Reporter;
use pingcal_geometry::Sim3;
use pingcal_lrf::registration::{check_table, PointObs};
use pingcal_project::Project;

/// The LRF through the estimated model: the cloud and its spheres, and which ball each
/// sphere is.
pub struct Remade {
    /// The cloud and its spheres.
    pub lrf: LrfData,
    /// Spheres of [`Self::lrf`] matched to balls of the scene.
    pub pairs: Vec<(SphereId, PointId)>,
}

/// The LRF through the joint adjustment's estimated model (see the module doc); `j`'s check
/// and control tables, ball points and LRF view are replaced by those of this cloud. None
/// (and `j` untouched) when the cloud has no readings to make again.
pub fn through_estimate(
    project: &Project,
    first: &LrfData,
    scene: &Scene,
    check_ids: &[String],
    j: &mut JointOutcome,
    opts: &Options,
    rep: &Reporter,
) -> Option<Remade> {
    let lrf = lrf::through_mount(project, first, j.mount_model, opts, rep)?;
    let radius = 0.5 * project.file.balls.diameter_mm;
    let centres: Vec<(PointId, nalgebra::Vector3<f64>)> =
        j.ball_centres.iter().map(|(p, o)| (*p, o.xyz)).collect();
    let pairs = match_by_extrinsic(&lrf, &centres, &j.camera_from_lrf, radius);
    let (mut lrf_points, mut cam_points) = (Vec::new(), Vec::new());
    for &(s, p) in &pairs {
        let ball = &lrf.found.balls[s.0];
        let Some((_, cam)) = j.ball_centres.iter().find(|(q, _)| *q == p) else {
            continue;
        };
        lrf_points.push(PointObs {
            id: scene.points[p].name.clone(),
            xyz: ball.centre,
            cov: ball.cov,
        });
        cam_points.push(cam.clone());
    }
    let t = Sim3::new(
        1.0,
        j.camera_from_lrf.rotation,
        j.camera_from_lrf.translation,
    );
    let pick = |set: &[PointObs], check: bool| -> Vec<PointObs> {
        (set.iter())
            .filter(|p| check_ids.contains(&p.id) == check)
            .cloned()
            .collect()
    };
    j.check = check_table(&t, &pick(&lrf_points, true), &pick(&cam_points, true));
    j.control = check_table(&t, &pick(&lrf_points, false), &pick(&cam_points, false));
    j.lrf_points = lrf_points;
    j.cam_points = cam_points;
    j.lrf_view = LrfView {
        pass: j.lrf_view.pass,
        spheres: lrf.found.balls.len(),
        matched: pairs.len(),
        seen_twice_rejected: lrf.found.seen_twice_rejected(),
        seen_twice_kept: lrf.found.seen_twice_kept(),
        rejected_at_unmatched: 0,
        unmeasured_labels: unmeasured_labels(project, scene, &lrf, &pairs, &j.camera_from_lrf),
    };
    let balls = j.ball_centres.len();
    j.notes.push(format!(
        "the outputs' LRF side (cloud.ply, balls[].lrf_mm, the check and control tables) is the cloud made again through the estimated model: {} spheres found, {} of {balls} balls matched (within the ball's radius of where the extrinsic puts them)",
        lrf.found.balls.len(),
        pairs.len()
    ));
    rep.log(format!(
        "LRF through the estimated model: {} spheres, {} of {balls} balls matched; mean check error {:.2} mm on {} balls",
        lrf.found.balls.len(),
        pairs.len(),
        j.check.mean_mm,
        j.check.rows.len()
    ));
    Some(Remade { lrf, pairs })
}
