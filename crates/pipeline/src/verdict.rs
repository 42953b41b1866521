//! Step 7a: the verdict. A calibration is a measurement, so it says whether to trust it:
//! `ok`, `doubtful` (with the reasons) or `failed`.
//!
//! Each test compares a statistic with the bound it would exceed with probability
//! α = [`ALPHA`] if the models held (the image noise, the LRF's noise profile, the rigid
//! transform between the frames, the σ's of both sides):
//!
//! | test | statistic | bound |
//! |---|---|---|
//! | bundle | σ0 of the final adjustment (redundancy r) | `√(χ²₁₋α(r) / r)` |
//! | registration | σ0 of the 3D conformal transform (redundancy 3n − 6) | `√(χ²₁₋α(dof) / dof)` × [`CENTRE_SIGMA_OPTIMISM`] |
//! | check points | `Σ dᵢᵀ Σᵢ⁻¹ dᵢ / 3k` over the k check (or leave-one-out) balls, `dᵢ` = estimated − reference, `Σᵢ` = camera-side covariance + the LRF-side one turned into the camera frame + the transform's own, propagated | `χ²₁₋α(3k) / 3k` × [`CENTRE_SIGMA_OPTIMISM`]² |
//! | sphere fits | the pooled σ0 of the sphere fits, `√(Σ σ0ᵢ² fᵢ / Σ fᵢ)` (fᵢ = inliers − 3) | `max(√(χ²₁₋α(Σf) / Σf), `[`SPHERE_PROFILE_TOLERANCE`]`)` |
//! | joint | σ0 of the joint adjustment (image points, distances, beams), and its check balls' `χ²/3k` as above | `√(χ²₁₋α(r) / r)` (no optimism factor: the beams' σ's are the sensor's), `χ²₁₋α(3k) / 3k` × [`CENTRE_SIGMA_OPTIMISM`]² (a check ball's LRF side is a sphere fit, refitted with the estimated mount, with the sphere centres' known optimism) |
//! | correlations | the largest \|ρ\| between two self-calibrated intrinsics | [`MAX_CORRELATION`] |
//!
//! Only the upper side is tested: a σ0 under 1 says the a-priori σ's are pessimistic, which
//! makes the reported σ's safe, not doubtful. When the joint adjustment succeeded, its
//! result is the one given, and the two-step registration's tests (their names start
//! `two-step`) become notes: they then say that the LRF has mount or range errors the
//! project does not give, which the joint adjustment estimated. Besides the tests, a check ball the project
//! names that no sphere was matched to, and a sphere in the cloud that matches no ball, make
//! the verdict doubtful, and so does an adjusted stereo baseline more than
//! [`BASELINE_TOLERANCE`] from the project's `baseline_mm`. The verdict is `failed` when the paper's sphere method gave no
//! extrinsic (only the corner baseline did).
//!
//! χ² quantiles by the Wilson–Hilferty approximation,
//! `χ²ₚ(k) ≈ k (1 − 2/(9k) + zₚ √(2/(9k)))³` with zₚ the standard normal quantile: within
//! 0.5 % of the exact value for k ≥ 3 at p = 0.99 (checked in the tests against tabulated
//! values).

use super::bundle::Adjusted;
use super::extrinsic;
use super::joint::JointOutcome;
use crate::stages::Stages;
use nalgebra::{DMatrix, Matrix3, Vector3};
use pingcal_ba::camera::{LensClass, ModelKind};
use pingcal_ba::solver::IntrinsicsPrecision;
use pingcal_geometry::{skew, Sim3};
use pingcal_lrf::registration::{CheckRow, Evaluation, PointObs};
use pingcal_project::Project;
use serde::Serialize;

/// The level of every test: the probability that it flags a calibration whose models hold.
pub const ALPHA: f64 = 0.01;
/// z of the standard normal at 1 − [`ALPHA`].
const Z_1_MINUS_ALPHA: f64 = 2.326_347_874_040_841;
/// How optimistic the sphere centres' σ's are known to be: over simulator seeds 1–40 the
/// RMS of (true error / reported σ) of the sphere method's extrinsic is 1.14 (docs/accuracy.md,
/// "On the paper-matched simulation"; mixed pixels at a ball's rim). The
/// This many LRF candidates seen twice (see `pingcal_lrf::ball_finder::Rejected::seen_twice`)
/// make the verdict doubtful: one may be a ball beside its own reflection or two balls
/// touching, several are a cloud whose sweeps do not agree.
const SEEN_TWICE_MIN: usize = 2;

