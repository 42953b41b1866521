//! Step 7's starts: the joint adjustment from the mount the room gives, else from the
//! project's mount, each with its passes through the mount the pass before estimated; a
//! result absurd for the field from every start is no result; and the simpler model where
//! the estimated mount is insignificant (`run_joint`).

use crate::context::Options;
use crate::progress::Reporter;
use crate::{bundle, extrinsic, joint, lrf, scene};
use pingcal_lrf::MountModel;
use pingcal_project::Project;

/// Passes of the joint adjustment that look at the LRF again through the mount the pass
/// before estimated, at most.
pub const JOINT_REFINEMENTS: usize = 3;

/// The first pass's gate for the planes' beams when it starts from the project's mount
/// (mm): how far apart a wrong mount may put a wall's two half-sweeps.
pub const FIRST_PLANE_GATE_MM: f64 = 60.0;

/// The level of the test that chooses the simpler model (every mount and range parameter
/// at the project's value) when the estimated ones are insignificant.
pub const MODEL_ALPHA: f64 = 0.05;

/// z of the standard normal at 1 − [`MODEL_ALPHA`] (one-sided, for the χ² quantile) and
/// at 1 − [`MODEL_ALPHA`]/2 (two-sided, for each parameter alone).
const Z_MODEL: (f64, f64) = (1.644_853_626_951_472, 1.959_963_984_540_054);

/// What every start of the joint adjustment shares.
struct JointRun<'a> {
    project: &'a Project,
    /// The project's mount (step 5's), where the priors sit.
    prior: MountModel,
    dets: &'a scene::Detections,
    scene: &'a scene::Scene,
    adjusted: &'a bundle::Adjusted,
    opts: &'a Options,
    /// The joint adjustment's observation groups ([`joint::BUILT_IN`] unless the caller
    /// gives its own).
    groups: &'a [joint::GroupBuilder],
    rep: &'a Reporter,
    /// Passes after the first that look at the LRF again, at most: [`JOINT_REFINEMENTS`],
    /// or none while the camera's model cannot hold its lens ([`refinements`]).
    refinements: usize,
}

/// The refinement passes the joint adjustment may take ([`JointRun::passes`]):
/// [`JOINT_REFINEMENTS`], or none when the bundle found that the camera's model cannot
/// hold the lens (`adjusted.lens_doubt`). The passes re-decide which LRF sphere is which
/// ball through a better mount; with ball centres off by the lens' unmodelled bending
/// (tens of σ) no pass can settle that, each one only redoes the cloud and the adjustment
/// (four passes from each of two starts), and the verdict is doubtful for the lens
/// whatever they give. So the work stops after one pass from each start.
fn refinements(adjusted: &bundle::Adjusted) -> usize {
    if adjusted.lens_doubt.is_some() {
        0
    } else {
        JOINT_REFINEMENTS
    }
}

