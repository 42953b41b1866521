//! A whole network from nothing but image measurements, approximate intrinsics and,
//! when there are any, points of known (approximate) coordinates.
//!
//! * **With control** (some image sees at least `min_resection_points` points of known
//!   coordinates, or two or more poses are given): every such image is resected; the points seen
//!   by two or more oriented images are intersected; a bundle adjustment
//!   ([`crate::solver::solve`]) refines what is oriented so far; then the images that now
//!   see enough oriented points are resected, and so on until nothing more can be added.
//! * **Without control**: the image pair with the strongest geometry (many common points,
//!   a large median intersection angle) is relatively oriented (the first image at the
//!   origin with the identity rotation, a unit baseline), its common points intersected,
//!   and the other images are resected from the intersected points a few at a time, with
//!   intersection and a bundle adjustment after each round. If three or more control points
//!   end up intersected, the whole network is brought into the control frame by a
//!   similarity transform and the control points take their given coordinates.
//! * **One given pose** and no image seeing enough control (the main station held fixed,
//!   as in the measurement file's documented example): one pose orients no point, so the
//!   start is the relative one, and at the end the network is moved rigidly so that this
//!   image has its given pose (unless control points took it into their frame).
//!
//! Intrinsics are held at their approximate values until `calibrate_from_images` images are
//! oriented; from then on the bundle adjustments free those the problem frees.
//!
//! Images and points that cannot be oriented are left out of the returned problem and
//! reported with the reason; nothing is ever set to NaN.

use super::intersection::{intersect, IntersectionError, IntersectionOptions, Ray};
use super::relative::{relative_orientation_radial, RelativeError, RelativeOptions};
use super::resection::{resect, similarity_transform, ResectionOptions};
use crate::keys::{ImageKey, PointKey};
use crate::problem::{Distance, PointPrior, Problem, ProblemError};
use crate::solver::{solve, Options, Rejection};
use nalgebra::Vector3;
use pingcal_geometry::Rigid3;
use std::collections::HashMap;

/// Options of [`initialise`].
#[derive(Clone, Debug)]
pub struct IncrementalOptions {
    /// Resection (threshold, RANSAC).
    pub resection: ResectionOptions,
    /// Intersection (angle and residual checks): `intersection.min_angle_deg` is the
    /// smallest largest angle between a point's rays for it to be intersected (default 2°);
    /// the points it refuses are listed in [`Initialised::refused_by_angle`].
    pub intersection: IntersectionOptions,
    /// Relative orientation of the starting pair (no control).
    pub relative: RelativeOptions,
    /// Fewest oriented points an image must see to be resected.
    pub min_resection_points: usize,
    /// Most images resected per round when growing from a relative orientation (with
    /// control, every image that sees enough control is resected in the first round).
    pub images_per_round: usize,
    /// Candidate pairs tried for the relative orientation.
    pub candidate_pairs: usize,
    /// Run a bundle adjustment after each round.
    pub bundle_between_steps: bool,
    /// Solver options of those bundle adjustments.
    pub bundle: Options,
    /// Free the problem's free intrinsics once this many images are oriented.
    pub calibrate_from_images: usize,
    /// Resect images from the known points (default). When false, the network is built
    /// from a relative orientation and the known points serve only to move it into their
    /// frame at the end.
    pub resect_from_control: bool,
    /// Reject gross errors after the bundle adjustments whose intrinsics are final
    /// (self-calibrating, or nothing to calibrate): an observation whose residual exceeds
    /// `max(reject_sigmas · s, reject_min_px)`, s the robust (MAD) residual scale, is left
    /// out of the rest of the initialisation and of the returned problem. After the bundle
    /// adjustment without them, every rejected observation whose residual is now under that
    /// threshold is given back (a gross error drags its point and its image, so good
    /// observations of both exceed the threshold before it is gone: one 60 px blunder used to
    /// take 11 good observations with it).
    pub reject_outliers: bool,
    /// See `reject_outliers`.
    pub reject_sigmas: f64,
    /// See `reject_outliers`, pixels.
    pub reject_min_px: f64,
}

/// The most rejection rounds of one start-up bundle (each takes the worst observation of
/// each point above the threshold, then adjusts again).
const REJECTION_ROUNDS: usize = 5;

impl Default for IncrementalOptions {
    fn default() -> Self {
        Self {
            resection: ResectionOptions::default(),
            intersection: IntersectionOptions::default(),
            relative: RelativeOptions::default(),
            min_resection_points: 4,
            images_per_round: 3,
            candidate_pairs: 6,
            bundle_between_steps: true,
            bundle: Options {
                max_iterations: 50,
                ..Options::default()
            },
            calibrate_from_images: 3,
            resect_from_control: true,
            reject_outliers: true,
            reject_sigmas: 10.0,
            reject_min_px: 3.0,
        }
    }
}

/// One thing the initialiser did, in order.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// An image resected from `points` points of which `inliers` agree.
    Resected {
        /// The image's name.
        image: String,
        /// Oriented points (control or intersected) the image sees.
        points: usize,
        /// Those within the resection's threshold at the refined pose.
        inliers: usize,
        /// RMS reprojection error of the inliers, pixels per coordinate.
        rms_px: f64,
    },
    /// The starting pair of a network without control.
    RelativePair {
        /// The first image's name: placed at the origin with the identity rotation.
        first: String,
        /// The second image's name: placed at a unit distance from the first.
        second: String,
        /// Common points consistent with the pair's epipolar geometry and in front of both
        /// images.
        inliers: usize,
        /// Median angle between the two rays of those points, degrees (the strength of the
        /// baseline).
        median_angle_deg: f64,
        /// The radial correction of the rays estimated with it (fraction of the radius at
        /// the outermost ray; 0: none).
        radial_correction: f64,
    },
    /// Points intersected in this round.
    Intersected {
        /// Points newly intersected.
        points: usize,
    },
    /// A bundle adjustment of what is oriented so far.
    Bundle {
        /// Images oriented so far, all in the adjustment.
        images: usize,
        /// Points determined so far (intersected or control), all in the adjustment.
        points: usize,
        /// Iterations the solver took.
        iterations: usize,
        /// RMS reprojection residual after it, pixels per coordinate.
        rms_px: f64,
        /// Whether the problem's free intrinsics were adjusted (from
        /// [`IncrementalOptions::calibrate_from_images`] oriented images on) or held.
        calibrating: bool,
    },
    /// Observations rejected as gross errors after a bundle adjustment.
    Rejected {
        /// Observations rejected in this round.
        observations: usize,
        /// The residual above which they were, pixels: the larger of
        /// [`IncrementalOptions::reject_sigmas`] robust σ and
        /// [`IncrementalOptions::reject_min_px`].
        threshold_px: f64,
    },
    /// Rejected observations given back: their residuals, adjusted without them, are under
    /// the threshold that rejected them.
    Readmitted {
        /// Observations given back.
        observations: usize,
        /// The threshold of the last rejection, pixels.
        threshold_px: f64,
    },
    /// A bundle adjustment that failed (its result is discarded).
    BundleFailed {
        /// The solver's error, or `non-finite estimate`.
        message: String,
    },
    /// A relative network scaled so that its measured distances hold.
    ScaledByDistances {
        /// Measured distances whose two points were determined.
        distances: usize,
        /// The factor applied to the points and the projection centres: the median of
        /// measured / network length.
        scale: f64,
    },
    /// The network moved into the control frame by a similarity transform.
    ToControlFrame {
        /// Control points intersected, on which the transform was fitted.
        points: usize,
        /// The transform's scale (control frame length / network length).
        scale: f64,
        /// RMS distance between the transformed points and their given coordinates, in the
        /// control frame's unit (mm).
        rms: f64,
    },
    /// The network moved rigidly so that the one image of given pose has it.
    ToGivenPose {
        /// The image's name.
        image: String,
    },
}