/// registration's σ0 is judged against its χ² bound widened by this factor (and the check
/// points' χ²/n, a squared statistic, by its square), so that a known
/// and documented optimism is not reported as a fault of every calibration.
pub const CENTRE_SIGMA_OPTIMISM: f64 = 1.15;
/// The sphere fits' pooled σ0 up to which the LRF's noise profile is taken as right. With
/// thousands of beams on the balls the χ² bound alone is 1.03, and a real (or simulated)
/// scanner's mixed pixels and footprint put the pooled σ0 at 1.0–1.05 with the right
/// profile: a profile 20 % optimistic is what matters to the sphere centres' σ, whose effect
/// the registration's own σ0 test then shows.
pub const SPHERE_PROFILE_TOLERANCE: f64 = 1.2;
/// Relative difference between the adjusted stereo baseline and the project's
/// `baseline_mm` beyond which one of them is wrong (a tape measure is good to a few mm in
/// 120; a unit or scale mistake is off by far more).
pub const BASELINE_TOLERANCE: f64 = 0.05;
/// A correlation between two intrinsics beyond which they are not separated by the data.
pub const MAX_CORRELATION: f64 = 0.999;

/// `ok`, `doubtful` or `failed`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Every test passed.
    Ok,
    /// A test failed or something was not as it should be: read the reasons.
    Doubtful,
    /// The paper's method gave no extrinsic.
    Failed,
}

impl Status {
    /// `ok`, `doubtful`, `failed`.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Doubtful => "doubtful",
            Status::Failed => "failed",
        }
    }
}

/// One statistical test.
#[derive(Clone, Debug, Serialize)]
pub struct Check {
    /// What is tested.
    pub name: String,
    /// The statistic.
    pub value: f64,
    /// Its bound at level [`ALPHA`].
    pub bound: f64,
    /// `value ≤ bound`.
    pub passed: bool,
}

/// The verdict on one calibration.
#[derive(Clone, Debug, Serialize)]
pub struct Verdict {
    /// The outcome.
    pub status: Status,
    /// Why it is not `ok`, one sentence each.
    pub reasons: Vec<String>,
    /// What the tests of the two-step method found when its result is not the one given
    /// (the joint adjustment succeeded): they do not change the status.
    pub notes: Vec<String>,
    /// The tests with their values and bounds.
    pub checks: Vec<Check>,
    /// The level of the tests.
    pub alpha: f64,
}

pub use pingcal_geometry::stats::chi2_quantile;

/// The `1 − ALPHA` quantile of χ² with `k` degrees of freedom.
pub fn chi2_upper(k: f64) -> f64 {
    chi2_quantile(k, Z_1_MINUS_ALPHA)
}

/// The bound of a σ0 with `dof` degrees of freedom at level [`ALPHA`]: `√(χ²₁₋α(dof) / dof)`.
pub(crate) fn sigma0_bound(dof: f64) -> f64 {
    (chi2_upper(dof) / dof).sqrt()
}

/// The widest diagonal field of view (undistorted, 2·atan(half-diagonal / focal length))
/// for which a perspective model with polynomial distortion is taken to hold; beyond it, and
/// with a failing σ0, the lens is named as the likely cause (a 120° wide-angle lens of the
/// simulator sees about 100° undistorted, its 190° fisheye about 126°).
pub const PERSPECTIVE_FOV_DEG: f64 = 115.0;

