//! Step 4: the final self-calibrating bundle adjustment.
//!
//! - Datum: the main image is held fixed (its camera frame is the photogrammetric frame);
//!   the measured distances (observation equations with their σ) give the scale.
//! - Intrinsics: the parameters each camera frees in the project, shared by its images.
//! - The head: with `[stereo]`, the right image of every station follows its left image
//!   through one rig pose, adjusted with everything else; so does each camera of `[rig]`
//!   follow the main camera's image (held where the project holds its pose). Cameras that
//!   share no view of the field are tied through the field.
//! - Balls: the centre of a ball's silhouette is not the image of its centre; each ball
//!   measurement is corrected by the cone fit of [`pingcal_targets::ball`] with the current
//!   intrinsics ([`super::adjust`]), and the adjustment is run twice so that the correction
//!   uses calibrated intrinsics.
//! - Gross errors: data snooping (Baarda's w, Pope's τ when σ0 > 1) removes one observation
//!   at a time, the worst of the image points and the measured distances alike
//!   ([`pingcal_ba::solver::adjust_with_snooping`]): a distance given wrong (a typo) is named
//!   as the blunder and left out of the later rounds ([`RejectedDistance`]), not the image
//!   points of its targets.

use super::adjust::{head_cameras, Datum, SceneProblem};
use super::ids::ImageId;
use super::scene::{coded_blunder, image_file, Detections, PointKind, Scene};
use crate::context::{Options, PipelineError, Result};
use crate::progress::Reporter;
use nalgebra::Matrix6;
use pingcal_ba::solver::{
    self, DistanceRejection, Precision, PrecisionError, Rejection, SnoopError, VarianceComponent,
    VarianceError,
};
use pingcal_geometry::Rigid3;
use pingcal_project::Project;
use serde::Serialize;

/// The adjusted network.
pub struct Adjusted {
    /// The last problem solved, with its map to the scene (its solution is also in the
    /// [`Scene`]) and the balls' eccentricity corrections.
    pub solved: SceneProblem,
    /// Precision of the last adjustment (each group weighted by its variance component).
    pub precision: Precision,
    /// σ0 of the last adjustment with the a-priori σ's, before the re-weighting: what the
    /// verdict's χ² test of the image and distance measurements judges.
    pub sigma0_a_priori: f64,
    /// Image points removed as gross errors.
    pub rejected: Vec<Rejection>,
    /// The pose (`member_from_base`) of each of the head's cameras that follow another
    /// ([`super::adjust::head_cameras`], `[stereo]`'s first), where its rig was adjusted.
    pub rigs: Vec<Option<Rigid3>>,
    /// Iterations of all final adjustments.
    pub iterations: usize,
    /// Why each `[[distances]]` entry left out of the adjustment was left out.
    pub unused_distances: Vec<String>,
    /// The `[[distances]]` entries data snooping found to be gross errors, left out.
    pub rejected_distances: Vec<RejectedDistance>,
    /// The σ0 of each group of observations ([`OBSERVATION_GROUPS`], then the distances)
    /// relative to its a-priori σ, by which the last adjustment re-weighted it.
    pub variance_components: Vec<VarianceComponent>,
    /// A camera whose image residuals grow toward the edge along the radius
    /// (`verdict::lens_doubt`, set by the pipeline after this step): its model cannot hold
    /// the lens.
    pub lens_doubt: Option<String>,
}

impl Adjusted {
    /// The adjusted rig of the head camera `camera` (`member_from_base`) and its covariance
    /// (of the update `(δω, δt)`, None where it was held), when the adjustment had it.
    pub fn rig_of(
        &self,
        camera: &str,
        project: &Project,
    ) -> Option<(Rigid3, Option<Matrix6<f64>>)> {
        let heads = head_cameras(project);
        let head = heads.iter().find(|h| h.camera == camera)?;
        let k = (self.solved.problem.rigs.iter()).position(|r| r.name == head.rig)?;
        let cov = self.precision.rig_covariances.get(k).copied().flatten();
        Some((self.solved.problem.rigs[k].member_from_base, cov))
    }
}