impl std::fmt::Display for Step {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Step::Resected {
                image,
                points,
                inliers,
                rms_px,
            } => write!(
                f,
                "resected image '{image}': {inliers}/{points} points, RMS {rms_px:.2} px"
            ),
            Step::RelativePair {
                first,
                second,
                inliers,
                median_angle_deg,
                radial_correction,
            } => {
                write!(
                    f,
                    "relative orientation '{first}'–'{second}': {inliers} points, median angle {median_angle_deg:.1}°"
                )?;
                if *radial_correction != 0.0 {
                    write!(
                        f,
                        ", rays corrected by {:+.1} % of the radius at the outermost ray (unmodelled radial distortion)",
                        100.0 * radial_correction
                    )?;
                }
                Ok(())
            }
            Step::Intersected { points } => write!(f, "intersected {points} points"),
            Step::Bundle {
                images,
                points,
                iterations,
                rms_px,
                calibrating,
            } => write!(
                f,
                "bundle: {images} images, {points} points, {iterations} iterations, RMS {rms_px:.3} px{}",
                if *calibrating { ", self-calibrating" } else { "" }
            ),
            Step::BundleFailed { message } => write!(f, "bundle failed: {message}"),
            Step::Rejected {
                observations,
                threshold_px,
            } => write!(
                f,
                "rejected {observations} observations with residuals above {threshold_px:.2} px"
            ),
            Step::Readmitted {
                observations,
                threshold_px,
            } => write!(
                f,
                "gave back {observations} rejected observations, now under {threshold_px:.2} px"
            ),
            Step::ScaledByDistances { distances, scale } => write!(
                f,
                "scaled by {scale:.6} from {distances} measured distances"
            ),
            Step::ToControlFrame { points, scale, rms } => write!(
                f,
                "similarity onto {points} control points: scale {scale:.6}, RMS {rms:.4}"
            ),
            Step::ToGivenPose { image } => {
                write!(f, "moved rigidly so that image '{image}' has its given pose")
            }
        }
    }
}

/// The initialised network.
#[derive(Clone, Debug)]
pub struct Initialised {
    /// The oriented images and intersected (or control) points with their observations,
    /// in the input order; cameras, their fixed flags and the loss as in the input.
    pub problem: Problem,
    /// Input image index → index in `problem` (None: not oriented).
    pub image_map: Vec<Option<usize>>,
    /// Input point index → index in `problem` (None: not determined).
    pub point_map: Vec<Option<usize>>,
    /// What was done, in order.
    pub steps: Vec<Step>,
    /// Images that could not be oriented, with the reason.
    pub unoriented_images: Vec<(String, String)>,
    /// Points that could not be determined, with the reason.
    pub undetermined_points: Vec<(String, String)>,
    /// Of those, the points the intersection refused because their rays meet at too small
    /// an angle (below [`IncrementalOptions::intersection`]'s `min_angle_deg`), with the
    /// largest angle between two of their rays in degrees, in input order.
    pub refused_by_angle: Vec<(String, f64)>,
    /// Whether the network is in the frame of the control points (always with control;
    /// without, once three or more of them were intersected). When false, control points
    /// are not held fixed and weighted control is left out of `problem`.
    pub in_control_frame: bool,
    /// Observations rejected as gross errors: image, point, residual in pixels.
    pub rejected_observations: Vec<(String, String, f64)>,
    /// The same, as the adjustment report lists rejections (measured coordinates,
    /// standardized residuals and the threshold in words): a caller reports them with the
    /// adjustment's own, so that nothing is dropped without saying so.
    pub rejections: Vec<Rejection>,
}

/// Two images and their common observations (first image's, second image's).
type PairObs = ((usize, usize), Vec<(usize, usize)>);

/// A relative orientation of two images with its score.
type Scored = (f64, (usize, usize), super::relative::Relative);

/// Why no network could be started.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum InitError {
    /// The problem is malformed.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// `known_points` / `known_poses` do not match the problem.
    #[error("{0}")]
    BadInput(String),
    /// Neither control nor a usable image pair.
    #[error("cannot start the network: {0}")]
    NoStart(String),
}

/// The oriented part of the problem as a problem of its own, and where its items come from.
struct SubProblem {
    problem: Problem,
    /// Per image of the full problem, its index in the sub-problem (None: not oriented).
    image_map: Vec<Option<usize>>,
    /// Per point of the full problem, its index in the sub-problem (None: not determined).
    point_map: Vec<Option<usize>>,
    /// Per observation of the sub-problem, its index in the full problem.
    obs_map: Vec<usize>,
}

struct State<'a> {
    problem: &'a Problem,
    params: Vec<Vec<f64>>,
    poses: Vec<Option<Rigid3>>,
    points: Vec<Option<Vector3<f64>>>,
    by_image: Vec<Vec<usize>>,
    by_point: Vec<Vec<usize>>,
    image_reason: Vec<String>,
    point_reason: Vec<String>,
    /// Per point: the largest angle between its rays (degrees) when its last intersection
    /// was refused for it.
    small_angle: Vec<Option<f64>>,
    steps: Vec<Step>,
    /// Whether control coordinates are in the frame (with control) or not (relative start).
    control_frame: bool,
    known: Vec<bool>,
    /// Per observation: rejected as a gross error (with its residual, px, and the record
    /// for the report).
    rejected: Vec<Option<(f64, Rejection)>>,
}

impl<'a> State<'a> {
    fn oriented(&self) -> usize {
        self.poses.iter().filter(|p| p.is_some()).count()
    }

    fn resect_image(&mut self, i: usize, options: &IncrementalOptions) -> bool {
        let im = &self.problem.images[i];
        let cam = &self.problem.cameras[im.camera];
        let (mut uv, mut x) = (Vec::new(), Vec::new());
        for &o in &self.by_image[i] {
            let ob = &self.problem.observations[o];
            if let Some(p) = self.points[ob.point.0] {
                uv.push(ob.uv);
                x.push(p);
            }
        }
        match resect(
            cam.model.as_ref(),
            &self.params[im.camera.0],
            &uv,
            &x,
            &options.resection,
        ) {
            Ok(r) => {
                self.poses[i] = Some(r.camera_from_object);
                self.steps.push(Step::Resected {
                    image: im.name.clone(),
                    points: uv.len(),
                    inliers: r.inliers.iter().filter(|v| **v).count(),
                    rms_px: r.rms_px,
                });
                true
            }
            Err(e) => {
                self.image_reason[i] = format!("resection failed: {e}");
                false
            }
        }
    }

    fn intersect_points(&mut self, options: &IncrementalOptions) -> usize {
        let mut count = 0;
        for j in 0..self.points.len() {
            if self.points[j].is_some() {
                continue;
            }
            let rays: Vec<Ray> = self.by_point[j]
                .iter()
                .filter_map(|&o| {
                    let ob = &self.problem.observations[o];
                    let pose = self.poses[ob.image.0]?;
                    let cam = &self.problem.cameras[self.problem.images[ob.image].camera];
                    Some(Ray {
                        camera_from_object: pose,
                        model: cam.model.as_ref(),
                        params: &self.params[self.problem.images[ob.image].camera.0],
                        uv: ob.uv,
                    })
                })
                .collect();
            self.small_angle[j] = None;
            if rays.len() < 2 {
                self.point_reason[j] = format!(
                    "seen in {} oriented image{} (2 needed)",
                    rays.len(),
                    if rays.len() == 1 { "" } else { "s" }
                );
                continue;
            }
            match intersect(&rays, &options.intersection) {
                Ok(r) => {
                    self.points[j] = Some(r.position);
                    count += 1;
                }
                Err(e) => {
                    if let IntersectionError::SmallAngle { angle_deg, .. } = e {
                        self.small_angle[j] = Some(angle_deg);
                    }
                    self.point_reason[j] = format!("intersection failed: {e}");
                }
            }
        }
        if count > 0 {
            self.steps.push(Step::Intersected { points: count });
        }
        count
    }