/// A camera whose model cannot hold its lens, in words with the models to try: the first
/// camera of the bundle's final problem whose image residuals grow toward the edge along the
/// radius while the bundle's σ0 fails its χ² test
/// ([`pingcal_ba::diagnostics::RadialProfile::grows_radially`]), or whose gross errors
/// gather toward the edge ([`pingcal_ba::diagnostics::RadialProfile::rejections_grow`]);
/// five rings of the image's half-diagonal. A perspective model whose σ0 fails on a lens
/// wider than `PERSPECTIVE_FOV_DEG` is named first.
pub fn lens_doubt(project: &Project, adjusted: &Adjusted) -> Option<String> {
    let dof = adjusted.precision.redundancy as f64;
    let sigma0_fails = dof > 0.0 && adjusted.sigma0_a_priori > sigma0_bound(dof);
    let f = &project.file;
    let problem = &adjusted.solved.problem;
    f.cameras.iter().enumerate().find_map(|(k, c)| {
        let rejected: Vec<nalgebra::Vector2<f64>> = (adjusted.rejected.iter())
            .filter(|r| f.images.iter().any(|im| im.file == r.image && im.camera == c.id))
            .map(|r| nalgebra::Vector2::from(r.uv))
            .collect();
        let profile = pingcal_ba::diagnostics::radial_profile(
            problem,
            pingcal_ba::CameraKey(k),
            (c.width, c.height),
            5,
            &rejected,
        );
        let cam = &problem.cameras[k];
        let fov_deg = 2.0
            * (0.5 * f64::from(c.width).hypot(f64::from(c.height))
                / cam.model.focal_px(&cam.params))
            .atan()
            .to_degrees();
        let perspective = c.model.perspective();
        let what = match (profile.grows_radially(), profile.rejections_grow()) {
            _ if sigma0_fails && perspective && fov_deg > PERSPECTIVE_FOV_DEG => format!(
                "the adjustment fails (σ0 {:.1}) and the lens sees {fov_deg:.0}° across the image's diagonal even before its distortion, beyond the {PERSPECTIVE_FOV_DEG:.0}° a perspective model with polynomial distortion holds",
                adjusted.sigma0_a_priori
            ),
            (Some((inner, outer)), _) if sigma0_fails => format!(
                "the image residuals grow toward the edge along the radius (RMS {:.3} px within {:.0} % of the image's half-diagonal, {:.3} px beyond {:.0} %, across the radius {:.3} px there)",
                inner.radial_px,
                100.0 * inner.to,
                outer.radial_px,
                100.0 * outer.from,
                outer.tangential_px
            ),
            (_, Some((inner, outer))) => format!(
                "data snooping removed {} of the {} image points beyond {:.0} % of the image's half-diagonal and {} of the {} within {:.0} %",
                outer.rejected,
                outer.n + outer.rejected,
                100.0 * outer.from,
                inner.rejected,
                inner.n + inner.rejected,
                100.0 * inner.to
            ),
            _ => return None,
        };
        // the fisheye models, then the wide-angle ones
        let others: Vec<String> = [LensClass::Fisheye, LensClass::WideAngle]
            .iter()
            .flat_map(|l| ModelKind::ALL.into_iter().filter(move |m| m.lens() == *l))
            .filter(|m| *m != c.model)
            .map(|m| format!("\"{m}\""))
            .collect();
        Some(format!(
            "camera '{}': {what}: the lens bends more than model '{}' can hold; give the camera the model of its lens ([[cameras]] model = {}: a fisheye, the first two; a wide-angle lens, the last)",
            c.id,
            c.model,
            others.join(", ")
        ))
    })
}

/// The bound of the check balls' `χ²/n` (n = 3k coordinates) at level [`ALPHA`], widened by
/// the sphere centres' documented optimism: a check ball's LRF side is a sphere fit.
pub(crate) fn check_points_bound(n: f64) -> f64 {
    chi2_upper(n) / n * CENTRE_SIGMA_OPTIMISM * CENTRE_SIGMA_OPTIMISM
}

/// The prefix of the two-step method's test names: when the joint adjustment's result is
/// the one given, their failures are notes (see the module doc).
const TWO_STEP: &str = "two-step";

/// The start of a fixed LRF's note that an extrinsic component was held (the data do not
/// determine it).
pub const HELD_EXTRINSIC: &str = "held: the extrinsic's";