/// A `[[distances]]` entry that data snooping found to be a gross error (its standardized
/// residual the largest of all observations and beyond the critical value): left out of the
/// adjustment, named in the log, results.json (`bundle.rejected_distances`), the report and
/// the verdict.
#[derive(Clone, Debug, Serialize)]
pub struct RejectedDistance {
    /// Its place in the project's `[[distances]]`, from 0.
    pub entry: usize,
    /// Its `from` coded target.
    pub from: u32,
    /// Its `to` coded target.
    pub to: u32,
    /// The distance given (`distance_mm`).
    pub given_mm: f64,
    /// Its σ given (`sigma_mm`).
    pub sigma_mm: f64,
    /// The distance between the two targets as the adjustment without it puts them.
    pub adjusted_mm: f64,
    /// Its standardized residual (Baarda's w) when it was rejected.
    pub w: f64,
    /// The test, with its figures.
    pub why: String,
}

impl RejectedDistance {
    /// What the log, the report and the verdict say of it.
    pub fn warning(&self) -> String {
        format!(
            "distances[{}]: the distance {} – {} given as {:.3} mm was measured as {:.3} mm ({:+.3} mm, w = {:.1}): a typo? it was left out",
            self.entry,
            self.from,
            self.to,
            self.given_mm,
            self.adjusted_mm,
            self.given_mm - self.adjusted_mm,
            self.w
        )
    }

    /// The project's entry that `r` (whose ends are named by their coded numbers) is.
    fn of(project: &Project, r: &DistanceRejection) -> Option<Self> {
        let (a, b) = (r.a.parse::<u32>().ok()?, r.b.parse::<u32>().ok()?);
        let entry = project.file.distances.iter().position(|d| {
            d.distance_mm == r.given && ((d.from, d.to) == (a, b) || (d.from, d.to) == (b, a))
        })?;
        let d = &project.file.distances[entry];
        Some(RejectedDistance {
            entry,
            from: d.from,
            to: d.to,
            given_mm: d.distance_mm,
            sigma_mm: d.sigma_mm,
            adjusted_mm: r.estimated,
            w: r.w,
            why: r.reason.clone(),
        })
    }
}

/// The groups of image observations whose variance components the final adjustment
/// estimates: the targets' centres (coded and plain, one detector and one σ model) and the
/// balls' silhouettes corrected for eccentricity (another measurement, with its own σ).
pub const OBSERVATION_GROUPS: [&str; 2] = ["targets", "balls"];

/// Removes rejected measurements from the scene (a point has one measurement per image).
fn remove_rejected(project: &Project, scene: &mut Scene, rejected: &[Rejection]) {
    for r in rejected {
        let Some(i) = project.file.images.iter().position(|im| im.file == r.image) else {
            continue;
        };
        for p in scene.points.iter_mut().filter(|p| p.name == r.point) {
            p.obs.retain(|d| d.image != ImageId(i));
        }
    }
}

/// Names the blunders among the image points data snooping `rejected`: a coded measurement
/// that the adjusted `scene` puts beyond the reach of its own ring ([`coded_blunder`]).
fn name_blunders(project: &Project, dets: &Detections, scene: &mut Scene, rejected: &[Rejection]) {
    for r in rejected {
        let Some(i) = project.file.images.iter().position(|im| im.file == r.image) else {
            continue;
        };
        let Some(p) = scene.points.iter().find(|p| p.name == r.point) else {
            continue;
        };
        let (PointKind::Coded(n), Some(&d)) =
            (p.kind, p.obs.iter().find(|d| d.image == ImageId(i)))
        else {
            continue;
        };
        let Some(uv) = scene.project_into(ImageId(i), &p.position) else {
            continue;
        };
        let off = (uv.x - r.uv[0]).hypot(uv.y - r.uv[1]);
        if let Some(b) = coded_blunder(project, dets, d, n, off, "final bundle") {
            scene.add_blunder(b);
        }
    }
}

/// Removes from the scene a point whose position the network does not determine and returns its
/// measurements as rejections. This happens when data snooping has taken the rays of a point
/// down to one, and then that one too (`pingcal_ba::solver::adjust_with_snooping` drops a lone
/// ray but keeps the point, which the precision then finds undetermined), or when its rays are
/// nearly parallel. A coded target that a distance refers to goes too, unless no distance would
/// be left to fix the scale (those data snooping `rejected` do not count): that is an error
/// naming it.
fn drop_undetermined(
    project: &Project,
    dets: &Detections,
    scene: &mut Scene,
    name: &str,
    rejected: &[RejectedDistance],
) -> Result<Vec<Rejection>> {
    let Some(j) = scene.points.position(|p| p.name == name) else {
        return Err(PipelineError::Data(format!(
            "final bundle adjustment: point '{name}' is not determined by its rays"
        )));
    };
    let p = scene.points.remove(j);
    if let PointKind::Coded(n) = p.kind {
        let f = &project.file;
        let left = (f.distances.iter().enumerate()).any(|(k, d)| {
            !rejected.iter().any(|r| r.entry == k)
                && measured(scene, d.from)
                && measured(scene, d.to)
        });
        if f.distances.iter().any(|d| d.from == n || d.to == n) && !left {
            return Err(PipelineError::Data(format!(
                "{}: coded target {n} of the distances is not determined by its rays after data snooping, and no other distance is left to fix the scale: it needs more images in which it is measured well",
                project.path.display()
            )));
        }
    }
    Ok(p.obs
        .iter()
        .map(|&d| {
            let t = dets.target(d);
            Rejection {
                image: image_file(project, d.image).to_string(),
                point: name.to_string(),
                uv: [t.x, t.y],
                w: [f64::NAN; 2],
                reason: "data snooping left the point too few rays to determine it: the point is dropped".into(),
            }
        })
        .collect())
}