impl JointRun<'_> {
    /// One pass of the joint adjustment.
    #[allow(clippy::too_many_arguments)]
    fn pass(
        &self,
        lrf: &lrf::LrfData,
        ext: &extrinsic::Extrinsics,
        start: pingcal_geometry::Rigid3,
        pass: usize,
        planes: &[(nalgebra::Vector3<f64>, f64)],
        plane_gate: pingcal_lrf::room::Gate,
        hold_mount: Option<&str>,
    ) -> std::result::Result<joint::JointOutcome, String> {
        let input = joint::JointInput {
            project: self.project,
            dets: self.dets,
            scene: self.scene,
            adj: self.adjusted,
            lrf,
            ext,
            start,
            mount0: lrf.mount,
            prior: self.prior,
            pass,
            noise: lrf.noise,
            planes,
            plane_gate,
            hold_mount,
            seed: self.opts.seed,
        };
        joint::joint_adjustment(&input, self.groups, self.rep).map_err(|e| e.to_string())
    }

    /// The passes of the joint adjustment from one start (the cloud `lrf` through the start
    /// mount, its spheres matched as `ext`, the extrinsic `start`).
    ///
    /// When the joint adjustment finds the mount significantly off its start (an estimate
    /// more than 3σ from it), or the cloud it saw shows a mount error (a fifth or more of
    /// the beams judged grazing, balls seen twice, spheres that match no ball), the cloud
    /// the spheres were found in was distorted by it: a ball seen twice, a ball missed,
    /// grazing judged at a wrong centre. So the cloud is made again from the readings
    /// through the estimated mount, its spheres found, each sphere re-assigned to the ball
    /// the estimated extrinsic puts within a ball's radius of it (one to one, nearest first;
    /// [`extrinsic::match_by_extrinsic`]), the beams on the balls and the planes re-decided
    /// there, and the joint adjustment run again from its own estimate, until a pass needs
    /// none of it or after [`Self::refinements`] such passes.
    fn passes(
        &self,
        lrf: &lrf::LrfData,
        ext: &extrinsic::Extrinsics,
        start: pingcal_geometry::Rigid3,
        planes: &[(nalgebra::Vector3<f64>, f64)],
        plane_gate: pingcal_lrf::room::Gate,
    ) -> std::result::Result<joint::JointOutcome, String> {
        let mut out = self.pass(lrf, ext, start, 1, planes, plane_gate, None)?;
        let mut start_mount = lrf.mount;
        for k in 1..=self.refinements {
            let why = match out.distorted_cloud() {
                Some(why) => why,
                None if out.moved_mount(&start_mount, 3.0) => {
                    "the mount is off its start by more than 3σ".to_string()
                }
                None => break,
            };
            self.rep.log(format!(
                "joint: {why}: the LRF spheres again through the estimated mount (pass {})",
                k + 1
            ));
            let Some(lrf2) =
                lrf::through_mount(self.project, lrf, out.mount_model, self.opts, self.rep)
            else {
                break;
            };
            let gate = pingcal_lrf::room::Gate::Sigma {
                k: pingcal_lrf::room::GATE_K,
                sigma0: plane_sigma0(&out),
                floor_mm: pingcal_lrf::room::RoomOptions::default().gate_floor_mm,
            };
            let planes2 = out.planes.clone();
            let again = extrinsic::spheres_by_extrinsic(
                self.project,
                self.scene,
                self.adjusted,
                &lrf2,
                &out.camera_from_lrf,
                self.rep,
            )
            .map_err(|e| e.to_string())
            .and_then(|ext2| {
                let planes = if planes2.is_empty() { planes } else { &planes2 };
                self.pass(&lrf2, &ext2, out.camera_from_lrf, k + 1, planes, gate, None)
            });
            match again {
                Ok(o) => {
                    start_mount = lrf2.mount;
                    out = o;
                }
                Err(e) => {
                    self.rep.log(format!(
                        "joint: pass {} failed ({e}): the pass before stands",
                        k + 1
                    ));
                    break;
                }
            }
        }
        Ok(out)
    }
}

/// The σ0 of the planes' beams in `out` (1 when there are none).
fn plane_sigma0(out: &joint::JointOutcome) -> f64 {
    (out.variance_components.iter())
        .find(|c| c.group == pingcal_lrf::room::PLANE_GROUP)
        .map_or(1.0, |c| c.sigma0)
}