/// Judges the calibration of `st`.
pub fn judge(st: &Stages) -> Verdict {
    let (mut checks, mut reasons, mut notes) = (Vec::new(), Vec::new(), Vec::new());
    // The result given is the joint adjustment's when it succeeded: the two-step method's
    // registration tests then say something about the LRF's model, not about that result.
    let joint_given = matches!(st.joint, Some(Ok(_)));
    statistical_tests(st, &mut |name, value, bound, why| {
        let passed = value <= bound;
        let secondary = joint_given && name.starts_with(TWO_STEP);
        if !passed && secondary {
            notes.push(format!("{} (the two-step method; the joint adjustment's result is the one given, and it estimates the LRF's mount and range errors)", why(value, bound)));
        } else if !passed {
            reasons.push(why(value, bound));
        }
        checks.push(Check {
            name: name.into(),
            value,
            bound,
            passed,
        });
    });
    let (unmatched_reasons, unmatched_notes) = unmatched(st);
    reasons.extend(unmatched_reasons);
    notes.extend(unmatched_notes);
    if let Some(d) = &st.adjusted.lens_doubt {
        reasons.insert(0, d.clone());
    }
    // a distance given wrong (a typo), found and left out by data snooping
    reasons.extend((st.adjusted.rejected_distances.iter()).map(|d| d.warning()));
    let kept_twice = match st.joint {
        Some(Ok(j)) => j.lrf_view.seen_twice_kept,
        _ => st.lrf.found.seen_twice_kept(),
    };
    if kept_twice >= SEEN_TWICE_MIN {
        let why = format!("{kept_twice} LRF sphere(s) were seen twice (as many beams pass through each as meet it): the cloud's mount model is off, which the joint adjustment estimates");
        if matches!(st.joint, Some(Ok(_))) {
            notes.push(why);
        } else {
            reasons.push(why);
        }
    }
    reasons.extend(misplaced_images(st));
    reasons.extend(head_cameras_left_out(st));
    let failed = joint_verdict(st, &mut reasons, &mut notes);
    let fixed = st.project.file.lrf.kind() == pingcal_project::LrfKind::Fixed;
    let status = if st.ext.spheres.is_none() && !(fixed && joint_given) {
        reasons.insert(
            0,
            "the sphere method gave no extrinsic (only the corner baseline did)".into(),
        );
        Status::Failed
    } else if failed {
        Status::Failed
    } else if reasons.is_empty() {
        Status::Ok
    } else {
        Status::Doubtful
    };
    Verdict {
        status,
        reasons,
        notes,
        checks,
        alpha: ALPHA,
    }
}

/// The joint adjustment's part of the verdict: its failure (the calibration's failure when
/// it did not converge), its doubts about convergence, a fixed LRF's extrinsic components
/// the data do not determine (held at the start: not a calibration in them); whether the
/// calibration failed.
fn joint_verdict(st: &Stages, reasons: &mut Vec<String>, notes: &mut Vec<String>) -> bool {
    let mut failed = false;
    match st.joint {
        Some(Err(e)) if e.not_converged => {
            failed = true;
            reasons.insert(0, format!("{e}; results.json's extrinsic is the two-step method's, given as the fallback, not as a calibration"));
        }
        Some(Err(e)) => reasons.push(format!(
            "the joint adjustment failed ({e}): the two-step result is given"
        )),
        Some(Ok(j)) => {
            reasons.extend(j.convergence.doubt());
            reasons.extend(held_costs(j));
            notes.extend(j.hold_mount.clone());
            // a fixed LRF's extrinsic component that the data do not determine is held at
            // its start: the extrinsic is then not a calibration in that component
            reasons.extend(
                (j.notes.iter())
                    .filter(|n| n.starts_with(HELD_EXTRINSIC))
                    .cloned(),
            );
        }
        None => {}
    }
    failed
}

/// A held mount parameter costs more than the extrinsic's σ's show when, were its held
/// value off by its plausible size, some component of the extrinsic would move by more than
/// this many of its σ.
pub const HELD_SHIFT_SIGMAS: f64 = 3.0;

/// The mount parameters the joint adjustment held for want of data whose plausible error
/// would move a component of the extrinsic beyond [`HELD_SHIFT_SIGMAS`] of its σ: one reason
/// each.
fn held_costs(j: &JointOutcome) -> Vec<String> {
    let sd = |i: usize| {
        j.extrinsic_cov[(i, i)]
            .max(0.0)
            .sqrt()
            .max(f64::MIN_POSITIVE)
    };
    (j.held_shifts.iter().enumerate())
        .filter_map(|(k, s)| s.map(|s| (k, s)))
        .filter_map(|(k, s)| {
            let times = (0..6).map(|i| s[i].abs() / sd(i)).fold(0.0f64, f64::max);
            let [t, r] = crate::joint::largest_shift(s);
            (times > HELD_SHIFT_SIGMAS).then(|| {
                format!(
                    "{} is held for want of data, and were it off by its plausible size the extrinsic would move by up to {t:.1} mm and {r:.2}°, {times:.0}× its σ: the σ's do not hold that error (record a sweep that determines it: a full turn of the servo sees every ball from both sides)",
                    pingcal_lrf::sensor::MOUNT_PARAM_NAMES[k]
                )
            })
        })
        .collect()
}

/// An image is not where the project puts it when at least this many of its coded readings,
/// and more than [`MISPLACED_SHARE`] of them, are where the network puts other targets
/// (named blunders): its whole picture disagrees, not a reading here and there.
pub const MIN_MISPLACED: usize = 4;
/// See [`MIN_MISPLACED`].
pub const MISPLACED_SHARE: f64 = 0.5;