    /// The sub-problem of what is oriented, with maps.
    fn subproblem(&self, calibrating: bool) -> SubProblem {
        let p = self.problem;
        let mut sub = Problem {
            cameras: p.cameras.clone(),
            loss: p.loss,
            ..Problem::default()
        };
        for (c, params) in sub.cameras.iter_mut().zip(&self.params) {
            c.params.clone_from(params);
            if !calibrating {
                c.fixed.iter_mut().for_each(|f| *f = true);
            }
        }
        let mut image_map = vec![None; p.images.len()];
        for (i, im) in p.images.iter().enumerate() {
            if let Some(pose) = self.poses[i] {
                image_map[i] = Some(sub.images.len());
                let mut im = im.clone();
                im.camera_from_object = pose;
                if !self.control_frame {
                    im.fixed_centre = [false; 3];
                } else if im.is_centre_held() {
                    // A held centre coordinate keeps its given value, not the estimate's.
                    let (mut c, given) = (pose.centre(), p.images[i].camera_from_object.centre());
                    for a in (0..3).filter(|&a| im.fixed_centre[a]) {
                        c[a] = given[a];
                    }
                    im.camera_from_object = Rigid3::from_rotation_and_centre(pose.rotation, c);
                }
                sub.images.push(im);
            }
        }
        let mut point_map = vec![None; p.points.len()];
        for (j, pt) in p.points.iter().enumerate() {
            if let Some(x) = self.points[j] {
                point_map[j] = Some(sub.points.len());
                let mut pt = pt.clone();
                pt.position = x;
                // Control points are held only when the frame is the control frame.
                pt.fixed = pt.fixed && self.control_frame && self.known[j];
                if !self.control_frame {
                    pt.fixed_axes = [false; 3];
                } else {
                    // A held coordinate keeps its given value, not the estimate's (which
                    // is an intersection for a point that is not known as a whole).
                    for a in (0..3).filter(|&a| pt.fixed_axes[a]) {
                        pt.position[a] = p.points[j].position[a];
                    }
                }
                sub.points.push(pt);
            }
        }
        for d in &p.distances {
            if let (Some(a), Some(b)) = (point_map[d.a.0], point_map[d.b.0]) {
                sub.distances.push(Distance {
                    a: PointKey(a),
                    b: PointKey(b),
                    ..*d
                });
            }
        }
        if self.control_frame {
            for c in &p.point_priors {
                if let Some(point) = point_map[c.point.0] {
                    sub.point_priors.push(PointPrior {
                        point: PointKey(point),
                        ..*c
                    });
                }
            }
        }
        let mut obs_map = Vec::new();
        for (k, o) in p.observations.iter().enumerate() {
            if self.rejected[k].is_some() {
                continue;
            }
            if let (Some(i), Some(j)) = (image_map[o.image.0], point_map[o.point.0]) {
                let mut o = *o;
                o.image = ImageKey(i);
                o.point = PointKey(j);
                // Leave out what does not project at the current estimate.
                if sub.residual(&o).is_some() {
                    sub.observations.push(o);
                    obs_map.push(k);
                }
            }
        }
        SubProblem {
            problem: sub,
            image_map,
            point_map,
            obs_map,
        }
    }

    /// Flags gross errors in the adjusted sub-problem; returns the threshold when it flagged
    /// any.
    fn reject(
        &mut self,
        sub: &Problem,
        obs_map: &[usize],
        options: &IncrementalOptions,
    ) -> Option<f64> {
        let residuals: Vec<Option<nalgebra::Vector2<f64>>> =
            sub.observations.iter().map(|o| sub.residual(o)).collect();
        let res: Vec<f64> = residuals
            .iter()
            .map(|r| r.map_or(f64::INFINITY, |r| r.norm()))
            .collect();
        let mut comps: Vec<f64> = sub
            .observations
            .iter()
            .filter_map(|o| sub.residual(o))
            .flat_map(|r| [r.x.abs(), r.y.abs()])
            .collect();
        if comps.is_empty() {
            return None;
        }
        comps.sort_by(f64::total_cmp);
        let scale = 1.4826 * comps[comps.len() / 2];
        let threshold = (options.reject_sigmas * scale).max(options.reject_min_px);
        // Only the worst observation of each point per round: a gross error drags its
        // point, and the point's good observations must not go with it.
        let mut worst: HashMap<usize, usize> = HashMap::new();
        for (k, r) in res.iter().enumerate() {
            if *r > threshold {
                let j = sub.observations[k].point;
                let e = worst.entry(j.0).or_insert(k);
                if res[*e] < *r {
                    *e = k;
                }
            }
        }
        let mut flagged: Vec<usize> = worst.into_values().collect();
        if flagged.is_empty() {
            return None;
        }
        flagged.sort_unstable();
        for &k in &flagged {
            let r = res[k];
            let o = obs_map[k];
            let ob = self.problem.observations[o];
            let w = residuals[k].map_or([f64::INFINITY; 2], |v| [v.x / ob.sigma, v.y / ob.sigma]);
            let rejection = Rejection {
                image: self.problem.images[ob.image].name.clone(),
                point: self.problem.points[ob.point].name.clone(),
                uv: [ob.uv.x, ob.uv.y],
                w,
                reason: format!(
                    "start-up bundle: residual {r:.2} px above {threshold:.2} px (the larger of {} robust σ and {} px)",
                    options.reject_sigmas, options.reject_min_px
                ),
            };
            self.rejected[o] = Some((r, rejection));
            self.by_image[ob.image.0].retain(|&x| x != o);
            self.by_point[ob.point.0].retain(|&x| x != o);
        }
        // Points left with fewer than two rays are undetermined again.
        for j in 0..self.points.len() {
            if self.points[j].is_some() && !self.known[j] {
                let rays = self.by_point[j]
                    .iter()
                    .filter(|&&o| self.poses[self.problem.observations[o].image.0].is_some())
                    .count();
                if rays < 2 {
                    self.points[j] = None;
                    self.point_reason[j] = "too few rays left after rejecting gross errors".into();
                    self.small_angle[j] = None;
                }
            }
        }
        self.steps.push(Step::Rejected {
            observations: flagged.len(),
            threshold_px: threshold,
        });
        Some(threshold)
    }

    /// After a first rejection at `threshold` px: adjusts again and rejects again (the worst
    /// of each point), [`REJECTION_ROUNDS`] rejections at most, then gives back what is under
    /// the threshold at the last estimate and adjusts once more if it gave any back.
    fn reject_rounds(&mut self, options: &IncrementalOptions, mut threshold: f64) {
        for round in 1.. {
            let Some((sub, obs_map, _)) = self.adjust(options) else {
                return;
            };
            if round >= REJECTION_ROUNDS {
                break;
            }
            match self.reject(&sub, &obs_map, options) {
                Some(t) => threshold = t,
                None => break,
            }
        }
        if self.readmit(threshold) > 0 {
            self.adjust(options);
        }
    }