/// Why `out` is absurd for the field, if it is: a mean check (or control) error, a σ of the
/// translation, or a σ of the rotation at the balls' range larger than the balls
/// themselves (their diameter): a result no ball can be matched by.
fn absurd(out: &joint::JointOutcome, diameter_mm: f64) -> Option<String> {
    let table = if out.check.rows.is_empty() {
        &out.control
    } else {
        &out.check
    };
    let what = if out.check.rows.is_empty() {
        "control"
    } else {
        "check"
    };
    if !(table.mean_mm <= diameter_mm) {
        return Some(format!(
            "its mean {what} error is {:.0} mm, more than a ball's diameter ({diameter_mm} mm)",
            table.mean_mm
        ));
    }
    let st = out
        .sigma_translation_mm
        .iter()
        .fold(0.0f64, |a, &b| a.max(b));
    if !(st <= diameter_mm) {
        return Some(format!(
            "the σ of its translation is {st:.0} mm, more than a ball's diameter ({diameter_mm} mm)"
        ));
    }
    let range = (out.lrf_points.iter().map(|p| p.xyz.norm()).sum::<f64>()
        / out.lrf_points.len().max(1) as f64)
        .max(1000.0);
    let sr = out.sigma_opk_deg.iter().fold(0.0f64, |a, &b| a.max(b));
    if !(sr.to_radians() * range <= diameter_mm) {
        return Some(format!(
            "the σ of its rotation is {sr:.2}°, {:.0} mm at the balls' range, more than a ball's diameter ({diameter_mm} mm)",
            sr.to_radians() * range
        ));
    }
    None
}

/// Whether the simpler model's extrinsic `simple` moved from the full model's `full` by
/// more than the simpler model may, and why. Holding parameters the balls determine poorly
/// (a range scale of 0.2 % is within 1.3 σ) can still move the extrinsic by millimetres
/// (that scale times the balls' range), which the simpler model's σ's do not contain. The
/// rule is the mean squared error's: the simpler estimate is the better one while its bias²
/// is at most the variance it saves, `Var_full − Var_simple`; its bias is estimated by the
/// difference `d` of the two (of variance `Var_full − Var_simple` when it has none), so the
/// simpler model is kept when `d² ≤ 2 (Var_full − Var_simple)` in each of the extrinsic's
/// six components (rotation δθ = log(R_simple R_fullᵀ), translation).
fn simpler_moved(full: &joint::JointOutcome, simple: &joint::JointOutcome) -> Option<String> {
    let (f, s) = (&full.camera_from_lrf, &simple.camera_from_lrf);
    let dth = pingcal_geometry::log_so3(&(s.rotation * f.rotation.transpose()));
    let dt = s.translation - f.translation;
    let d = [dth.x, dth.y, dth.z, dt.x, dt.y, dt.z];
    const NAMES: [&str; 6] = ["rotation x", "rotation y", "rotation z", "tx", "ty", "tz"];
    (0..6).find_map(|k| {
        let saved = full.extrinsic_cov[(k, k)] - simple.extrinsic_cov[(k, k)];
        let bound = (2.0 * saved.max(0.0)).sqrt();
        (!(d[k].abs() <= bound)).then(|| {
            let (v, b, u) = if k < 3 {
                (d[k].to_degrees(), bound.to_degrees(), "°")
            } else {
                (d[k], bound, " mm")
            };
            format!(
                "holding the mount moves the extrinsic's {} by {v:.3}{u}, more than the {b:.3}{u} the simpler model's smaller variance allows (bias² ≤ the variance saved)",
                NAMES[k]
            )
        })
    })
}

/// Whether the estimated mount and range parameters of `out` are insignificant against
/// the project's mount `prior` (see [`MODEL_ALPHA`]): the Wald test of all of them together,
/// `W = δᵀ Σ⁻¹ δ` against `χ²₁₋α(k)`, and each alone, `|δ_k/σ_k|` against `z₁₋α/₂`. Some(the
/// test's words) when both pass.
fn insignificant_mount(out: &joint::JointOutcome, prior: &MountModel) -> Option<String> {
    let p0 = prior.to_params();
    let th = out.mount_model.to_params();
    let free: Vec<usize> = (0..8).filter(|&k| out.mount[k].sigma.is_some()).collect();
    if free.is_empty() {
        return None;
    }
    let n = free.len();
    let d = nalgebra::DVector::from_iterator(n, free.iter().map(|&k| th[k] - p0[k]));
    let c = nalgebra::DMatrix::from_fn(n, n, |a, b| out.mount_cov[(free[a], free[b])]);
    let w = d.dot(&(c.clone().try_inverse()? * &d));
    let bound = pingcal_geometry::stats::chi2_quantile(n as f64, Z_MODEL.0);
    let zmax = (0..n)
        .map(|a| d[a].abs() / c[(a, a)].max(1e-300).sqrt())
        .fold(0.0f64, f64::max);
    (w <= bound && zmax <= Z_MODEL.1).then(|| format!(
        "the estimated mount and range parameters are insignificant: Wald χ² {w:.2} ≤ {bound:.2} ({n} parameters, α = {MODEL_ALPHA}) and each within {:.2} σ of the project's value (largest {zmax:.2}): the simpler model, the mount held at the project's",
        Z_MODEL.1
    ))
}