/// The head's cameras (`[stereo]`'s other one, `[rig]`'s) that no rig of the adjustment
/// holds — none of their images could be oriented, nor placed through the rig: their pose
/// to the main camera is not a result, and `sensors` leaves them out. One reason each.
fn head_cameras_left_out(st: &Stages) -> Vec<String> {
    (crate::adjust::head_cameras(st.project).iter())
        .filter(|h| st.adjusted.rig_of(h.camera, st.project).is_none())
        .map(|h| {
            let images = (st.project.file.images.iter())
                .filter(|im| im.camera == h.camera)
                .count();
            format!(
                "camera '{}' of the head: none of its {images} images is in the adjustment with its station's '{}' image (bundle.unoriented_images says why): its pose to the main camera is not estimated and results.json's sensors leave it out",
                h.camera, h.base
            )
        })
        .collect()
}

/// The images whose coded targets the network mostly puts elsewhere (the demo with one
/// station's left and right images swapped: every coded reading of one of them a blunder,
/// the verdict ok and σ0 0.687 against 0.661 before this said so): one reason each.
fn misplaced_images(st: &Stages) -> Vec<String> {
    let f = &st.project.file;
    (0..f.images.len())
        .filter_map(|i| {
            let image = crate::ids::ImageId(i);
            let coded = (st.dets[image].targets.iter())
                .filter(|t| t.id.is_some())
                .count();
            let off = (st.scene.blunders.iter())
                .filter(|b| b.det.image == image)
                .count();
            (off >= MIN_MISPLACED && off as f64 > MISPLACED_SHARE * coded as f64).then(|| {
                let im = &f.images[i];
                format!(
                    "station {}: {} ({}): {off} of its {coded} coded targets are read where the network puts other targets: the image is not where the project puts it (the station's images swapped, or the camera moved between stations)",
                    im.station, im.file, im.camera
                )
            })
        })
        .collect()
}

type Test<'a> = dyn FnMut(&str, f64, f64, &dyn Fn(f64, f64) -> String) + 'a;

/// Every statistical test, each reported through `test(name, value, bound, why)`.
fn statistical_tests(st: &Stages, test: &mut Test) {
    let p = &st.adjusted.precision;
    if p.redundancy > 0 {
        let r = p.redundancy as f64;
        // the a-priori σ's are what is judged, not the re-weighted ones (their σ0 is 1)
        test(
            "bundle sigma0",
            st.adjusted.sigma0_a_priori,
            sigma0_bound(r),
            &|v, b| {
                format!("the bundle adjustment's σ0 {v:.3} exceeds {b:.3}: the image points are worse than their σ's say (blur, wrong detections, or a camera model that does not fit)")
            },
        );
    }
    if let Some(ev) = &st.ext.spheres {
        registration_tests(ev, st, test);
    }
    if let Some(Ok(j)) = st.joint {
        joint_tests(j, test);
    }
    sphere_fit_test(st, test);
    correlation_test(st, test);
}

/// σ0 of the registration and the check points against their predicted covariances.
fn registration_tests(ev: &Evaluation, st: &Stages, test: &mut Test) {
    let reg = &ev.registration;
    if reg.dof > 0 {
        let f = reg.dof as f64;
        test(
            &format!("{TWO_STEP} registration sigma0"),
            reg.sigma0,
            sigma0_bound(f) * CENTRE_SIGMA_OPTIMISM,
            &|v, b| {
                format!("the registration's σ0 {v:.2} exceeds {b:.2}: the sphere centres do not fit a rigid transform of the balls within their σ's (an LRF mount or range error, or a wrong noise profile)")
            },
        );
    }
    let (rows, what) = if ev.check.rows.is_empty() {
        (&ev.leave_one_out.rows, "leave-one-out")
    } else {
        (&ev.check.rows, "check")
    };
    let chi2 = mean_check_chi2(
        rows,
        (&st.ext.lrf_points, &st.ext.cam_points),
        &reg.camera_from_lrf,
        &reg.cov,
    );
    if let Some((mean, n)) = chi2 {
        test(
            &format!("{TWO_STEP} {what} points"),
            mean,
            check_points_bound(n),
            &|v, b| {
                format!("the {what} balls' errors are {:.1}× their predicted σ (χ²/n = {v:.2} > {b:.2}): the extrinsic is worse than its σ's say", v.sqrt())
            },
        );
    }
}