    /// Gives back every rejected observation whose residual at the current estimate is at
    /// most `threshold_px` (its image oriented and its point determined); returns how many.
    fn readmit(&mut self, threshold_px: f64) -> usize {
        let mut count = 0;
        for o in 0..self.rejected.len() {
            if self.rejected[o].is_none() {
                continue;
            }
            let ob = self.problem.observations[o];
            let (Some(pose), Some(x)) = (self.poses[ob.image.0], self.points[ob.point.0]) else {
                continue;
            };
            let c = self.problem.images[ob.image].camera;
            let model = &self.problem.cameras[c].model;
            let Some(uv) = model.project(&self.params[c.0], &pose.transform(&x), None, None) else {
                continue;
            };
            if (uv - ob.uv).norm() <= threshold_px {
                self.rejected[o] = None;
                for list in [
                    &mut self.by_image[ob.image.0],
                    &mut self.by_point[ob.point.0],
                ] {
                    list.push(o);
                    list.sort_unstable();
                }
                count += 1;
            }
        }
        if count > 0 {
            self.steps.push(Step::Readmitted {
                observations: count,
                threshold_px,
            });
        }
        count
    }

    fn bundle(&mut self, options: &IncrementalOptions) {
        self.bundle_once(options, options.reject_outliers);
    }

    /// A bundle adjustment, then (when `allow_reject` and the camera model is final) the
    /// rejection of gross errors.
    fn bundle_once(&mut self, options: &IncrementalOptions, allow_reject: bool) {
        let Some((sub, obs_map, model_final)) = self.adjust(options) else {
            return;
        };
        if allow_reject && model_final {
            if let Some(threshold) = self.reject(&sub, &obs_map, options) {
                self.reject_rounds(options, threshold);
            }
        }
    }

    /// Adjusts what is oriented so far and takes its estimate; returns the adjusted
    /// sub-problem, its observation map and whether the camera model is final (None: no
    /// observation, or the adjustment failed, which is logged).
    fn adjust(&mut self, options: &IncrementalOptions) -> Option<(Problem, Vec<usize>, bool)> {
        let calibrating = self.oriented() >= options.calibrate_from_images;
        let SubProblem {
            problem: mut sub,
            image_map,
            point_map,
            obs_map,
        } = self.subproblem(calibrating);
        if sub.observations.is_empty() {
            return None;
        }
        // Without control the datum is the first oriented image (scale from the distances,
        // if any, otherwise left to the damping).
        // Single held coordinates (point or centre) count when they define a datum
        // themselves; fixing the first image on top would distort the network.
        let held_datum = (sub
            .points
            .iter()
            .any(|p| !p.fixed && p.held().iter().any(|h| *h))
            || sub.images.iter().any(|i| i.is_centre_held()))
            && crate::datum::check(&sub, false).is_ok();
        let control_datum =
            sub.points.iter().any(|p| p.fixed) || sub.point_priors.len() >= 3 || held_datum;
        if !control_datum {
            if let Some(first) = sub.images.first_mut() {
                first.fixed = true;
            }
        }
        match solve(&mut sub, &options.bundle, |_| {}) {
            Ok(summary) => {
                let finite = sub.images.iter().all(|im| {
                    im.camera_from_object
                        .rotation
                        .iter()
                        .chain(im.camera_from_object.translation.iter())
                        .all(|v| v.is_finite())
                }) && sub
                    .points
                    .iter()
                    .all(|p| p.position.iter().all(|v| v.is_finite()))
                    && sub
                        .cameras
                        .iter()
                        .all(|c| c.params.iter().all(|v| v.is_finite()));
                if !finite {
                    self.steps.push(Step::BundleFailed {
                        message: "non-finite estimate".into(),
                    });
                    return None;
                }
                for (i, m) in image_map.iter().enumerate() {
                    if let Some(k) = m {
                        self.poses[i] = Some(sub.images[*k].camera_from_object);
                    }
                }
                for (j, m) in point_map.iter().enumerate() {
                    if let Some(k) = m {
                        self.points[j] = Some(sub.points[*k].position);
                    }
                }
                for (c, sc) in self.params.iter_mut().zip(&sub.cameras) {
                    c.clone_from(&sc.params);
                }
                self.steps.push(Step::Bundle {
                    images: sub.images.len(),
                    points: sub.points.len(),
                    iterations: summary.iterations,
                    rms_px: sub.rms_px(),
                    calibrating,
                });
                let model_final = calibrating
                    || self
                        .problem
                        .cameras
                        .iter()
                        .all(|c| c.fixed.iter().all(|f| *f));
                Some((sub, obs_map, model_final))
            }
            Err(e) => {
                self.steps.push(Step::BundleFailed {
                    message: e.to_string(),
                });
                None
            }
        }
    }

    /// Tries relative orientation on the best pairs; orients the winner.
    fn bootstrap(&mut self, options: &IncrementalOptions) -> Result<(), InitError> {
        let p = self.problem;
        let mut common: HashMap<(usize, usize), Vec<(usize, usize)>> = HashMap::new();
        for obs in &self.by_point {
            for (a, &oa) in obs.iter().enumerate() {
                for &ob in &obs[a + 1..] {
                    let (ia, ib) = (p.observations[oa].image.0, p.observations[ob].image.0);
                    let (key, pair) = if ia < ib {
                        ((ia, ib), (oa, ob))
                    } else {
                        ((ib, ia), (ob, oa))
                    };
                    if ia != ib {
                        common.entry(key).or_default().push(pair);
                    }
                }
            }
        }
        let mut pairs: Vec<_> = common.into_iter().filter(|(_, v)| v.len() >= 8).collect();
        pairs.sort_by(|a, b| b.1.len().cmp(&a.1.len()).then(a.0.cmp(&b.0)));
        let tried = pairs.len().min(options.candidate_pairs.max(1));
        let pairs = &pairs[..tried];
        // The rays as given first; the radial search only when no pair orients with them
        // (a distortion-corrected start is coarser than an uncorrected one that works).
        let plain = RelativeOptions {
            radial_bound: 0.0,
            ..options.relative.clone()
        };
        let (mut best, mut failure) = self.best_pair(pairs, &plain);
        if best.is_none() && options.relative.radial_bound != 0.0 {
            (best, failure) = self.best_pair(pairs, &options.relative);
        }
        let Some((_, (ia, ib), r)) = best else {
            return Err(InitError::NoStart(no_start_message(
                tried,
                failure,
                &options.relative,
            )));
        };
        self.poses[ia] = Some(Rigid3::identity());
        self.poses[ib] = Some(r.camera2_from_camera1);
        self.steps.push(Step::RelativePair {
            first: p.images[ia].name.clone(),
            second: p.images[ib].name.clone(),
            inliers: r.inliers.iter().filter(|v| **v).count(),
            median_angle_deg: r.median_angle_deg,
            radial_correction: r.radial_correction,
        });
        Ok(())
    }

    /// The relative orientation of `pairs` (images and their common observations) with the
    /// largest score (consistent points × median intersection angle up to 10°), or the
    /// failure of the pair with the most support.
    fn best_pair(
        &self,
        pairs: &[PairObs],
        relative: &RelativeOptions,
    ) -> (Option<Scored>, Option<String>) {
        let p = self.problem;
        let mut best: Option<Scored> = None;
        let mut failure: Option<(usize, String)> = None;
        for &((ia, ib), ref obs) in pairs {
            let ray = |o: usize| {
                let ob = &p.observations[o];
                let cam = p.images[ob.image].camera;
                p.cameras[cam].model.unproject(&self.params[cam.0], &ob.uv)
            };
            let (mut d1, mut d2) = (Vec::new(), Vec::new());
            for &(oa, ob) in obs {
                if let (Some(a), Some(b)) = (ray(oa), ray(ob)) {
                    d1.push(a);
                    d2.push(b);
                }
            }
            match relative_orientation_radial(&d1, &d2, relative) {
                Ok(r) => {
                    let n = r.inliers.iter().filter(|v| **v).count() as f64;
                    let score = n * r.median_angle_deg.min(10.0);
                    if best.as_ref().is_none_or(|b| score > b.0) {
                        best = Some((score, (ia, ib), r));
                    }
                }
                Err(e) => {
                    let support = match e {
                        RelativeError::NoConsensus { best, .. } => best,
                        RelativeError::TooFewPoints { .. } => 0,
                    };
                    if failure.as_ref().is_none_or(|f| support > f.0) {
                        let names = (&p.images[ia].name, &p.images[ib].name);
                        failure = Some((support, format!("best '{}'–'{}': {e}", names.0, names.1)));
                    }
                }
            }
        }
        (best, failure.map(|f| f.1))
    }

