//! The final adjustment's rounds: the adjustment with the plausible-range prior, then every
//! group's gross errors removed (each group judged by its own σ0, see
//! [`super::groups`]), and again, at most [`REJECT_ROUNDS`] times.

use super::problem::Joint;
use super::{BEAM_REJECT, PLAUSIBLE, REJECT_ROUNDS};
use crate::context::Result;
use pingcal_ba::solver::Precision;
use pingcal_ba::Problem;

/// Observations removed as gross errors, per group (in the order of the joint problem's
/// groups).
pub(super) type Rejected = Vec<usize>;

/// Which observations of one group are kept after an adjustment: those whose largest
/// standardised residual component `w` over the group's σ0 (from its own redundancy, at
/// least 1) is at most [`BEAM_REJECT`]. `e` and `sigma` are the errors and their σ's, `w`
/// and `q` the group's standardised residuals and redundancy numbers.
pub(crate) fn keep_flags(e: &[f64], sigma: &[f64], w: &[Vec<f64>], q: &[Vec<f64>]) -> Vec<bool> {
    let vv: f64 = e.iter().zip(sigma).map(|(e, s)| (e / s).powi(2)).sum();
    let r: f64 = q.iter().map(|q| q.iter().sum::<f64>()).sum();
    let s0 = (vv / r.max(1.0)).sqrt().max(1.0);
    (w.iter())
        .map(|w| !(w.iter().fold(0.0_f64, |m, w| m.max(w.abs())) / s0 > BEAM_REJECT))
        .collect()
}

/// The adjustment with the plausible-range prior, removing every group's gross errors (see
/// the module doc). Returns the solved problem, its precision and the observations removed
/// per group.
pub(super) fn final_rounds(
    joint: &mut Joint,
    free: &[bool; 8],
) -> Result<(Problem, Precision, Rejected)> {
    let mut rejected = vec![0; joint.groups.len()];
    for round in 0..=REJECT_ROUNDS {
        let mut p = joint.problem_from(&joint.base, free, &PLAUSIBLE);
        let (prec, summary) = joint.solve(&mut p)?;
        joint.last = Some(summary);
        let keep = keep_per_group(joint, &p, &prec);
        let bad: Vec<usize> = (keep.iter())
            .map(|k| k.iter().filter(|k| !**k).count())
            .collect();
        if round == REJECT_ROUNDS || bad.iter().all(|&b| b == 0) {
            return Ok((p, prec, rejected));
        }
        for ((g, keep), (r, bad)) in
            (joint.groups.iter_mut().zip(&keep)).zip(rejected.iter_mut().zip(bad))
        {
            g.retain(keep);
            *r += bad;
        }
    }
    unreachable!("the last round returns")
}

/// Each group's keep flags at the solution `p` (its residual blocks come first in the
/// problem, group after group, in order).
fn keep_per_group(joint: &Joint, p: &Problem, prec: &Precision) -> Vec<Vec<bool>> {
    let at = joint.at(p);
    let (w, q) = (
        &prec.residual_standardized,
        &prec.residual_redundancy_numbers,
    );
    let mut start = 0;
    (joint.groups.iter())
        .map(|g| {
            let n = g.len();
            let range = start..start + n;
            start += n;
            keep_flags(&g.errors(&at), &g.sigmas(), &w[range.clone()], &q[range])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A group's σ0 comes from its own residuals and redundancy; an observation is a gross
    /// error when its |w| over that σ0 (at least 1) exceeds the critical value.
    #[test]
    fn an_observation_beyond_the_critical_value_of_its_groups_sigma0_is_removed() {
        // five observations of redundancy 0.8 each, σ 1: four small, one of w = 5
        let e = [0.1, -0.2, 0.1, 0.0, 4.5];
        let sigma = [1.0; 5];
        let w: Vec<Vec<f64>> = [0.1, -0.2, 0.1, 0.0, 5.0]
            .iter()
            .map(|&w| vec![w])
            .collect();
        let q = vec![vec![0.8]; 5];
        // σ0 = √(20.31 / 4) = 2.25: 5 / 2.25 = 2.2 is below 3.29, so the blunder hides
        assert_eq!(keep_flags(&e, &sigma, &w, &q), vec![true; 5]);
        // with twenty clean observations the group's σ0 is 1.1 and w = 5 is a gross error
        let mut e2 = vec![0.1; 20];
        e2.push(4.5);
        let mut w2 = vec![vec![0.1]; 20];
        w2.push(vec![5.0]);
        let q2 = vec![vec![0.8]; 21];
        let keep = keep_flags(&e2, &[1.0; 21], &w2, &q2);
        assert_eq!(keep.iter().filter(|k| !**k).count(), 1);
        assert!(!keep[20]);
    }

    /// A multi-component observation is judged by its largest |w|, whatever its sign.
    #[test]
    fn a_multi_component_observation_is_judged_by_its_largest_component() {
        let e = vec![0.0; 30];
        let mut w = vec![vec![0.1, 0.2]; 30];
        w[7] = vec![0.5, -3.5];
        let q = vec![vec![0.5, 0.5]; 30];
        let keep = keep_flags(&e, &[1.0; 30], &w, &q);
        assert_eq!(
            keep.iter()
                .enumerate()
                .filter(|(_, k)| !**k)
                .map(|(i, _)| i)
                .collect::<Vec<_>>(),
            vec![7]
        );
    }

    /// NaN standardised residuals are not a reason to remove (nothing is known of them).
    #[test]
    fn an_undefined_w_keeps_the_observation() {
        let keep = keep_flags(
            &[0.0; 3],
            &[1.0; 3],
            &[vec![f64::NAN], vec![0.0], vec![1.0]],
            &vec![vec![1.0]; 3],
        );
        assert_eq!(keep, vec![true; 3]);
    }
}
