//! Estimability: which asked-for mount parameters (and the servo time offset) the data
//! determine, judged on the cofactors of the extrinsic and the mount with weak priors in
//! place of the plausible ones (see the joint module's doc): a σ beyond
//! [`MAX_PRIOR_SHARE`] of its prior, or a correlation beyond [`MAX_CORRELATION`], holds the
//! worst one, named, and the test is made again. The rows of the covariance are found by
//! the blocks' keys ([`Rows`]), never by position.

use super::groups::SensorKeys;
use super::problem::Joint;
use super::{
    to_unit, unit, FULL_TURN_DEG, MAX_CORRELATION, MAX_PRIOR_SHARE, PLAUSIBLE, PRIOR_SIGMA,
    TIME_OFFSET_PRIOR_SIGMA_S,
};
use crate::context::{PipelineError, Result};
use nalgebra::DMatrix;
use pingcal_ba::solver::{self, Precision};
use pingcal_ba::Problem;
use pingcal_lrf::sensor::MOUNT_PARAM_NAMES;

/// Where the extrinsic's 6 unknowns (δω, δt) and the mount's 8 are among the rows of a
/// precision's parameter covariance: read from the solver's offsets of their blocks
/// (`Precision::parameter_offsets`), not from the order the blocks were added in.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rows {
    extrinsic: usize,
    mount: usize,
}

impl Rows {
    /// The rows of `keys`' blocks in `prec`.
    pub fn of(keys: &SensorKeys, prec: &Precision) -> Self {
        Rows {
            extrinsic: prec.parameter_offsets[keys.extrinsic.0],
            mount: prec.parameter_offsets[keys.mount.0],
        }
    }

    /// The row of the extrinsic's unknown `k` (0–2 δω, 3–5 δt).
    pub fn ext(&self, k: usize) -> usize {
        self.extrinsic + k
    }

    /// The row of mount parameter `k` ([`pingcal_lrf::sensor::MountParam::index`]).
    pub fn mount(&self, k: usize) -> usize {
        self.mount + k
    }

    /// The extrinsic's rows and those of the free mount parameters, each with its name.
    pub fn named(&self, free: &[bool; 8]) -> Vec<(usize, String)> {
        let ext = ["ω", "φ", "κ", "tx", "ty", "tz"];
        (0..6)
            .map(|k| (self.ext(k), format!("the extrinsic's {}", ext[k])))
            .chain(
                (0..8)
                    .filter(|&k| free[k])
                    .map(|k| (self.mount(k), MOUNT_PARAM_NAMES[k].to_string())),
            )
            .collect()
    }
}

/// Holds, one at a time, the asked-for mount parameters that the data cannot determine
/// (see the module doc), naming each with its reason; judged on the cofactors at the
/// solution `at` (no new adjustment: the precision with the weak priors in place of the
/// plausible ones). Returns whether it held any.
pub(super) fn estimability(
    joint: &mut Joint,
    at: &Problem,
    free: &mut [bool; 8],
    (held, shifts): (&mut [Option<String>; 8], &mut [Option<[f64; 6]>; 8]),
) -> Result<bool> {
    let mut any = false;
    let tau_free = |j: &Joint| j.time_offset.as_ref().is_some_and(|t| t.free());
    while free.iter().any(|&f| f) || tau_free(joint) {
        let p = joint.problem_from(at, free, &PRIOR_SIGMA);
        let prec = solver::precision(&p)
            .map_err(|e| PipelineError::Adjustment(format!("joint adjustment: {e}")))?;
        // the cofactors of (extrinsic, mount): the covariance with σ0 = 1
        let cov = &prec.parameters_covariance / prec.sigma0.powi(2).max(f64::MIN_POSITIVE);
        let rows = Rows::of(&joint.keys, &prec);
        // the servo time offset: the same two tests, on its own row (k = 8)
        let tau = (joint.time_offset.as_ref().filter(|t| t.free())).and_then(|t| {
            let i = prec.parameter_offsets[t.block.0];
            time_offset_not_estimable(i, &cov, rows, free).map(|(rank, why)| (rank, 8, why))
        });
        let worst = (0..8)
            .filter(|&k| free[k])
            .filter_map(|k| not_estimable(k, &cov, rows, free).map(|(rank, why)| (rank, k, why)))
            .chain(tau)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, k, why)) = worst else { break };
        any = true;
        if k == 8 {
            let t = joint.time_offset.as_mut().expect("tested above");
            t.held = Some(why);
            continue;
        }
        free[k] = false;
        let shift = consider(k, &cov, rows);
        shifts[k] = shift;
        let why = match shift.map(largest_shift) {
            Some([t, r]) => format!(
                "{why}; held at the project's value: were it off by its plausible {:.3}{}, the extrinsic would move by up to {t:.1} mm and {r:.2}°",
                to_unit(k, PLAUSIBLE[k]),
                unit(k)
            ),
            None => why,
        };
        held[k] = Some(if joint.sweep_deg < FULL_TURN_DEG {
            format!(
                "{why}; the servo turned through {:.0}° only: a full turn sees every ball twice, from both sides, which is what tells the scanner's offsets and its range offset from the extrinsic",
                joint.sweep_deg
            )
        } else {
            why
        });
    }
    Ok(any)
}