    /// Scales a relative network so that its measured distances hold (median ratio).
    fn scale_from_distances(&mut self) {
        let mut ratios: Vec<f64> = self
            .problem
            .distances
            .iter()
            .filter_map(|d| {
                let (a, b) = (self.points[d.a.0]?, self.points[d.b.0]?);
                let l = (a - b).norm();
                (l > 0.0).then(|| d.value / l)
            })
            .filter(|r| r.is_finite() && *r > 0.0)
            .collect();
        if ratios.is_empty() {
            return;
        }
        ratios.sort_by(f64::total_cmp);
        let s = ratios[ratios.len() / 2];
        for x in self.points.iter_mut().flatten() {
            *x *= s;
        }
        for pose in self.poses.iter_mut().flatten() {
            pose.translation *= s;
        }
        self.steps.push(Step::ScaledByDistances {
            distances: ratios.len(),
            scale: s,
        });
    }

    /// Moves the network rigidly so that image `i` has its pose of the problem (the one the
    /// caller gave), when it is oriented.
    fn move_to_given_pose(&mut self, i: usize) {
        let Some(now) = self.poses[i] else {
            return;
        };
        let given = self.problem.images[i].camera_from_object;
        // x_given = given⁻¹ · now · x_relative; each pose P becomes P · now⁻¹ · given.
        let to_given = given.inverse().compose(&now);
        let from_given = now.inverse().compose(&given);
        for x in self.points.iter_mut().flatten() {
            *x = to_given.transform(x);
        }
        for pose in self.poses.iter_mut().flatten() {
            *pose = pose.compose(&from_given);
        }
        self.poses[i] = Some(given);
        self.control_frame = true;
        self.steps.push(Step::ToGivenPose {
            image: self.problem.images[i].name.clone(),
        });
    }

    fn move_to_control_frame(&mut self) {
        let (mut from, mut to, mut idx) = (Vec::new(), Vec::new(), Vec::new());
        for j in 0..self.points.len() {
            if let (true, Some(x)) = (self.known[j], self.points[j]) {
                from.push(x);
                to.push(self.problem.points[j].position);
                idx.push(j);
            }
        }
        if from.len() < 3 {
            return;
        }
        let Some((t, s)) = similarity_transform(&from, &to, true) else {
            return;
        };
        if !(s > 0.0 && s.is_finite()) {
            return;
        }
        let map = |x: &Vector3<f64>| s * (t.rotation * x) + t.translation;
        let rms = (from
            .iter()
            .zip(&to)
            .map(|(a, b)| (map(a) - b).norm_squared())
            .sum::<f64>()
            / from.len() as f64)
            .sqrt();
        for x in self.points.iter_mut().flatten() {
            *x = map(x);
        }
        for pose in self.poses.iter_mut().flatten() {
            let c = map(&pose.centre());
            let r = pose.rotation * t.rotation.transpose();
            *pose = Rigid3::from_rotation_and_centre(r, c);
        }
        for &j in &idx {
            self.points[j] = Some(self.problem.points[j].position);
        }
        self.control_frame = true;
        self.steps.push(Step::ToControlFrame {
            points: from.len(),
            scale: s,
            rms,
        });
    }
}

/// Why no relative orientation started the network, and what would start it: `tried` pairs of
/// eight or more common points were tried, `failure` is the one with the most support.
fn no_start_message(tried: usize, failure: Option<String>, options: &RelativeOptions) -> String {
    let needs = "give 4 or more control points (known coordinates) seen by one image, a known pose with control, or more targets common to two images taken from different positions";
    match failure {
        None => format!("no two images share 8 or more points: {needs}"),
        Some(f) => {
            let radial = match options.radial_bound.abs() {
                0.0 => String::new(),
                b => format!(
                    ", even with their rays corrected for a radial distortion of up to {:.0} %",
                    100.0 * b
                ),
            };
            format!(
                "none of the {tried} image pairs with the most common points has a relative orientation with {} or more consistent points{radial} ({f}): {needs}",
                options.min_inliers.max(8),
            )
        }
    }
}

/// The per-item flags `given` for `n` items: all false when empty, refused when of another
/// length (`name` and `items` name them in the error).
fn flags(given: &[bool], n: usize, name: &str, items: &str) -> Result<Vec<bool>, InitError> {
    if given.is_empty() {
        Ok(vec![false; n])
    } else if given.len() == n {
        Ok(given.to_vec())
    } else {
        Err(InitError::BadInput(format!(
            "{name} has {} entries for {n} {items}",
            given.len()
        )))
    }
}

impl<'a> State<'a> {
    /// The starting state: the known poses and point coordinates of `problem`, nothing
    /// else determined.
    fn new(problem: &'a Problem, known: &[bool], known_pose: &[bool]) -> Self {
        let (np, ni) = (problem.points.len(), problem.images.len());
        let mut by_image = vec![Vec::new(); ni];
        let mut by_point = vec![Vec::new(); np];
        for (k, o) in problem.observations.iter().enumerate() {
            by_image[o.image.0].push(k);
            by_point[o.point.0].push(k);
        }
        Self {
            problem,
            params: problem.cameras.iter().map(|c| c.params.clone()).collect(),
            poses: (0..ni)
                .map(|i| known_pose[i].then_some(problem.images[i].camera_from_object))
                .collect(),
            points: (0..np)
                .map(|j| known[j].then_some(problem.points[j].position))
                .collect(),
            by_image,
            by_point,
            image_reason: vec!["never tried".into(); ni],
            point_reason: vec!["never tried".into(); np],
            small_angle: vec![None; np],
            steps: Vec::new(),
            control_frame: true,
            known: known.to_vec(),
            rejected: vec![None; problem.observations.len()],
        }
    }

    /// How many points of image `i` have coordinates (known or intersected).
    fn determined_points_seen(&self, i: usize) -> usize {
        self.by_image[i]
            .iter()
            .filter(|&&o| self.points[self.problem.observations[o].point.0].is_some())
            .count()
    }

    /// The start with control: every image not yet oriented that sees enough points of
    /// known coordinates is resected; fails when none could be.
    fn resect_from_control(&mut self, options: &IncrementalOptions) -> Result<(), InitError> {
        for i in 0..self.problem.images.len() {
            if self.poses[i].is_none() {
                let n = self.determined_points_seen(i);
                if n >= options.min_resection_points {
                    self.resect_image(i, options);
                } else {
                    self.image_reason[i] = format!(
                        "sees {n} points of known coordinates (needs {})",
                        options.min_resection_points
                    );
                }
            }
        }
        if self.oriented() == 0 {
            return Err(InitError::NoStart(
                "no image could be resected from the control points".into(),
            ));
        }
        Ok(())
    }