/// Step 7 from the outcomes of the steps before it.
///
/// **Starts.** First the mount the room gives ([`lrf::room_mount`]): the cloud through it,
/// its spheres matched to the balls by the distance invariants, their registration the
/// extrinsic's start, and the planes' beams found near where the room's estimate put them.
/// Then, when that start is not available or its result is absurd for the field
/// ([`absurd`]), the project's mount with the two-step method's extrinsic. Each start runs
/// its passes ([`JointRun::passes`]). A result that is absurd from every start is no
/// result: "the joint adjustment did not converge from any start", and the calibration
/// fails. The priors stay at `prior`, the project's mount, throughout (also when `lrf` is
/// the cloud through the room's mount because step 6 failed on the project's, see
/// `crate::calibrate`), and the two-step method's results stay those of `lrf`'s mount: the
/// paper's method as the user gave it.
///
/// **The simpler model.** When the estimated mount and range parameters are insignificant
/// ([`insignificant_mount`]), the joint adjustment is run once more with every one held at
/// the project's value, through the project's mount, and that result is given, with the
/// test that chose it in its notes.
pub(crate) fn run_joint(
    project: &Project,
    (dets, scene, adjusted): (&scene::Detections, &scene::Scene, &bundle::Adjusted),
    (lrf, prior): (&lrf::LrfData, MountModel),
    ext: &extrinsic::Extrinsics,
    (opts, groups): (&Options, &[joint::GroupBuilder]),
    rep: &Reporter,
) -> std::result::Result<joint::JointOutcome, joint::JointError> {
    let Some(ev) = &ext.spheres else {
        return Err(joint::JointError::other(
            "it starts from the sphere method, which did not run",
        ));
    };
    let run = JointRun {
        project,
        prior,
        dets,
        scene,
        adjusted,
        opts,
        groups,
        rep,
        refinements: refinements(adjusted),
    };
    if run.refinements == 0 {
        rep.log("joint: the camera's model cannot hold the lens (the warning above): one pass from each start, without the LRF looked at again through the estimated mount");
    }
    let diameter = project.file.balls.diameter_mm;
    let room = lrf::room_mount(project, lrf, opts.seed, rep);
    let planes: Vec<(nalgebra::Vector3<f64>, f64)> = (room.iter())
        .flat_map(|r| r.planes.iter().map(|p| (p.normal, p.offset_mm)))
        .collect();
    let mut tried: Vec<String> = Vec::new();
    let found = (room.as_ref()).and_then(|r| from_room(&run, r, lrf, &planes, &mut tried));
    let out = match found {
        Some(o) => o,
        None => {
            let gate = pingcal_lrf::room::Gate::First(FIRST_PLANE_GATE_MM);
            let start = ev.registration.camera_from_lrf.rigid();
            match run.passes(lrf, ext, start, &planes, gate) {
                Ok(o) => match absurd(&o, diameter) {
                    None => o,
                    Some(why) => {
                        tried.push(format!("from the project's mount, {why}"));
                        return Err(not_converged(&tried));
                    }
                },
                Err(e) if !tried.is_empty() => {
                    tried.push(format!("from the project's mount, {e}"));
                    return Err(not_converged(&tried));
                }
                Err(e) => return Err(joint::JointError::other(e)),
            }
        }
    };
    Ok(simpler_if_insignificant(&run, out, lrf, ext))
}