/// What holding mount parameter `k` at the project's value costs: were the value off by the
/// parameter's plausible size ([`PLAUSIBLE`]), the extrinsic (δω rad, δt mm) would move by
/// `Σ_xk / Σ_kk` times it (the shift of the extrinsic given the parameter, from the cofactors
/// `cov` with the weak priors on), whatever its σ says.
fn consider(k: usize, cov: &DMatrix<f64>, rows: Rows) -> Option<[f64; 6]> {
    let kk = cov[(rows.mount(k), rows.mount(k))];
    (kk > 0.0 && kk.is_finite())
        .then(|| std::array::from_fn(|j| cov[(rows.ext(j), rows.mount(k))] / kk * PLAUSIBLE[k]))
}

/// The largest translation (mm) and rotation (degrees) of an extrinsic shift (δω rad, δt mm).
pub fn largest_shift(s: [f64; 6]) -> [f64; 2] {
    let t = s[3..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let r = s[..3].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    [t, r.to_degrees()]
}

/// Why parameter `k` cannot be estimated, judged on the cofactors `cov` of the extrinsic
/// (6: δω, δt) and the mount (8; with the weak priors on): None when it can. The second value
/// ranks how badly (larger: worse).
fn not_estimable(
    k: usize,
    cov: &DMatrix<f64>,
    rows: Rows,
    free: &[bool; 8],
) -> Option<(f64, String)> {
    let undetermined = |sd: f64| {
        let (sd, prior, u) = (to_unit(k, sd), to_unit(k, PRIOR_SIGMA[k]), unit(k));
        format!("the data do not determine it (σ {sd:.3}{u} against a prior of {prior:.3}{u}: the sweep and the balls leave it free)")
    };
    let row = (rows.mount(k), PRIOR_SIGMA[k]);
    row_not_estimable(
        row,
        (cov, rows, free),
        undetermined,
        "the data cannot tell them apart",
    )
}

/// The two tests of an unknown at row `i` of the cofactors `cov` under a weak prior of
/// `prior_sigma`: its σ beyond [`MAX_PRIOR_SHARE`] of the prior (`undetermined` of its σ
/// says so; ranked above every correlation), or its correlation with the extrinsic or a free
/// mount parameter beyond [`MAX_CORRELATION`] (said with `why_correlated`, ranked by |ρ|).
fn row_not_estimable(
    (i, prior_sigma): (usize, f64),
    (cov, rows, free): (&DMatrix<f64>, Rows, &[bool; 8]),
    undetermined: impl FnOnce(f64) -> String,
    why_correlated: &str,
) -> Option<(f64, String)> {
    let sd = cov[(i, i)].max(0.0).sqrt();
    let share = sd / prior_sigma;
    if !(share <= MAX_PRIOR_SHARE) {
        return Some((1e6 + share, undetermined(sd)));
    }
    correlated(i, cov, rows, free).map(|(other, r)| {
        (
            r.abs(),
            format!("it is correlated with {other} at ρ = {r:.4}: {why_correlated}"),
        )
    })
}

/// The first unknown among the extrinsic's and the free mount parameters (their `rows`)
/// that unknown `i` is correlated with beyond [`MAX_CORRELATION`]: its name and the
/// correlation.
fn correlated(i: usize, cov: &DMatrix<f64>, rows: Rows, free: &[bool; 8]) -> Option<(String, f64)> {
    (rows.named(free).into_iter())
        .filter(|&(j, _)| j != i)
        .find_map(|(j, other)| {
            let r = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
            (r.abs() > MAX_CORRELATION).then_some((other, r))
        })
}

/// Why the servo time offset (row `i` of the cofactors `cov`: the extrinsic's 6, the
/// mount's 8, the planes', then its own) cannot be estimated: its σ against the weak prior,
/// or its correlation with the extrinsic or a free mount parameter. A sweep in one direction
/// at one speed moves every beam's servo angle by the same rate × τ: one angle about the
/// servo axis, which the extrinsic's rotation takes; a sweep forward and back (or at
/// several speeds) tells them apart.
fn time_offset_not_estimable(
    i: usize,
    cov: &DMatrix<f64>,
    rows: Rows,
    free: &[bool; 8],
) -> Option<(f64, String)> {
    const WHY: &str = "a sweep in one direction at one speed turns every beam by the same angle, which the extrinsic's rotation about the servo axis takes; sweep forward and back (or at two speeds) to estimate it";
    let undetermined = |sd: f64| {
        format!("the data do not determine it (σ {sd:.3} s against a prior of {TIME_OFFSET_PRIOR_SIGMA_S} s): {WHY}")
    };
    let row = (i, TIME_OFFSET_PRIOR_SIGMA_S);
    row_not_estimable(row, (cov, rows, free), undetermined, WHY)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows of a covariance of the extrinsic (rows 0–5) and the mount (6–13).
    fn rows() -> Rows {
        Rows {
            extrinsic: 0,
            mount: 6,
        }
    }

    /// A parameter whose σ is a large share of its weak prior is undetermined, ranked above
    /// any correlation; one of a small σ and no correlation is estimable.
    #[test]
    fn a_parameter_the_data_leave_at_its_prior_is_not_estimable() {
        let mut cov = DMatrix::<f64>::identity(14, 14) * 1e-6;
        let k = 6; // range_offset (mm): prior σ 100
        let i = rows().mount(k);
        let free = [true; 8];
        cov[(i, i)] = 30.0_f64.powi(2); // σ 30 mm: 0.3 of the prior
        let (rank, why) = not_estimable(k, &cov, rows(), &free).expect("undetermined");
        assert!(rank > 1e6, "{rank}");
        assert!(why.contains("the data do not determine it"), "{why}");
        cov[(i, i)] = 1.0; // σ 1 mm: 0.01 of the prior
        assert!(not_estimable(k, &cov, rows(), &free).is_none());
    }

    /// A parameter correlated beyond the limit with the extrinsic is named with that
    /// unknown and ranked by |ρ|; a correlation with a held mount parameter is not looked at.
    #[test]
    fn a_parameter_correlated_with_the_extrinsic_names_the_unknown() {
        let mut cov = DMatrix::<f64>::identity(14, 14) * 1e-4;
        let (i, j) = (rows().mount(0), rows().ext(3)); // offset_x and tx
        let rho = -0.9995;
        cov[(i, j)] = rho * 1e-4;
        cov[(j, i)] = rho * 1e-4;
        let free = [true; 8];
        let (rank, why) = not_estimable(0, &cov, rows(), &free).expect("correlated");
        assert!((rank - 0.9995).abs() < 1e-12, "{rank}");
        assert!(
            why.contains("the extrinsic's tx") && why.contains("-0.9995"),
            "{why}"
        );
        // the same correlation with a mount parameter that is held does not count
        let m = rows().mount(2);
        cov[(j, i)] = 0.0;
        cov[(i, j)] = 0.0;
        cov[(i, m)] = rho * 1e-4;
        cov[(m, i)] = rho * 1e-4;
        let mut held = free;
        held[2] = false;
        assert!(not_estimable(0, &cov, rows(), &held).is_none());
        assert!(not_estimable(0, &cov, rows(), &free).is_some());
    }
}