    /// Grows the network until nothing changes: in each round, resects up to `per_round`
    /// images (those seeing the most determined points first), intersects the new
    /// points, and bundles when asked to.
    fn grow(&mut self, options: &IncrementalOptions, per_round: usize) {
        loop {
            let mut cands: Vec<(usize, usize)> = (0..self.problem.images.len())
                .filter(|&i| self.poses[i].is_none())
                .map(|i| (self.determined_points_seen(i), i))
                .collect();
            cands.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
            let mut added = 0;
            for (n, i) in cands {
                if added >= per_round {
                    break;
                }
                if n < options.min_resection_points {
                    self.image_reason[i] = format!(
                        "sees {n} oriented points (needs {})",
                        options.min_resection_points
                    );
                    continue;
                }
                if self.resect_image(i, options) {
                    added += 1;
                }
            }
            let new_points = self.intersect_points(options);
            if added == 0 && new_points == 0 {
                break;
            }
            if options.bundle_between_steps {
                self.bundle(options);
            }
        }
    }

    /// The result: the oriented part as a problem, with the caller's fixed flags on the
    /// intrinsics, and what could not be oriented or determined, and why.
    fn into_initialised(self) -> Initialised {
        let problem = self.problem;
        let SubProblem {
            problem: mut sub,
            image_map,
            point_map,
            ..
        } = self.subproblem(true);
        for (c, orig) in sub.cameras.iter_mut().zip(&problem.cameras) {
            c.fixed.clone_from(&orig.fixed);
        }
        let unoriented_images = (0..problem.images.len())
            .filter(|&i| self.poses[i].is_none())
            .map(|i| (problem.images[i].name.clone(), self.image_reason[i].clone()))
            .collect();
        let undetermined_points = (0..problem.points.len())
            .filter(|&j| self.points[j].is_none())
            .map(|j| (problem.points[j].name.clone(), self.point_reason[j].clone()))
            .collect();
        let refused_by_angle = (0..problem.points.len())
            .filter(|&j| self.points[j].is_none())
            .filter_map(|j| Some((problem.points[j].name.clone(), self.small_angle[j]?)))
            .collect();
        let rejected_observations = (self.rejected.iter().enumerate())
            .filter_map(|(k, r)| {
                let o = &problem.observations[k];
                r.as_ref().map(|(r, _)| {
                    (
                        problem.images[o.image].name.clone(),
                        problem.points[o.point].name.clone(),
                        *r,
                    )
                })
            })
            .collect();
        let rejections = self
            .rejected
            .iter()
            .filter_map(|r| r.as_ref().map(|(_, rej)| rej.clone()))
            .collect();
        Initialised {
            problem: sub,
            image_map,
            point_map,
            in_control_frame: self.control_frame || !self.known.iter().any(|k| *k),
            steps: self.steps,
            unoriented_images,
            undetermined_points,
            refused_by_angle,
            rejected_observations,
            rejections,
        }
    }
}

