//! The verdict of a sphere calibration: the tests of calibrate's (`crate::verdict`), on this
//! method's figures, at the same level α:
//!
//! | test | statistic | bound |
//! |---|---|---|
//! | registration sigma0 | σ0 of the weighted 3D transform (redundancy 3n − 6) | `√(χ²₁₋α(dof) / dof)` × [`CENTRE_SIGMA_OPTIMISM`] |
//! | leave-one-out | `Σ dᵢᵀ Σᵢ⁻¹ dᵢ / 3n` of the frames' leave-one-out errors against their predicted covariances | `χ²₁₋α(3n) / 3n` × [`CENTRE_SIGMA_OPTIMISM`]² |
//! | sphere fits sigma0 | the lidar sphere fits' pooled σ0 | `max(√(χ²₁₋α(f) / f), ` [`SPHERE_PROFILE_TOLERANCE`]`)` |
//!
//! The registration's σ0 is tested against the sensors' own σ's; when it fails, every σ is
//! scaled by it (`super::Outcome::sigma_scale`) and the leave-one-out test is on the scaled
//! σ's: whether the σ's the result states are honest.
//!
//! A failed test makes it `doubtful`, with the reason. Frames left out are listed as notes
//! (each with why); more than half of the frames left out makes it `doubtful` too: what is
//! left may not be the ball.

use super::frames::Frame;
use crate::verdict::{
    check_points_bound, mean_check_chi2, sigma0_bound, Check, Status, Verdict, ALPHA,
    CENTRE_SIGMA_OPTIMISM, SPHERE_PROFILE_TOLERANCE,
};
use pingcal_lrf::registration::{Evaluation, PointObs, Registration};

/// The bound of the registration's σ0 with `dof` degrees of freedom.
fn registration_bound(dof: usize) -> f64 {
    sigma0_bound(dof as f64) * CENTRE_SIGMA_OPTIMISM
}

/// Whether the registration's σ0 passes its test (no redundancy passes).
pub fn sigma0_passes(reg: &Registration) -> bool {
    reg.dof == 0 || reg.sigma0 <= registration_bound(reg.dof)
}

/// Judges a run: its frames, its evaluation, the point lists registered (lidar, camera: as
/// `ev` used them), the registration's σ0 against the sensors' own σ's and the factor all
/// σ's were scaled by when that σ0 failed ([`super::Outcome::sigma_scale`]). The σ0 test is
/// on the sensors' σ0 (the scaling makes `ev`'s one by construction); the leave-one-out test
/// on `ev`'s σ's, scaled: whether the σ's stated are honest.
pub fn judge(
    frames: &[Frame],
    ev: &Evaluation,
    (lidar, cam): (&[PointObs], &[PointObs]),
    sensor_sigma0: f64,
    sigma_scale: Option<f64>,
) -> Verdict {
    let (mut checks, mut reasons, mut notes) = (Vec::new(), Vec::new(), Vec::new());
    let mut test = |name: &str, value: f64, bound: f64, why: String| {
        let passed = value <= bound;
        if !passed {
            reasons.push(why);
        }
        checks.push(Check {
            name: name.into(),
            value,
            bound,
            passed,
        });
    };
    let reg = &ev.registration;
    if reg.dof > 0 {
        let b = registration_bound(reg.dof);
        let scatter = sigma_scale.map_or(String::new(), |k| format!(
            "; the centres scatter {k:.1}× more than their σ's say, and every σ of the result is scaled by that"
        ));
        test("registration sigma0", sensor_sigma0, b, format!(
            "the registration's σ0 {sensor_sigma0:.2} exceeds {b:.2}: the sphere's centres do not fit one rigid transform within their σ's (a sphere diameter that is not the ball's, a camera model that does not fit, a wrong lidar noise profile, or sensors that moved){scatter}"
        ));
    }
    if let Some((mean, n)) = mean_check_chi2(
        &ev.leave_one_out.rows,
        (lidar, cam),
        &reg.camera_from_lrf,
        &reg.cov,
    ) {
        let b = check_points_bound(n);
        test("leave-one-out", mean, b, format!(
            "the frames' leave-one-out errors are {:.1}× their predicted σ (χ²/n = {mean:.2} > {b:.2}): the extrinsic is worse than its σ's say",
            mean.sqrt()
        ));
    }
    let (s, f) = pooled_sphere_fits(frames);
    if f > 0.0 {
        let b = sigma0_bound(f).max(SPHERE_PROFILE_TOLERANCE);
        let v = (s / f).sqrt();
        test("sphere fits sigma0", v, b, format!(
            "the lidar sphere fits' pooled σ0 {v:.2} exceeds {b:.2}: the lidar's noise profile is too optimistic for these ranges (set noise or noise_sigma_mm in [lidar])"
        ));
    }
    left_out(frames, &mut reasons, &mut notes);
    Verdict {
        status: if reasons.is_empty() {
            Status::Ok
        } else {
            Status::Doubtful
        },
        reasons,
        notes,
        checks,
        alpha: ALPHA,
    }
}

/// The lidar sphere fits of the frames used, pooled: the sum of σ0² · dof and the sum of
/// dof (inliers − 3) over the fits with redundancy and a finite σ0.
fn pooled_sphere_fits(frames: &[Frame]) -> (f64, f64) {
    let (mut s, mut f) = (0.0, 0.0);
    for l in frames
        .iter()
        .filter(|f| f.skipped.is_none())
        .filter_map(|f| f.lidar.as_ref())
    {
        let dof = l.inliers as f64 - 3.0;
        if dof > 0.0 && l.sigma0.is_finite() {
            s += l.sigma0 * l.sigma0 * dof;
            f += dof;
        }
    }
    (s, f)
}

/// A note for each frame left out, with why; and a reason when more than half of them are.
fn left_out(frames: &[Frame], reasons: &mut Vec<String>, notes: &mut Vec<String>) {
    let left: Vec<&Frame> = frames.iter().filter(|f| f.skipped.is_some()).collect();
    for f in &left {
        notes.push(format!(
            "{} left out: {}",
            f.id,
            f.skipped.as_deref().unwrap_or("")
        ));
    }
    if 2 * left.len() > frames.len() {
        reasons.push(format!(
            "{} of {} frames left out: what is left may not be the ball (see the notes)",
            left.len(),
            frames.len()
        ));
    }
}