/// Whether coded target `n` is a point of two or more rays in the scene.
fn measured(scene: &Scene, n: u32) -> bool {
    scene
        .points
        .iter()
        .any(|p| p.kind == PointKind::Coded(n) && p.obs.len() >= 2)
}

/// The distances that cannot take part in the adjustment, one warning each (naming the entry
/// and its target not identified in two or more oriented images); an error when none is left
/// to fix the scale (the project has no control points, so the distances are the only scale),
/// those data snooping `rejected` counted as gone.
fn unusable_distances(
    project: &Project,
    scene: &Scene,
    rejected: &[RejectedDistance],
) -> Result<Vec<String>> {
    let f = &project.file;
    let mut warnings = Vec::new();
    // a rejected entry is named by its own warning (RejectedDistance::warning)
    for (k, d) in
        (f.distances.iter().enumerate()).filter(|(k, _)| rejected.iter().all(|r| r.entry != *k))
    {
        let missing: Vec<String> = [d.from, d.to]
            .into_iter()
            .filter(|&n| !measured(scene, n))
            .map(|n| n.to_string())
            .collect();
        if !missing.is_empty() {
            warnings.push(format!(
                "distances[{k}] ({} – {}) not used: coded target {} was not identified in two or more oriented images",
                d.from,
                d.to,
                missing.join(" and ")
            ));
        }
    }
    if warnings.len() + rejected.len() == f.distances.len() {
        let why: Vec<String> = (warnings.iter().cloned())
            .chain(rejected.iter().map(RejectedDistance::warning))
            .collect();
        // targets unidentified in the oriented images: a principal distance no lens has
        // (a value in µm or in pixels) is the likeliest cause, and is named
        return Err(PipelineError::Data(format!(
            "{}: no distance is left to fix the scale of the network: {}{}",
            project.path.display(),
            if why.is_empty() {
                "the project has no [[distances]]".to_string()
            } else {
                why.join("; ")
            },
            super::matching::implausible_principal_distance(project).unwrap_or_default()
        )));
    }
    Ok(warnings)
}

/// The final adjustment's failure `e`, with a principal distance that no lens has named
/// beside it: such a value (in µm, in pixels) makes a network whose failures, a point
/// behind a camera or no convergence, would otherwise hide their cause.
fn failed(project: &Project, e: impl std::fmt::Display) -> PipelineError {
    PipelineError::Adjustment(format!(
        "final bundle adjustment: {e}{}",
        super::matching::implausible_principal_distance(project).unwrap_or_default()
    ))
}

/// The state of the final adjustment between its rounds.
struct Rounds<'a> {
    project: &'a Project,
    dets: &'a Detections,
    options: solver::Options,
    snoop_critical: f64,
    rigs: Vec<Option<Rigid3>>,
    rejected: Vec<Rejection>,
    rejected_distances: Vec<RejectedDistance>,
    /// Why the distances are no longer tested ([`Rounds::disagree`]).
    distances_disagree: Option<String>,
    iterations: usize,
}

