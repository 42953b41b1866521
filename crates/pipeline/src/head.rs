//! The head's sensors as one adjustment gives them: every camera that follows the main
//! camera through a rig ([`crate::adjust::head_cameras`]) and the LRF, each with its pose
//! relative to the main (reference) camera, and the **joint** covariance of all of them.
//!
//! **What the adjustment holds.** A rig's block is `member_from_base` (the reference camera
//! frame → the member camera's), the LRF's is `camera_from_lrf`; both are updated on the
//! left, `R ← exp([δω]×) R`, `t ← t + δt` ([`pingcal_geometry::Rigid3::plus`]). The
//! covariance of all the updates together (6 per rig, then 6 for the extrinsic) is the
//! adjustment's ([`pingcal_ba::solver::Precision::rigs_and_parameters_covariance`]): the
//! sensors are correlated, since every one of them is tied to the same image poses.
//!
//! **What is reported.** Each sensor's `camera_from_sensor` (`p_ref = R p_sensor + t`) and
//! any pair's `a_from_b = camera_from_a⁻¹ · camera_from_b`, each with the σ of its ω, φ, κ
//! and t: `J Σ Jᵀ`, with `J` the derivative of (ω, φ, κ, t) of that transform in all the
//! updates (central differences; the transform is smooth and the step 1e-6 rad / mm leaves
//! an error far below the σ's). A pair's σ thus comes from the joint covariance, cross
//! terms included, not from adding the two sensors' σ's.

use crate::adjust::{head_cameras, HeadCamera};
use nalgebra::DMatrix;
use pingcal_ba::problem::Problem;
use pingcal_ba::solver::Precision;
use pingcal_ba::{ParameterKey, ParameterValue};
use pingcal_geometry::{to_opk, Rigid3};
use pingcal_project::Project;

/// Central-difference step of the propagation (rad, mm).
const STEP: f64 = 1e-6;

/// One sensor of the head, as the adjustment holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadSensor {
    /// A camera's id, or the LRF's (`[lrf] id`, by default `lrf`).
    pub id: String,
    /// `camera` or the LRF's kind (`rotating`, `fixed`).
    pub kind: String,
    /// The adjustment's block: `member_from_base` for a camera (`inverted`), or
    /// `camera_from_lrf`.
    pub block: Rigid3,
    /// Whether `block` maps the reference frame to the sensor's (a rig) rather than back.
    pub inverted: bool,
}

impl HeadSensor {
    /// `camera_from_sensor` after the update `delta` (δω, δt) of its block.
    fn camera_from_sensor(&self, delta: &[f64]) -> Rigid3 {
        let b = self.block.plus(delta);
        if self.inverted {
            b.inverse()
        } else {
            b
        }
    }
}

/// The head's sensors and the joint covariance of their blocks' updates (6 rows each, in
/// `sensors`' order; a held block's rows are zero).
#[derive(Clone, Debug, Default)]
pub struct HeadPoses {
    /// The cameras that follow the reference camera, then the LRF where it is one of the
    /// adjustment's unknowns.
    pub sensors: Vec<HeadSensor>,
    /// The covariance of the updates; None where the cross-covariances are not known (the
    /// rigs from one adjustment and the LRF from another).
    pub cov: Option<DMatrix<f64>>,
    /// Each sensor's own 6 × 6 (None where this adjustment does not have it: an LRF from
    /// another).
    pub own: Vec<Option<DMatrix<f64>>>,
    /// The adjustment the range sensor's pose came from, to join it with another range
    /// sensor's adjustment of the same bundle ([`crate::range_sensors`]).
    pub adjustment: Option<Adjustment>,
}

/// A range sensor's adjustment: its solved problem (the bundle's with the sensor's blocks and
/// observations, each group at its variance component) and its extrinsic's block.
#[derive(Clone, Debug)]
pub struct Adjustment {
    /// The solved problem.
    pub problem: std::sync::Arc<Problem>,
    /// The extrinsic's block in it.
    pub extrinsic: ParameterKey,
}

/// A transform with the σ's of its ω, φ, κ (degrees) and t (mm); σ None where they are not
/// known.
#[derive(Clone, Copy, Debug)]
pub struct WithSigma {
    /// The transform.
    pub pose: Rigid3,
    /// σ of ω, φ, κ (degrees).
    pub sigma_rotation_deg: Option<[f64; 3]>,
    /// σ of t (mm).
    pub sigma_translation_mm: Option<[f64; 3]>,
}