/// σ0 of the joint adjustment and its check points against their predicted covariances
/// (the camera side's, the refitted sphere's turned into the camera frame, and the
/// extrinsic's propagated: `∂/∂δθ = −[R p]×`, `∂/∂t = I`).
fn joint_tests(j: &JointOutcome, test: &mut Test) {
    if j.redundancy > 0 {
        let r = j.redundancy as f64;
        test("joint sigma0", j.sigma0, sigma0_bound(r), &|v, b| {
            format!("the joint adjustment's σ0 {v:.3} exceeds {b:.3}: the image points or the LRF beams are worse than their σ's say (a mount error the model lacks, or a wrong noise profile)")
        });
    }
    let t = &j.camera_from_lrf;
    let chi2 = mean_check_chi2(
        &j.check.rows,
        (&j.lrf_points, &j.cam_points),
        &Sim3::new(1.0, t.rotation, t.translation),
        &j.extrinsic_cov,
    );
    if let Some((mean, n)) = chi2 {
        test(
            "joint check points",
            mean,
            check_points_bound(n),
            &|v, b| {
                format!("the joint adjustment's check balls are {:.1}× their predicted σ (χ²/n = {v:.2} > {b:.2}): its extrinsic is worse than its σ's say", v.sqrt())
            },
        );
    }
}

fn find<'a>(pts: &'a [PointObs], id: &str) -> Option<&'a PointObs> {
    pts.iter().find(|p| p.id == id)
}

/// `Σ dᵢᵀ Σᵢ⁻¹ dᵢ / 3k` over the `k` rows whose ball is in both point lists (and whose
/// predicted covariance inverts), with `3k`; None when no row counts.
pub(crate) fn mean_check_chi2(
    rows: &[CheckRow],
    (lrf, cam): (&[PointObs], &[PointObs]),
    t: &Sim3,
    tcov: &DMatrix<f64>,
) -> Option<(f64, f64)> {
    let (mut sum, mut k) = (0.0, 0usize);
    for row in rows {
        let (Some(l), Some(c)) = (find(lrf, &row.id), find(cam, &row.id)) else {
            continue;
        };
        let d = Vector3::new(row.dx_mm, row.dy_mm, row.dz_mm);
        if let Some(m) = predicted_covariance(t, tcov, l, c)
            .try_inverse()
            .map(|inv| d.dot(&(inv * d)))
            .filter(|m| m.is_finite())
        {
            sum += m;
            k += 1;
        }
    }
    let n = 3.0 * k as f64;
    (k > 0).then(|| (sum / n, n))
}

/// The check error to expect from the covariances the calibration reports: for each check
/// (or leave-one-out) ball of the result given (the joint adjustment's when it succeeded,
/// else the sphere method's), `E|dᵢ|` of a zero-mean normal `dᵢ` with the covariance `Σᵢ`
/// of the check-point test (`mean_check_chi2`), to second order `√T (1 − tr Σᵢ² / 4T²)`, `T = tr Σᵢ`
/// (exact to 0.5 % for an isotropic Σᵢ), averaged over the balls; None without a check
/// ball in both point lists. What `pingcal plan` predicts the mean check error to be.
pub fn expected_check_error_mm(st: &Stages) -> Option<f64> {
    let (rows, pts, t, tcov) = match st.joint {
        Some(Ok(j)) => (
            &j.check.rows,
            (&j.lrf_points[..], &j.cam_points[..]),
            Sim3::new(
                1.0,
                j.camera_from_lrf.rotation,
                j.camera_from_lrf.translation,
            ),
            &j.extrinsic_cov,
        ),
        _ => {
            let ev = st.ext.spheres.as_ref()?;
            let rows = if ev.check.rows.is_empty() {
                &ev.leave_one_out.rows
            } else {
                &ev.check.rows
            };
            (
                rows,
                (&st.ext.lrf_points[..], &st.ext.cam_points[..]),
                ev.registration.camera_from_lrf,
                &ev.registration.cov,
            )
        }
    };
    let expected: Vec<f64> = rows
        .iter()
        .filter_map(|row| {
            let (l, c) = (find(pts.0, &row.id)?, find(pts.1, &row.id)?);
            let cov = predicted_covariance(&t, tcov, l, c);
            let tr = cov.trace();
            let tr2 = (cov * cov).trace();
            (tr.is_finite() && tr > 0.0).then(|| tr.sqrt() * (1.0 - tr2 / (4.0 * tr * tr)))
        })
        .collect();
    (!expected.is_empty()).then(|| expected.iter().sum::<f64>() / expected.len() as f64)
}