impl Rounds<'_> {
    /// The problem of the scene's current state, without the distances rejected so far.
    fn problem(&self, scene: &Scene) -> SceneProblem {
        let mut sp =
            SceneProblem::build(self.project, self.dets, scene, Datum::MainImage, &self.rigs);
        let (points, rejected) = (&sp.problem.points, &self.rejected_distances);
        let number = |p: pingcal_ba::PointKey| points[p].name.parse::<u32>().ok();
        sp.problem.distances.retain(|d| {
            let ends = (number(d.a), number(d.b));
            !rejected.iter().any(|r| {
                r.given_mm == d.value
                    && (ends == (Some(r.from), Some(r.to)) || ends == (Some(r.to), Some(r.from)))
            })
        });
        sp
    }

    /// Data snooping on `sp`'s problem: at most `max_rej` observations, of which one distance
    /// in all the rounds (a typo is one value), none once the distances disagree.
    fn snoop(
        &self,
        sp: &mut SceneProblem,
        max_rej: usize,
    ) -> std::result::Result<solver::SnoopResult, SnoopError> {
        let limits = solver::SnoopLimits {
            total: max_rej,
            distances_and_control: match self.distances_disagree {
                Some(_) => 0,
                None => 1usize.saturating_sub(self.rejected_distances.len()),
            },
        };
        solver::adjust_with_snooping_limited(
            &mut sp.problem,
            &self.options,
            self.snoop_critical,
            limits,
        )
    }

    /// Whether a distance still fails the test after one was rejected (its w beyond the
    /// critical value, over σ0 when above 1): the distances then disagree with the network
    /// as a whole, which is no typo — a camera model that does not fit the lens, distances
    /// in another unit — and every distance is kept, untested, from the round run again on.
    fn disagree(&mut self, prec: &Precision, rep: &Reporter) -> bool {
        let scale = prec.sigma0.max(1.0);
        let worst = (prec.distance_standardized.iter())
            .map(|w| w.abs() / scale)
            .filter(|w| w.is_finite())
            .fold(0.0, f64::max);
        if self.distances_disagree.is_some() || worst <= self.snoop_critical {
            return false;
        }
        let why = format!(
            "the distances disagree with the network beyond their σ's (a standardized residual of {worst:.1} left after one was rejected): more than a typo — a camera model that does not fit the lens, or distances in another unit? Every distance is kept and only the image points are tested"
        );
        rep.log(format!("  warning: {why}"));
        self.distances_disagree = Some(why);
        self.rejected_distances.clear();
        true
    }

    /// Records and logs the distances data snooping rejected in a round.
    fn distances_rejected(&mut self, rejected: &[DistanceRejection], rep: &Reporter) {
        for r in rejected {
            // every distance of the problem is a [[distances]] entry between coded targets
            let Some(d) = RejectedDistance::of(self.project, r) else {
                rep.log(format!(
                    "  warning: the distance {} – {} given as {} mm was rejected (w = {:.1})",
                    r.a, r.b, r.given, r.w
                ));
                continue;
            };
            rep.log(format!("  warning: {}", d.warning()));
            self.rejected_distances.push(d);
        }
    }

    /// One adjustment with data snooping; the solution goes into the scene and the rejected
    /// image points out of it. A point left undetermined is dropped and the round run again.
    fn snooping_round(&mut self, scene: &mut Scene, round: usize, rep: &Reporter) -> Result<()> {
        let (sp, r) = loop {
            let mut sp = self.problem(scene);
            let max_rej = sp.problem.observations.len() / 20;
            if round == 0 {
                // a camera parameter the network cannot determine: named before solving
                if let Err(e @ PrecisionError::NotDeterminable(_)) =
                    solver::check_intrinsics(&sp.problem)
                {
                    return Err(PipelineError::Data(format!(
                        "{}: final bundle adjustment: {e} (the calibrated parameters are each [[cameras]] entry's free list)",
                        self.project.path.display()
                    )));
                }
            }
            match self.snoop(&mut sp, max_rej) {
                Ok(r) if self.disagree(&r.precision, rep) => {}
                Ok(r) => break (sp, r),
                Err(SnoopError::Precision(PrecisionError::PointUndetermined(name))) => {
                    self.rejected.extend(drop_undetermined(
                        self.project,
                        self.dets,
                        scene,
                        &name,
                        &self.rejected_distances,
                    )?);
                    rep.log(format!(
                        "  point {name} dropped: after data snooping its rays no longer determine it"
                    ));
                }
                Err(e) => return Err(failed(self.project, e)),
            }
        };
        self.distances_rejected(&r.rejected_distances, rep);
        self.iterations += r.summary.iterations;
        sp.write_back(scene);
        let solved = sp.rig_poses(self.project);
        for (rig, solved) in self.rigs.iter_mut().zip(solved) {
            *rig = solved.or(*rig);
        }
        let before = scene.blunders.len();
        name_blunders(self.project, self.dets, scene, &r.rejected);
        super::network::log_blunders(self.project, self.dets, scene, before, rep);
        remove_rejected(self.project, scene, &r.rejected);
        rep.log(format!(
            "  bundle round {}: {} iterations, sigma0 {:.3}, RMS {:.3} px, {} image points rejected{}",
            round + 1,
            r.summary.iterations,
            r.precision.sigma0,
            r.precision.rms_image_px,
            r.rejected.len(),
            match r.rejected_distances.len() {
                0 => String::new(),
                n => format!(", {n} distances rejected"),
            }
        ));
        self.rejected.extend(r.rejected);
        Ok(())
    }

    /// The final solution, aligned with the scene's measurements, and its precision, with
    /// each group of observations ([`OBSERVATION_GROUPS`], the distances) re-weighted by
    /// its own variance component ([`pingcal_ba::solver::estimate_variance_components`]):
    /// one σ0 for all would let the group whose a-priori σ is most pessimistic (the targets)
    /// scale down the covariance of what another group determines (the balls' centres).
    fn last(&mut self, scene: &mut Scene) -> Result<(SceneProblem, solver::VarianceEstimate)> {
        let mut sp = self.problem(scene);
        let group_of: Vec<usize> = sp
            .map
            .observations
            .iter()
            .map(|&(j, _)| usize::from(scene.points[j].kind == PointKind::Ball))
            .collect();
        let estimate = solver::estimate_variance_components(
            &mut sp.problem,
            &self.options,
            &group_of,
            &OBSERVATION_GROUPS,
        )
        .map_err(|e| match e {
            VarianceError::Solve(e) => failed(self.project, e),
            VarianceError::Precision(e) => PipelineError::Adjustment(format!(
                "{}: the network's precision cannot be computed: {e}",
                self.project.path.display()
            )),
        })?;
        self.iterations += estimate.iterations;
        sp.write_back(scene);
        Ok((sp, estimate))
    }
}