impl HeadPoses {
    /// The head's rigs in `problem` (solved), the extrinsic's block `extrinsic` (kind `kind`)
    /// where it is one, and their joint covariance from `prec` (`problem`'s precision).
    pub fn of_problem(
        project: &Project,
        problem: &Problem,
        prec: &Precision,
        extrinsic: Option<(ParameterKey, &str)>,
    ) -> Self {
        let heads = head_cameras(project);
        let mut sensors = Vec::new();
        let mut rows = Vec::new();
        for (r, rig) in problem.rigs.iter().enumerate() {
            let Some(head) = heads.iter().find(|h| h.rig == rig.name) else {
                continue;
            };
            sensors.push(camera(head, rig.member_from_base));
            rows.extend(6 * r..6 * r + 6);
        }
        let joint = &prec.rigs_and_parameters_covariance;
        if let Some((key, kind)) = extrinsic {
            if let ParameterValue::Pose(pose) = problem.parameters[key.0].value {
                sensors.push(HeadSensor {
                    id: project.file.lrf.id().into(),
                    kind: kind.into(),
                    block: pose,
                    inverted: false,
                });
                let offset = prec.parameter_offsets[key.0];
                if problem.rigs.is_empty() {
                    rows.extend(offset..offset + 6);
                } else {
                    rows.extend(
                        6 * problem.rigs.len() + offset..6 * problem.rigs.len() + offset + 6,
                    );
                }
            }
        }
        let whole = if problem.rigs.is_empty() {
            &prec.parameters_covariance
        } else {
            joint
        };
        let cov = DMatrix::from_fn(rows.len(), rows.len(), |a, b| whole[(rows[a], rows[b])]);
        HeadPoses {
            own: own_blocks(&cov),
            sensors,
            cov: Some(cov),
            adjustment: extrinsic.map(|(key, _)| Adjustment {
                problem: std::sync::Arc::new(problem.clone()),
                extrinsic: key,
            }),
        }
    }

    /// The head's rigs of the bundle `problem` (with `prec`'s joint covariance of them) and
    /// an LRF from another adjustment (`camera_from_lrf` of kind `kind`): its covariance is
    /// not this one's, so neither its own σ's nor its pairs' are had here.
    pub fn with_separate_lrf(
        project: &Project,
        problem: &Problem,
        prec: &Precision,
        (pose, kind): (Rigid3, &str),
    ) -> Self {
        let mut head = Self::of_problem(project, problem, prec, None);
        head.sensors.push(HeadSensor {
            id: project.file.lrf.id().into(),
            kind: kind.into(),
            block: pose,
            inverted: false,
        });
        head.own.push(None);
        head.cov = None;
        head
    }

    /// Range sensors (`camera_from_lrf` blocks `poses`, ids and kinds) with the joint
    /// covariance `cov` of their blocks' updates (6 rows each, in order).
    pub fn of_range_sensors(poses: Vec<(String, String, Rigid3)>, cov: DMatrix<f64>) -> Self {
        HeadPoses {
            sensors: (poses.into_iter())
                .map(|(id, kind, block)| HeadSensor {
                    id,
                    kind,
                    block,
                    inverted: false,
                })
                .collect(),
            own: own_blocks(&cov),
            cov: Some(cov),
            adjustment: None,
        }
    }

    /// `camera_from_sensor` of sensor `k` with its σ's (None where they are not known).
    pub fn sensor(&self, k: usize) -> WithSigma {
        let s = &self.sensors[k];
        let pose = s.camera_from_sensor(&[0.0; 6]);
        let sigmas = (self.own[k].as_ref()).map(|c| propagate(c, |d| s.camera_from_sensor(d)));
        with(pose, sigmas)
    }