/// Covariance of `R p + t − q` for one ball: both sides' and the transform's (covariance
/// `tcov` of (δθ, t) or (δθ, t, s)), to first order (`∂/∂δθ = −[R p]×`, `∂/∂t = I`,
/// `∂/∂s = R p`).
pub fn predicted_covariance(
    t: &Sim3,
    tcov: &DMatrix<f64>,
    l: &PointObs,
    c: &PointObs,
) -> Matrix3<f64> {
    let rp = t.rotation * l.xyz * t.scale;
    let mut cov = c.cov + t.rotation * l.cov * t.rotation.transpose() * (t.scale * t.scale);
    let n = tcov.nrows();
    if n >= 6 {
        let mut j = DMatrix::<f64>::zeros(3, n);
        j.view_mut((0, 0), (3, 3)).copy_from(&(-skew(&rp)));
        j.view_mut((0, 3), (3, 3)).copy_from(&Matrix3::identity());
        if n == 7 {
            j.view_mut((0, 6), (3, 1)).copy_from(&(t.rotation * l.xyz));
        }
        let jt = &j * tcov * j.transpose();
        cov += Matrix3::from_fn(|a, b| jt[(a, b)]);
    }
    cov
}

/// The pooled σ0 of the sphere fits against the noise profile.
fn sphere_fit_test(st: &Stages, test: &mut Test) {
    let (mut s, mut f) = (0.0, 0.0);
    for b in &st.lrf_out.found.balls {
        let dof = b.inliers.len() as f64 - 3.0;
        if dof > 0.0 && b.sigma0.is_finite() {
            s += b.sigma0 * b.sigma0 * dof;
            f += dof;
        }
    }
    if f > 0.0 {
        test(
            "sphere fits sigma0",
            (s / f).sqrt(),
            sigma0_bound(f).max(SPHERE_PROFILE_TOLERANCE),
            &|v, b| {
                format!("the sphere fits' pooled σ0 {v:.2} exceeds {b:.2}: the LRF's noise profile is too optimistic for these ranges (set the sensor's accuracy in [lrf])")
            },
        );
    }
}

/// The correlation matrix of camera `ip`'s self-calibrated intrinsics in the parameters
/// the network separates ([`pingcal_ba::camera::ModelKind::separable_jacobian`]: the double
/// sphere's scales on the axis in place of its fx, fy), by linear propagation of their
/// covariance.
fn separable_correlation(st: &Stages, ip: &IntrinsicsPrecision) -> Vec<Vec<f64>> {
    let Some(cam) = st.project.file.cameras.iter().find(|c| c.id == ip.camera) else {
        return ip.correlation.clone();
    };
    let kind = cam.model;
    let names: Vec<&str> = ip.names.iter().map(String::as_str).collect();
    let values = cam.model.parameter_names().iter().map(|n| {
        // the adjusted values of the free parameters, the start of the held ones
        names
            .iter()
            .position(|x| x == n)
            .map_or(0.0, |k| ip.values[k])
    });
    let values: Vec<f64> = values.collect();
    let Some(j) = kind.separable_jacobian(&values, &names) else {
        return ip.correlation.clone();
    };
    let n = names.len();
    let cov = |a: usize, b: usize| ip.correlation[a][b] * ip.sigmas[a] * ip.sigmas[b];
    let c2: Vec<Vec<f64>> = (0..n)
        .map(|a| {
            (0..n)
                .map(|b| {
                    let mut s = 0.0;
                    for (k, jak) in j[a].iter().enumerate() {
                        for (l, jbl) in j[b].iter().enumerate() {
                            if *jak != 0.0 && *jbl != 0.0 {
                                s += jak * cov(k, l) * jbl;
                            }
                        }
                    }
                    s
                })
                .collect()
        })
        .collect();
    (0..n)
        .map(|a| {
            (0..n)
                .map(|b| c2[a][b] / (c2[a][a] * c2[b][b]).sqrt())
                .collect()
        })
        .collect()
}