/// The final adjustment (see the module doc).
pub fn final_adjustment(
    project: &Project,
    dets: &Detections,
    scene: &mut Scene,
    opts: &Options,
    rep: &Reporter,
) -> Result<Adjusted> {
    let unused_distances = unusable_distances(project, scene, &[])?;
    for w in &unused_distances {
        rep.log(format!("warning: {w}"));
    }
    let mut rounds = Rounds {
        project,
        dets,
        options: solver::Options {
            max_iterations: 100,
            threads: opts.threads,
            ..solver::Options::default()
        },
        snoop_critical: opts.snoop_critical,
        rigs: super::adjust::rig_starts(project, scene),
        rejected: Vec::new(),
        rejected_distances: Vec::new(),
        distances_disagree: None,
        iterations: 0,
    };
    let pb = rep.task("bundle adjustment", 3);
    for round in 0..2 {
        rounds.snooping_round(scene, round, rep)?;
        pb.advance(1);
    }
    let (sp, estimate) = rounds.last(scene)?;
    scene.warnings.extend(rounds.distances_disagree.take());
    let solver::VarianceEstimate {
        components: variance_components,
        sigma0_a_priori,
        precision,
        ..
    } = estimate;
    pb.finish();
    // a coded target of a distance may have been dropped by data snooping
    let mut unused_distances = unused_distances;
    for w in unusable_distances(project, scene, &rounds.rejected_distances)? {
        if !unused_distances.contains(&w) {
            rep.log(format!("warning: {w}"));
            unused_distances.push(w);
        }
    }
    for w in super::network::layout_warnings(project, scene) {
        rep.log(format!("warning: {w}"));
        scene.warnings.push(w);
    }
    let rigs = sp.rig_poses(project);
    log_adjustment(
        &sp,
        scene,
        (sigma0_a_priori, &precision),
        &variance_components,
        rounds.rejected.len(),
        rep,
    );
    Ok(Adjusted {
        solved: sp,
        precision,
        sigma0_a_priori,
        rejected: rounds.rejected,
        rigs,
        iterations: rounds.iterations,
        unused_distances,
        rejected_distances: rounds.rejected_distances,
        variance_components,
        lens_doubt: None,
    })
}