    /// `a_from_b = camera_from_a⁻¹ · camera_from_b` with its σ's from the joint covariance
    /// (None where it is not known).
    pub fn pair(&self, a: usize, b: usize) -> WithSigma {
        let (sa, sb) = (&self.sensors[a], &self.sensors[b]);
        let relative = |da: &[f64], db: &[f64]| {
            sa.camera_from_sensor(da)
                .inverse()
                .compose(&sb.camera_from_sensor(db))
        };
        let pose = relative(&[0.0; 6], &[0.0; 6]);
        let sigmas = self.cov.as_ref().map(|cov| {
            let rows: Vec<usize> = (6 * a..6 * a + 6).chain(6 * b..6 * b + 6).collect();
            let sub = DMatrix::from_fn(12, 12, |i, j| cov[(rows[i], rows[j])]);
            propagate(&sub, |d| relative(&d[..6], &d[6..]))
        });
        with(pose, sigmas)
    }
}

/// The sensor of head camera `head` whose rig block is `member_from_base`.
fn camera(head: &HeadCamera, member_from_base: Rigid3) -> HeadSensor {
    HeadSensor {
        id: head.camera.into(),
        kind: "camera".into(),
        block: member_from_base,
        inverted: true,
    }
}

/// Each sensor's own 6 × 6 block of `cov`.
fn own_blocks(cov: &DMatrix<f64>) -> Vec<Option<DMatrix<f64>>> {
    (0..cov.nrows() / 6)
        .map(|k| Some(cov.view((6 * k, 6 * k), (6, 6)).into_owned()))
        .collect()
}

fn with(pose: Rigid3, sigmas: Option<([f64; 3], [f64; 3])>) -> WithSigma {
    WithSigma {
        pose,
        sigma_rotation_deg: sigmas.map(|s| s.0),
        sigma_translation_mm: sigmas.map(|s| s.1),
    }
}

/// (ω, φ, κ) in radians and t of `pose`.
fn parameters(pose: &Rigid3) -> [f64; 6] {
    let (o, p, k) = to_opk(&pose.rotation);
    let t = pose.translation;
    [o, p, k, t.x, t.y, t.z]
}