/// Builds initial values for `problem` (see the module doc). `known_points[j]`: point j's
/// coordinates in `problem` are known (control or approximate); `known_poses[i]`: image i's
/// pose in `problem` is known. Both may be empty (nothing known).
pub fn initialise(
    problem: &Problem,
    known_points: &[bool],
    known_poses: &[bool],
    options: &IncrementalOptions,
) -> Result<Initialised, InitError> {
    problem.validate()?;
    let known = flags(known_points, problem.points.len(), "known_points", "points")?;
    let known_pose = flags(known_poses, problem.images.len(), "known_poses", "images")?;
    let mut st = State::new(problem, &known, &known_pose);
    // Control available?
    let control_images = (0..problem.images.len())
        .filter(|&i| {
            st.poses[i].is_none() && st.determined_points_seen(i) >= options.min_resection_points
        })
        .count();
    // One given pose alone (the main station held fixed, as in the measurement file's
    // documented example) orients no point: the network starts from a relative orientation
    // and is moved, at the end, so that this image has its given pose.
    let anchor = match (control_images, known_pose.iter().filter(|k| **k).count()) {
        (0, 1) => known_pose.iter().position(|k| *k),
        _ => None,
    };
    let with_control = (options.resect_from_control && control_images > 0)
        || (st.oriented() > 0 && anchor.is_none());
    if with_control {
        st.resect_from_control(options)?;
    } else {
        // The control coordinates are in another frame than the relative orientation's.
        st.control_frame = false;
        st.points.iter_mut().for_each(|p| *p = None);
        st.poses.iter_mut().for_each(|p| *p = None);
        st.bootstrap(options)?;
    }
    st.intersect_points(options);
    if !with_control {
        st.scale_from_distances();
    }
    if options.bundle_between_steps {
        st.bundle(options);
    }
    let per_round = if with_control {
        usize::MAX
    } else {
        options.images_per_round.max(1)
    };
    st.grow(options, per_round);
    if !st.control_frame {
        st.move_to_control_frame();
        if st.control_frame && options.bundle_between_steps {
            st.bundle(options);
        }
    }
    if let (Some(i), false) = (anchor, st.control_frame) {
        st.move_to_given_pose(i);
    }
    Ok(st.into_initialised())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{CameraModel, PhotogrammetricCamera};
    use crate::initial::resection::tests::look_at;
    use crate::keys::CameraKey;
    use crate::problem::{Camera, Image, Observation, Point};
    use nalgebra::Vector2;
    use rand::Rng;
    use rand_distr::{Distribution, Normal};
    use std::sync::Arc;

    /// A 3D test field (a room corner: floor and two walls, mm) photographed from 12
    /// stations around it; truth and a problem with zero poses/points.
    fn network(seed: u64, noise_px: f64) -> (Problem, Problem, Vec<bool>) {
        network_with(seed, noise_px, [-0.01, 0.0], 60)
    }

    /// [`network`] with the radial distortion `k` = [K1, K2] (mm⁻², mm⁻⁴) of the truth (the
    /// problem starts from none) and `n_points` points.
    fn network_with(
        seed: u64,
        noise_px: f64,
        k: [f64; 2],
        n_points: usize,
    ) -> (Problem, Problem, Vec<bool>) {
        let mut rng = pingcal_geometry::consensus::rng(seed);
        let cam = PhotogrammetricCamera::new(1280, 720, 0.00375);
        let mut params = vec![0.0; 10];
        params[0] = 2.45;
        params[3] = k[0];
        params[4] = k[1];
        let mut truth = Problem::default();
        let mut c = Camera::new("left", Arc::new(cam), params.clone());
        c.fixed = vec![
            false, false, false, false, true, true, true, true, true, true,
        ];
        truth.cameras.push(c);
        for k in 0..n_points {
            let (a, b) = (rng.random_range(0.0..2000.0), rng.random_range(0.0..1500.0));
            let p = match k % 3 {
                0 => Vector3::new(a, b, 0.0),
                1 => Vector3::new(a, 0.0, b),
                _ => Vector3::new(0.0, a, b),
            };
            truth.points.push(Point {
                name: format!("T{k}"),
                position: p,
                fixed: false,
                fixed_axes: [false; 3],
            });
        }
        let target = Vector3::new(700.0, 700.0, 500.0);
        for i in 0..12 {
            let ang = 0.2 + 1.2 * i as f64 / 11.0;
            let r = 3200.0 + rng.random_range(-300.0..300.0);
            let centre = Vector3::new(
                r * ang.cos(),
                r * ang.sin(),
                1200.0 + rng.random_range(-300.0..300.0),
            );
            truth.images.push(Image {
                name: format!("S{i}"),
                camera: CameraKey(0),
                camera_from_object: look_at(centre, target, rng.random_range(-0.3..0.3)),
                fixed: false,
                fixed_centre: [false; 3],
            });
        }
        let n = Normal::new(0.0, noise_px).unwrap();
        for (i, im) in truth.images.iter().enumerate() {
            for (j, pt) in truth.points.iter().enumerate() {
                if let Some(uv) = cam.project(
                    &params,
                    &im.camera_from_object.transform(&pt.position),
                    None,
                    None,
                ) {
                    if uv.x > 0.0 && uv.y > 0.0 && uv.x < 1279.0 && uv.y < 719.0 {
                        truth.observations.push(Observation {
                            image: ImageKey(i),
                            point: PointKey(j),
                            uv: uv + Vector2::new(n.sample(&mut rng), n.sample(&mut rng)),
                            sigma: noise_px,
                        });
                    }
                }
            }
        }
        let mut p = truth.clone();
        p.cameras[0].params[0] = 2.5; // approximate c
        p.cameras[0].params[3] = 0.0;
        p.cameras[0].params[4] = 0.0;
        for im in &mut p.images {
            im.camera_from_object = Rigid3::identity();
        }
        let mut known = vec![false; n_points];
        for (j, pt) in p.points.iter_mut().enumerate() {
            if j < 6 {
                pt.fixed = true;
                known[j] = true;
            } else {
                pt.position = Vector3::zeros();
            }
        }
        (truth, p, known)
    }

    #[test]
    fn flags_of_another_length_are_refused() {
        let (p, _, known) = network(1, 0.3);
        let opts = IncrementalOptions::default();
        let (np, ni) = (p.points.len(), p.images.len());
        assert_eq!(
            initialise(&p, &known[..1], &[], &opts).unwrap_err(),
            InitError::BadInput(format!("known_points has 1 entries for {np} points"))
        );
        assert_eq!(
            initialise(&p, &known, &[true; 2], &opts).unwrap_err(),
            InitError::BadInput(format!("known_poses has 2 entries for {ni} images"))
        );
        assert_eq!(flags(&[], 3, "x", "y").unwrap(), vec![false; 3]);
        assert_eq!(
            flags(&[true, false], 2, "x", "y").unwrap(),
            vec![true, false]
        );
    }

    #[test]
    fn with_control_recovers_the_truth() {
        let (truth, p, known) = network(1, 0.1);
        let init = initialise(&p, &known, &[], &IncrementalOptions::default()).unwrap();
        assert!(
            init.unoriented_images.is_empty(),
            "{:?}",
            init.unoriented_images
        );
        assert!(
            init.undetermined_points.is_empty(),
            "{:?}",
            init.undetermined_points
        );
        let q = &init.problem;
        for (i, im) in truth.images.iter().enumerate() {
            let k = init.image_map[i].unwrap();
            assert!(
                (q.images[k].camera_from_object.centre() - im.camera_from_object.centre()).norm()
                    < 20.0
            );
        }
        for (j, pt) in truth.points.iter().enumerate() {
            let k = init.point_map[j].unwrap();
            assert!(
                (q.points[k].position - pt.position).norm() < 5.0,
                "{}",
                pt.name
            );
        }
        assert!(q.rms_px() < 0.2, "{}", q.rms_px());
        assert!((q.cameras[0].params[0] - 2.45).abs() < 0.01);
        assert!(init.steps.iter().any(|s| matches!(
            s,
            Step::Bundle {
                calibrating: true,
                ..
            }
        )));
    }

    /// `p` with no control point and two measured distances (scale bars) between points 0–1
    /// and 2–3 of `truth`.
    fn without_control(truth: &Problem, p: &Problem) -> Problem {
        let mut p2 = p.clone();
        for pt in &mut p2.points {
            pt.fixed = false;
        }
        for (a, b) in [(0, 1), (2, 3)] {
            p2.distances.push(Distance {
                a: PointKey(a),
                b: PointKey(b),
                value: (truth.points[a].position - truth.points[b].position).norm(),
                sigma: 0.05,
            });
        }
        p2
    }

    #[test]
    fn without_control_builds_a_network_scaled_by_its_distances() {
        let (truth, p, _) = network(2, 0.1);
        let p2 = without_control(&truth, &p);
        let init = initialise(&p2, &[], &[], &IncrementalOptions::default()).unwrap();
        assert!(
            matches!(init.steps[0], Step::RelativePair { .. }),
            "{:?}",
            init.steps
        );
        assert!(init
            .steps
            .iter()
            .any(|s| matches!(s, Step::ScaledByDistances { distances: 2, .. })));
        assert!(
            init.unoriented_images.is_empty(),
            "{:?}",
            init.unoriented_images
        );
        assert!(init.undetermined_points.is_empty());
        assert!(init.in_control_frame);
        assert_eq!(init.problem.distances.len(), 2);
        assert!(init.problem.rms_px() < 0.2, "{}", init.problem.rms_px());
        // Shape and scale: distances from point 0 agree with the truth (mm).
        let q = &init.problem;
        let j0 = init.point_map[0].unwrap();
        for j in 1..60 {
            let k = init.point_map[j].unwrap();
            let e = (truth.points[j].position - truth.points[0].position).norm()
                - (q.points[k].position - q.points[j0].position).norm();
            assert!(e.abs() < 5.0, "point {j}: {e} mm");
        }
    }

    /// The simulated field's barrel distortion (K1 −0.021, K2 0.0004: −14 % at the image's
    /// corners) against nominal intrinsics without distortion, no control and 14 targets (as
    /// few as the coded targets two images of the simulated mono field share): the start must
    /// still orient every image (issue 19, mono; without the radial search every pair had
    /// 10 or 11 of its 14 points within the epipolar threshold). When no pair can start, the
    /// error says what would.
    #[test]
    fn a_strongly_distorted_network_starts_from_nominal_intrinsics() {
        for seed in 1..=10 {
            let (truth, p, _) = network_with(seed, 0.1, [-0.021, 0.0004], 14);
            let p2 = without_control(&truth, &p);
            let init = initialise(&p2, &[], &[], &IncrementalOptions::default())
                .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            assert!(
                init.unoriented_images.is_empty(),
                "seed {seed}: {:?}",
                init.unoriented_images
            );
            assert!(
                init.problem.rms_px() < 0.2,
                "seed {seed}: {}",
                init.problem.rms_px()
            );
        }
        let (_, p, _) = network_with(1, 0.1, [-0.021, 0.0004], 14);
        let mut opts = IncrementalOptions::default();
        opts.relative.min_inliers = 15;
        let err = initialise(&p, &[], &[], &opts).unwrap_err().to_string();
        for part in [
            "none of the 6 image pairs",
            "15 or more",
            "up to 25 %",
            "control points",
        ] {
            assert!(err.contains(part), "{err}");
        }
    }

    #[test]
    fn three_control_points_bring_a_relative_network_into_their_frame() {
        let (truth, mut p, _) = network(4, 0.1);
        // Three control points: too few to resect, enough for a similarity at the end.
        let known: Vec<bool> = (0..p.points.len()).map(|j| j < 3).collect();
        for (pt, k) in p.points.iter_mut().zip(&known) {
            pt.fixed = *k;
        }
        let init = initialise(&p, &known, &[], &IncrementalOptions::default()).unwrap();
        assert!(
            init.steps
                .iter()
                .any(|s| matches!(s, Step::ToControlFrame { points: 3, .. })),
            "{:?}",
            init.steps
        );
        let q = &init.problem;
        for (i, im) in truth.images.iter().enumerate() {
            let k = init.image_map[i].unwrap();
            assert!(
                (q.images[k].camera_from_object.centre() - im.camera_from_object.centre()).norm()
                    < 50.0,
                "image {i}"
            );
        }
        for j in 0..3 {
            let k = init.point_map[j].unwrap();
            assert_eq!(q.points[k].position, truth.points[j].position);
            assert!(q.points[k].fixed);
        }
    }

    /// In the control frame a held single coordinate keeps its given value: Z of a point
    /// that is otherwise intersected and X of an image's centre that is otherwise resected
    /// are not replaced by the estimates, and stay held.
    #[test]
    fn held_single_coordinates_keep_their_given_values() {
        let (truth, mut p, known) = network(2, 0.1);
        let z = truth.points[10].position.z;
        p.points[10].position.z = z;
        p.points[10].fixed_axes = [false, false, true];
        let c = truth.images[2].camera_from_object.centre();
        p.images[2].camera_from_object =
            Rigid3::from_rotation_and_centre(nalgebra::Matrix3::identity(), c);
        p.images[2].fixed_centre = [true, false, false];
        let init = initialise(&p, &known, &[], &IncrementalOptions::default()).unwrap();
        assert!(init.in_control_frame);
        let q = &init.problem;
        let pt = &q.points[init.point_map[10].unwrap()];
        assert_eq!(pt.position.z.to_bits(), z.to_bits());
        assert_eq!(pt.fixed_axes, [false, false, true]);
        assert!((pt.position - truth.points[10].position).norm() < 20.0);
        let im = &q.images[init.image_map[2].unwrap()];
        assert!((im.camera_from_object.centre().x - c.x).abs() < 1e-9);
        assert_eq!(im.fixed_centre, [true, false, false]);
        assert!((im.camera_from_object.centre() - c).norm() < 20.0);
    }

    #[test]
    fn gross_errors_are_rejected_and_reported() {
        let (truth, mut p, known) = network(5, 0.1);
        let mut bad = Vec::new();
        for k in (0..p.observations.len()).step_by(37) {
            p.observations[k].uv += Vector2::new(25.0, -18.0);
            bad.push((
                p.images[p.observations[k].image].name.clone(),
                p.points[p.observations[k].point].name.clone(),
            ));
        }
        let init = initialise(&p, &known, &[], &IncrementalOptions::default()).unwrap();
        let rejected: Vec<(String, String)> = init
            .rejected_observations
            .iter()
            .map(|(i, pt, _)| (i.clone(), pt.clone()))
            .collect();
        assert_eq!(rejected, bad, "{:?}", init.steps);
        assert_eq!(
            init.problem.observations.len(),
            p.observations.len() - bad.len()
        );
        assert!(init.problem.rms_px() < 0.2, "{}", init.problem.rms_px());
        assert!(init.unoriented_images.is_empty());
        for (j, pt) in truth.points.iter().enumerate() {
            if let Some(k) = init.point_map[j] {
                assert!((init.problem.points[k].position - pt.position).norm() < 5.0);
            }
        }
    }

    #[test]
    fn a_network_in_two_pieces_orients_one_and_names_the_other() {
        let (_, a, _) = network(6, 0.1);
        let (_, b, _) = network(7, 0.1);
        // Two copies side by side sharing no point, no control at all.
        let mut p = a.clone();
        let (ni, np) = (a.images.len(), a.points.len());
        for im in &b.images {
            let mut im = im.clone();
            im.name = format!("B-{}", im.name);
            p.images.push(im);
        }
        for pt in &b.points {
            let mut pt = pt.clone();
            pt.name = format!("B-{}", pt.name);
            pt.fixed = false;
            p.points.push(pt);
        }
        for pt in p.points.iter_mut() {
            pt.fixed = false;
        }
        for o in &b.observations {
            let mut o = *o;
            o.image.0 += ni;
            o.point.0 += np;
            p.observations.push(o);
        }
        let init = initialise(&p, &[], &[], &IncrementalOptions::default()).unwrap();
        assert_eq!(
            init.unoriented_images.len(),
            12,
            "{:?}",
            init.unoriented_images
        );
        let names: Vec<&str> = init
            .unoriented_images
            .iter()
            .map(|(n, _)| n.as_str())
            .collect();
        let piece_b = names.iter().all(|n| n.starts_with("B-"));
        let piece_a = names.iter().all(|n| !n.starts_with("B-"));
        assert!(piece_a || piece_b, "{names:?}");
        assert!(init
            .unoriented_images
            .iter()
            .all(|(_, why)| why.contains("sees 0")));
        assert_eq!(init.undetermined_points.len(), 60);
        assert!(init.problem.validate().is_ok());
        assert!(init.problem.rms_px() < 0.2);
    }

    #[test]
    fn a_disconnected_image_is_reported_not_nan() {
        let (_, mut p, known) = network(3, 0.1);
        // An extra image that sees only two points of its own.
        p.images.push(Image {
            name: "lonely".into(),
            camera: CameraKey(0),
            camera_from_object: Rigid3::identity(),
            fixed: false,
            fixed_centre: [false; 3],
        });
        for k in 0..2 {
            p.points.push(Point {
                name: format!("L{k}"),
                position: Vector3::zeros(),
                fixed: false,
                fixed_axes: [false; 3],
            });
            p.observations.push(Observation {
                image: ImageKey(12),
                point: PointKey(60 + k),
                uv: Vector2::new(100.0 + 50.0 * k as f64, 100.0),
                sigma: 0.1,
            });
        }
        let mut known = known;
        known.extend([false, false]);
        let init = initialise(&p, &known, &[], &IncrementalOptions::default()).unwrap();
        assert_eq!(init.unoriented_images.len(), 1);
        assert_eq!(init.unoriented_images[0].0, "lonely");
        assert!(
            init.unoriented_images[0].1.contains("sees 0"),
            "{:?}",
            init.unoriented_images
        );
        assert_eq!(init.undetermined_points.len(), 2);
        assert!(init.image_map[12].is_none());
        let q = &init.problem;
        assert!(q
            .points
            .iter()
            .all(|p| p.position.iter().all(|v| v.is_finite())));
        assert!(q.validate().is_ok());
    }

    #[test]
    fn the_intersection_angle_option_decides_which_points_are_refused_and_names_them() {
        let (truth, mut p, mut known) = network(1, 0.1);
        // A point seen only by two neighbouring stations: its rays meet at a few degrees.
        let x = Vector3::new(700.0, 700.0, 500.0);
        let j = p.points.len();
        p.points.push(Point {
            name: "narrow".into(),
            position: Vector3::zeros(),
            fixed: false,
            fixed_axes: [false; 3],
        });
        known.push(false);
        let cam = &truth.cameras[0];
        for i in [5, 6] {
            let pose = truth.images[i].camera_from_object;
            let uv = cam
                .model
                .project(&cam.params, &pose.transform(&x), None, None)
                .unwrap();
            p.observations.push(Observation {
                image: ImageKey(i),
                point: PointKey(j),
                uv,
                sigma: 0.1,
            });
        }
        let c5 = truth.images[5].camera_from_object.centre();
        let c6 = truth.images[6].camera_from_object.centre();
        let angle = (c5 - x).angle(&(c6 - x)).to_degrees();
        assert!(angle > 2.0 && angle < 10.0, "{angle}");

        let default = initialise(&p, &known, &[], &IncrementalOptions::default()).unwrap();
        assert!(
            default.refused_by_angle.is_empty(),
            "{:?}",
            default.refused_by_angle
        );
        assert!(default.point_map[j].is_some());

        let strict = IncrementalOptions {
            intersection: IntersectionOptions {
                min_angle_deg: 10.0,
                ..IntersectionOptions::default()
            },
            ..IncrementalOptions::default()
        };
        let init = initialise(&p, &known, &[], &strict).unwrap();
        assert!(init.point_map[j].is_none());
        let narrow: Vec<&(String, f64)> = init
            .refused_by_angle
            .iter()
            .filter(|(n, _)| n == "narrow")
            .collect();
        assert_eq!(narrow.len(), 1, "{:?}", init.refused_by_angle);
        assert!(
            (narrow[0].1 - angle).abs() < 0.5,
            "{} vs {angle}",
            narrow[0].1
        );
        // Every refused point is undetermined, with its angle under the threshold.
        for (name, a) in &init.refused_by_angle {
            assert!(*a < 10.0, "{name}: {a}");
            assert!(init.undetermined_points.iter().any(|(n, _)| n == name));
        }
    }
}