/// The joint adjustment's passes from the mount the room's planes gave (`room`): the cloud
/// through it, its spheres matched by the distance invariants, their registration the
/// extrinsic's start, the planes' beams gated by the room's σ0. None, with the reason pushed
/// on `tried`, when that start fails or its result is absurd for the field.
fn from_room(
    run: &JointRun,
    room: &pingcal_lrf::room::RoomMount,
    lrf: &lrf::LrfData,
    planes: &[(nalgebra::Vector3<f64>, f64)],
    tried: &mut Vec<String>,
) -> Option<joint::JointOutcome> {
    let (project, opts, rep) = (run.project, run.opts, run.rep);
    let gate = pingcal_lrf::room::Gate::Sigma {
        k: pingcal_lrf::room::GATE_K,
        sigma0: room.sigma0,
        floor_mm: pingcal_lrf::room::RoomOptions::default().gate_floor_mm,
    };
    let attempt = lrf::through_mount(project, lrf, room.mount, opts, rep)
        .ok_or_else(|| "the cloud has no readings".to_string())
        .and_then(|lrf_r| {
            let inputs = (run.scene, run.adjusted, &lrf_r, run.dets);
            let ext_r =
                extrinsic::spheres_only(project, inputs, opts, rep).map_err(|e| e.to_string())?;
            let Some(ev_r) = &ext_r.spheres else {
                return Err("no sphere method on the room's cloud".to_string());
            };
            let start = ev_r.registration.camera_from_lrf.rigid();
            run.passes(&lrf_r, &ext_r, start, planes, gate)
        });
    let diameter = project.file.balls.diameter_mm;
    let found = match attempt.map(|o| (absurd(&o, diameter), o)) {
        Ok((None, mut o)) => {
            o.notes.insert(0, "started from the mount the room's planes gave (the cloud through it, its spheres matched by the distance invariants)".into());
            Some(o)
        }
        Ok((Some(why), _)) => {
            tried.push(format!("from the room's mount, {why}"));
            None
        }
        Err(e) => {
            tried.push(format!("from the room's mount, {e}"));
            None
        }
    };
    if !tried.is_empty() {
        rep.log(format!(
            "joint: {}: starting again from the project's mount",
            tried[0]
        ));
    }
    found
}

/// The error of a joint adjustment absurd from every start in `tried`.
fn not_converged(tried: &[String]) -> joint::JointError {
    joint::JointError {
        message: format!(
            "the joint adjustment did not converge from any start ({}): more balls, balls seen in both half-sweeps, or more of the room's walls, floor and ceiling in view would help",
            tried.join("; ")
        ),
        not_converged: true,
    }
}

/// `out`, or the simpler model's result when `out`'s mount parameters are insignificant
/// (see [`run_joint`]).
fn simpler_if_insignificant(
    run: &JointRun,
    out: joint::JointOutcome,
    lrf: &lrf::LrfData,
    ext: &extrinsic::Extrinsics,
) -> joint::JointOutcome {
    let Some(why) = insignificant_mount(&out, &run.prior) else {
        return out;
    };
    run.rep.log(format!("joint: {why}"));
    let gate = pingcal_lrf::room::Gate::First(FIRST_PLANE_GATE_MM);
    match run.pass(lrf, ext, out.camera_from_lrf, 1, &[], gate, Some(&why)) {
        Ok(s) if absurd(&s, run.project.file.balls.diameter_mm).is_none() => {
            match simpler_moved(&out, &s) {
                None => s,
                Some(moved) => {
                    let note =
                        format!("the simpler model was refused: {moved}: the full model stands");
                    run.rep.log(format!("joint: {note}"));
                    let mut out = out;
                    out.notes.push(note);
                    out
                }
            }
        }
        Ok(_) | Err(_) => {
            run.rep
                .log("joint: the simpler model gave no usable result: the full model stands");
            out
        }
    }
}