/// The final adjustment's two log lines: its size, σ0, RMS and rejections, and its
/// variance components.
fn log_adjustment(
    sp: &SceneProblem,
    scene: &Scene,
    (sigma0_a_priori, precision): (f64, &solver::Precision),
    variance_components: &[solver::VarianceComponent],
    rejected: usize,
    rep: &Reporter,
) {
    rep.log(format!(
        "bundle adjustment: {} images, {} points ({} balls), {} image points, {} distances; sigma0 {:.3}, RMS {:.3} px, {} rejected",
        sp.problem.images.len(),
        sp.problem.points.len(),
        scene.points.iter().filter(|p| p.kind == PointKind::Ball).count(),
        sp.problem.observations.len(),
        sp.problem.distances.len(),
        sigma0_a_priori,
        precision.rms_image_px,
        rejected
    ));
    rep.log(format!(
        "bundle adjustment: variance components (σ0 of each group against its a-priori σ) {}",
        variance_components
            .iter()
            .map(|c| format!(
                "{} {:.3} (redundancy {:.0}{})",
                c.group,
                c.sigma0,
                c.redundancy,
                if c.reweighted {
                    ""
                } else {
                    ", not re-weighted"
                }
            ))
            .collect::<Vec<_>>()
            .join(", ")
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adjust::tests::fixture;

    /// A point the network no longer determines leaves the scene, and each of its
    /// measurements is a rejection naming its image and the reason (what the report lists).
    #[test]
    fn an_undetermined_point_is_dropped_with_its_measurements_as_rejections() {
        let (project, dets, mut scene) = fixture();
        let rejected = drop_undetermined(&project, &dets, &mut scene, "3", &[]).expect("dropped");
        assert_eq!(scene.points.len(), 2);
        assert!(scene.points.iter().all(|p| p.name != "3"));
        let images: Vec<&str> = rejected.iter().map(|r| r.image.as_str()).collect();
        assert_eq!(images, ["a.png", "c.png"]);
        for r in &rejected {
            assert_eq!(r.point, "3");
            assert_eq!(r.uv, [70.0, 40.0]);
            assert!(
                r.reason.contains("too few rays to determine it"),
                "{}",
                r.reason
            );
        }
    }

    /// A distance data snooping rejected is the project's entry (its ends in either order),
    /// named with the values given and adjusted; the later rounds' problems leave it out, and
    /// when it was the last distance the adjustment is refused by name rather than left
    /// without a scale.
    #[test]
    fn a_rejected_distance_is_named_left_out_and_not_the_last_scale() {
        let (project, dets, scene) = fixture();
        let snooped = DistanceRejection {
            a: "2".into(),
            b: "1".into(),
            given: 100.0,
            sigma: 0.1,
            estimated: 95.0,
            w: -41.0,
            reason: "standardized residual 41.00 > 3.29".into(),
        };
        let d = RejectedDistance::of(&project, &snooped).expect("the project's entry");
        assert_eq!((d.entry, d.from, d.to), (0, 1, 2));
        let warning = d.warning();
        assert!(
            warning.contains("distances[0]: the distance 1 – 2 given as 100.000 mm was measured as 95.000 mm (+5.000 mm, w = -41.0): a typo?"),
            "{warning}"
        );
        let other = DistanceRejection {
            given: 101.0,
            ..snooped
        };
        assert!(
            RejectedDistance::of(&project, &other).is_none(),
            "another value"
        );
        let mut rounds = Rounds {
            project: &project,
            dets: &dets,
            options: solver::Options::default(),
            snoop_critical: 3.29,
            rigs: Vec::new(),
            rejected: Vec::new(),
            rejected_distances: Vec::new(),
            distances_disagree: None,
            iterations: 0,
        };
        assert_eq!(rounds.problem(&scene).problem.distances.len(), 1);
        rounds.rejected_distances.push(d.clone());
        assert!(rounds.problem(&scene).problem.distances.is_empty());
        let Err(PipelineError::Data(e)) = unusable_distances(&project, &scene, &[d]) else {
            panic!("the scale was left undetermined");
        };
        assert!(
            e.contains("no distance is left to fix the scale") && e.contains("a typo?"),
            "{e}"
        );
    }

    /// A coded target of the only distance cannot go: nothing would fix the scale, and the
    /// error names it; a name not in the scene is an error too.
    #[test]
    fn the_last_distances_target_is_not_dropped_silently() {
        let (project, dets, mut scene) = fixture();
        let Err(PipelineError::Data(e)) = drop_undetermined(&project, &dets, &mut scene, "1", &[])
        else {
            panic!("dropping the distance's end passed");
        };
        assert!(
            e.contains("coded target 1 of the distances") && e.contains("no other distance"),
            "{e}"
        );
        let Err(PipelineError::Data(e)) = drop_undetermined(&project, &dets, &mut scene, "P9", &[])
        else {
            panic!("an unknown point passed");
        };
        assert!(e.contains("'P9' is not determined"), "{e}");
    }
}