/// The σ's of (ω, φ, κ) (degrees) and t (mm) of `f(δ)` for updates δ of covariance `cov`:
/// `J cov Jᵀ` with `J` by central differences. An angle that wraps within the step (ω or
/// κ at ±180°) takes no derivative from it, as [`pingcal_geometry::opk_sigma_deg`] does.
fn propagate(cov: &DMatrix<f64>, f: impl Fn(&[f64]) -> Rigid3) -> ([f64; 3], [f64; 3]) {
    let n = cov.nrows();
    let e0 = parameters(&f(&vec![0.0; n]));
    let mut j = DMatrix::zeros(6, n);
    for c in 0..n {
        let mut d = vec![0.0; n];
        d[c] = STEP;
        let ep = parameters(&f(&d));
        d[c] = -STEP;
        let em = parameters(&f(&d));
        for r in 0..6 {
            let wraps = r < 3 && ((ep[r] - e0[r]).abs() > 1.0 || (em[r] - e0[r]).abs() > 1.0);
            j[(r, c)] = if wraps {
                0.0
            } else {
                (ep[r] - em[r]) / (2.0 * STEP)
            };
        }
    }
    let out = &j * cov * j.transpose();
    let sd = |k: usize| out[(k, k)].max(0.0).sqrt();
    ([0, 1, 2].map(|k| sd(k).to_degrees()), [3, 4, 5].map(sd))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};
    use pingcal_geometry::{exp_so3, opk_sigma_deg};

    fn rig(id: &str, member_from_base: Rigid3) -> HeadSensor {
        HeadSensor {
            id: id.into(),
            kind: "camera".into(),
            block: member_from_base,
            inverted: true,
        }
    }

    fn lrf(camera_from_lrf: Rigid3) -> HeadSensor {
        HeadSensor {
            id: "lrf".into(),
            kind: "fixed".into(),
            block: camera_from_lrf,
            inverted: false,
        }
    }

    fn head(sensors: Vec<HeadSensor>, cov: DMatrix<f64>) -> HeadPoses {
        HeadPoses {
            own: own_blocks(&cov),
            sensors,
            cov: Some(cov),
            adjustment: None,
        }
    }

    /// The LRF's block is `camera_from_lrf` itself: its t's σ is the covariance's diagonal
    /// and its ω, φ, κ's that of [`opk_sigma_deg`] (a separate, rotation-only derivative),
    /// so the propagation through the whole transform agrees with both.
    #[test]
    fn a_sensors_own_sigmas_agree_with_the_extrinsics() {
        let e = Rigid3::new(
            exp_so3(&Vector3::new(0.3, -1.1, 0.7)),
            Vector3::new(70.0, 10.0, 90.0),
        );
        let a = DMatrix::from_fn(6, 6, |i, j| ((i * 7 + j * 3) % 5) as f64 * 0.1);
        let cov = &a * a.transpose() * 1e-4 + DMatrix::identity(6, 6) * 1e-5;
        let h = head(vec![lrf(e)], cov.clone());
        let s = h.sensor(0);
        assert!((s.pose.translation - e.translation).norm() == 0.0);
        let expect = opk_sigma_deg(&e.rotation, &Matrix3::from_fn(|i, j| cov[(i, j)]));
        for k in 0..3 {
            let (got, want) = (s.sigma_rotation_deg.unwrap()[k], expect[k]);
            assert!(
                (got - want).abs() <= 1e-6 * want,
                "opk {k}: {got} against {want}"
            );
            let (got, want) = (
                s.sigma_translation_mm.unwrap()[k],
                cov[(3 + k, 3 + k)].sqrt(),
            );
            assert!(
                (got - want).abs() <= 1e-6 * want,
                "t {k}: {got} against {want}"
            );
        }
    }

    /// Two cameras whose rigs share one translation error (fully correlated): each has the
    /// error's σ, their relative pose none of it. Adding the two σ's (what chaining pairs
    /// does) would give √2 σ; the pair's σ comes from the joint covariance. And the pair's
    /// transform is the composition of the sensors' to 1e-9.
    #[test]
    fn a_pairs_sigma_comes_from_the_joint_covariance() {
        let a =
            Rigid3::from_rotation_and_centre(Matrix3::identity(), Vector3::new(120.0, 0.0, 0.0));
        let b =
            Rigid3::from_rotation_and_centre(Matrix3::identity(), Vector3::new(-60.0, 20.0, 5.0));
        let sigma = 0.5;
        let mut cov = DMatrix::zeros(12, 12);
        for i in 0..3 {
            for (r, c) in [(3, 3), (3, 9), (9, 3), (9, 9)] {
                cov[(r + i, c + i)] = sigma * sigma;
            }
            // independent rotation errors of 1 mrad
            cov[(i, i)] = 1e-6;
            cov[(6 + i, 6 + i)] = 1e-6;
        }
        let h = head(vec![rig("right", a), rig("side", b)], cov);
        // camera_from_right = (I, C): δC = −δt + δω × t with t = −C = (−120, 0, 0)
        let lever = (sigma * sigma + (120.0f64 * 1e-3).powi(2)).sqrt();
        let s = h.sensor(0).sigma_translation_mm.unwrap();
        for (got, want) in s.iter().zip([sigma, lever, lever]) {
            assert!((got - want).abs() < 1e-6, "{s:?}");
        }
        let pair = h.pair(0, 1);
        let composed = h.sensor(0).pose.inverse().compose(&h.sensor(1).pose);
        assert!((pair.pose.rotation - composed.rotation).norm() < 1e-12);
        assert!((pair.pose.translation - composed.translation).norm() < 1e-9);
        // the translation error cancels; what is left is the rotations' lever arm:
        // 1 mrad on each side over the 60–180 mm between the centres, well under σ
        let t = pair.sigma_translation_mm.unwrap();
        assert!(t.iter().all(|v| *v < 0.3), "{t:?}");
        let r = pair.sigma_rotation_deg.unwrap();
        let independent = (2e-6f64).sqrt().to_degrees();
        assert!(r.iter().all(|v| (v - independent).abs() < 1e-4), "{r:?}");
    }

    /// Without the cross-covariance (the LRF from another adjustment than the rigs) a
    /// pair's σ is not made up.
    #[test]
    fn a_pair_across_separate_adjustments_has_no_sigma() {
        let mut h = head(
            vec![rig("right", Rigid3::identity())],
            DMatrix::identity(6, 6),
        );
        h.sensors.push(lrf(Rigid3::identity()));
        h.own.push(Some(DMatrix::identity(6, 6)));
        h.cov = None;
        assert!(h.pair(0, 1).sigma_translation_mm.is_none());
        assert!(h.sensor(1).sigma_translation_mm.is_some());
        // an LRF whose covariance this adjustment does not have: no σ of its own either
        h.own[1] = None;
        assert!(h.sensor(1).sigma_translation_mm.is_none());
    }
}