/// The largest correlation between two self-calibrated intrinsics (in the parameters the
/// network separates, [`separable_correlation`]).
fn correlation_test(st: &Stages, test: &mut Test) {
    let mut worst: Option<(f64, String)> = None;
    for ip in &st.adjusted.precision.intrinsics {
        for (i, row) in separable_correlation(st, ip).iter().enumerate() {
            for (j, r) in row.iter().enumerate().skip(i + 1) {
                if r.is_finite() && worst.as_ref().is_none_or(|w| r.abs() > w.0) {
                    worst = Some((
                        r.abs(),
                        format!("{} {}–{}", ip.camera, ip.names[i], ip.names[j]),
                    ));
                }
            }
        }
    }
    if let Some((r, pair)) = worst {
        test(
            "largest intrinsic correlation",
            r,
            MAX_CORRELATION,
            &|v, b| {
                format!("intrinsics {pair} are correlated at |ρ| = {v:.4} > {b}: the network does not separate them (more rolled and convergent images, or fix one)")
            },
        );
    }
}

/// Check balls the project names that were not judged, and spheres matched to no ball (the
/// reasons), and the unmatched spheres that lie where a labelled ball the images did not
/// measure is (the notes: such a sphere is that ball, not a spurious one).
fn unmatched(st: &Stages) -> (Vec<String>, Vec<String>) {
    let mut out = Vec::new();
    // the joint adjustment's own view of the LRF when its result is the one given (it may
    // have looked at the cloud again through its estimated mount)
    let joint = match st.joint {
        Some(Ok(j)) => Some(j),
        _ => None,
    };
    let judged: Vec<&str> = match joint {
        Some(j) => j.check.rows.iter().map(|r| r.id.as_str()).collect(),
        None => (st.ext.spheres.iter())
            .flat_map(|e| e.check.rows.iter().map(|r| r.id.as_str()))
            .collect(),
    };
    for id in &st.project.file.balls.check {
        if st.ext.spheres.is_some() && !judged.contains(&id.as_str()) {
            out.push(format!(
                "check ball {id} was not judged: no LRF sphere was matched to it"
            ));
        }
    }
    let stereo = crate::adjust::rig_cameras(st.project)
        .and_then(|(_, member)| st.adjusted.rig_of(member, st.project));
    if let (Some(s), Some((rig, _))) = (&st.project.file.stereo, stereo) {
        let adjusted = rig.centre().norm();
        if (adjusted - s.baseline_mm).abs() > BASELINE_TOLERANCE * s.baseline_mm {
            out.push(format!(
                "the adjusted stereo baseline is {adjusted:.1} mm but [stereo] baseline_mm = {}: a wrong entry, a unit mistake, or a scale from wrong distances",
                s.baseline_mm
            ));
        }
    }
    let twice = joint.map_or_else(
        || st.lrf.found.seen_twice_rejected(),
        |j| j.lrf_view.seen_twice_rejected,
    );
    if twice >= SEEN_TWICE_MIN {
        out.push(format!(
            "{twice} LRF candidate(s) were seen twice (as many beams pass through each as meet it): the points of one ball from different servo angles do not coincide, as under a wrong LRF mount model ([lrf] mount_offset_mm, tilts, servo zero); method = \"joint\" (the default) or \"all\" estimates it"
        ));
    }
    let extra = joint.map_or_else(
        || st.lrf.found.balls.len().saturating_sub(st.ext.pairs.len()),
        |j| j.lrf_view.spheres.saturating_sub(j.lrf_view.matched),
    );
    let labelled = match (joint, &st.ext.spheres) {
        (Some(j), _) => j.lrf_view.unmeasured_labels.clone(),
        (None, Some(e)) => extrinsic::unmeasured_labels(
            st.project,
            st.scene,
            st.lrf,
            &st.ext.pairs,
            &e.registration.camera_from_lrf.rigid(),
        ),
        (None, None) => Vec::new(),
    };
    let explained = labelled.len().min(extra);
    if extra > explained {
        out.push(format!(
            "{} sphere(s) found in the LRF cloud match no ball of the photogrammetric model (spurious spheres, or balls the images did not measure)",
            extra - explained
        ));
    }
    let notes = (explained > 0).then(|| format!(
        "{explained} sphere(s) found in the LRF cloud lie where the main image's label of a ball the images did not measure is ({}): that ball, seen by the LRF only, takes no part",
        labelled.join(", ")
    ));
    (out, notes.into_iter().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The level's quantile is χ²₀.₉₉ (NIST/SEMATECH e-Handbook, table 1.3.6.7.4: 30.578 at
    /// k = 15; the quantile function itself is tested in `pingcal_geometry::stats`).
    #[test]
    fn the_upper_quantile_is_at_the_level() {
        assert!((chi2_upper(15.0) - 30.578).abs() / 30.578 < 0.005);
    }
}
