//! What the precision of an adjusted network is, as Australis reports it — σ0, redundancy,
//! RMS image residual, σ's and correlations of the intrinsics, σ's of every pose and point,
//! standardized residuals — and the propagation of a cofactor matrix of the reduced system
//! into the σ's of intrinsics and poses.
//!
//! Two computations fill it in: [`precision`](mod@super::precision) for a network whose datum is
//! fixed (minimal or more constraints), and [`free_network`](super::free_network) for a free
//! network (inner constraints). Both stand on this module, which uses neither.

use super::evaluate::Linearization;
use super::layout::Layout;
use super::selected_inverse::CofactorLookup;
use crate::problem::{Problem, ProblemError};
use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3};

/// Largest reduced camera system whose datum defect is counted and named by the
/// eigenvectors of the dense S, and that [`CofactorMethod::Dense`](super::CofactorMethod)
/// inverts; the precision itself has no size limit but memory and work
/// ([`CofactorMethod::Auto`](super::CofactorMethod)).
pub const MAX_DENSE_PRECISION: usize = 6000;

/// [`Precision::cofactors`] of each form.
pub(crate) const DENSE: &str = "dense inverse";
pub(crate) const SELECTED: &str = "selected inversion";
pub(crate) const DENSE_CHOLESKY: &str = "dense Cholesky inverse";
pub(crate) const BORDERED_DENSE: &str =
    "inner constraints: dense inverse of the bordered reduced system";
pub(crate) const TRANSFORMED: &str = "inner constraints: S-transformation of a selected inversion";
pub(crate) const TRANSFORMED_DENSE: &str =
    "inner constraints: S-transformation of a dense Cholesky inverse";
pub(crate) const DENSE_INNER: &str = "inner constraints: dense normal matrix";

/// Standard deviations and correlations of one camera's free intrinsics.
#[derive(Clone, Debug, serde::Serialize)]
pub struct IntrinsicsPrecision {
    /// Camera name.
    pub camera: String,
    /// Names of the free parameters (the model's names).
    pub names: Vec<String>,
    /// Their values.
    pub values: Vec<f64>,
    /// Their standard deviations (σ0-scaled).
    pub sigmas: Vec<f64>,
    /// Correlation matrix, row by row, in the order of `names`.
    pub correlation: Vec<Vec<f64>>,
    /// Pairs whose |correlation| exceeds 0.95.
    pub high_correlations: Vec<(String, String, f64)>,
}

/// Standard deviation of one image's exterior orientation.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct PoseSigma {
    /// Of the small rotation about the camera axes, radians.
    pub rotation_rad: [f64; 3],
    /// Of the projection centre in object space.
    pub centre: [f64; 3],
}

/// The precision of a network.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Precision {
    /// How the cofactors were computed: "dense inverse", "selected inversion", or for a
    /// free network "inner constraints: …" with the form.
    pub cofactors: &'static str,
    /// A-posteriori standard deviation of unit weight.
    pub sigma0: f64,
    /// Observations minus unknowns (image coordinates, distances, control coordinates).
    pub redundancy: i64,
    /// Number of scalar observations.
    pub observations: usize,
    /// Number of unknowns.
    pub unknowns: usize,
    /// RMS image residual, pixels.
    pub rms_image_px: f64,
    /// Per camera with free intrinsics.
    pub intrinsics: Vec<IntrinsicsPrecision>,
    /// Per image (None for a fixed pose).
    pub poses: Vec<Option<PoseSigma>>,
    /// Per rig: the covariance (σ0²-scaled) of the update `(δω, δt)` of its
    /// `member_from_base` ([`pingcal_geometry::Rigid3::plus`]: the small rotations about the
    /// member camera's axes, radians, then the translation, mm); `None` when held.
    #[serde(skip)]
    pub rig_covariances: Vec<Option<Matrix6<f64>>>,
    /// Per point: its covariance (None for a fixed point).
    #[serde(skip)]
    pub point_covariances: Vec<Option<Matrix3<f64>>>,
    /// Per image observation (problem order): the standardized residuals of u and v,
    /// `w = v / (σ √q_vv)` with the a-priori σ (Baarda's data snooping statistic, N(0, 1)
    /// for a good observation). NaN where the observation has no redundancy.
    #[serde(skip)]
    pub standardized_residuals: Vec<[f64; 2]>,
    /// Per image observation (problem order): the redundancy numbers of u and v,
    /// `q_vv = 1 − (A Q Aᵀ)_ii` in whitened units (the share of the observation's own error
    /// that shows in its residual). With those of the distances, the control coordinates
    /// and the residuals they add up to the redundancy. 0 where the observation
    /// has no redundancy.
    #[serde(skip)]
    pub redundancy_numbers: Vec<[f64; 2]>,
    /// Per distance (problem order): its redundancy number.
    #[serde(skip)]
    pub distance_redundancy_numbers: Vec<f64>,
    /// Per distance (problem order): its standardized residual `w = v / (σ √q_vv)` with the
    /// a-priori σ, as [`Precision::standardized_residuals`] for the image points; NaN where
    /// the distance has no redundancy (the only distance of a network fixed by a distance).
    #[serde(skip)]
    pub distance_standardized: Vec<f64>,
    /// Per weighted control point ([`Problem::point_priors`], problem order): the redundancy
    /// numbers of its X, Y and Z.
    #[serde(skip)]
    pub control_redundancy_numbers: Vec<[f64; 3]>,
    /// Per weighted control point (problem order): the standardized residuals of X, Y and Z
    /// (NaN where a coordinate has no redundancy).
    #[serde(skip)]
    pub control_standardized: Vec<[f64; 3]>,
    /// Per residual of [`Problem::residuals`]: the redundancy numbers of its components.
    #[serde(skip)]
    pub residual_redundancy_numbers: Vec<Vec<f64>>,
    /// Per residual of [`Problem::residuals`]: its standardized residuals `r / √q_vv`
    /// (whitened, divided by its σ factor; NaN where the component has no redundancy).
    #[serde(skip)]
    pub residual_standardized: Vec<Vec<f64>>,
    /// The joint covariance (σ0²-scaled) of the local updates of all of
    /// [`Problem::parameters`], block after block (offsets in `parameter_offsets`), zero
    /// rows and columns for held components.
    #[serde(skip)]
    pub parameters_covariance: DMatrix<f64>,
    /// Where each parameter block's rows start in `parameters_covariance` (one more entry
    /// than blocks).
    #[serde(skip)]
    pub parameter_offsets: Vec<usize>,
    /// The joint covariance (σ0²-scaled) of every rig's update `(δω, δt)` (6 rows each, in
    /// [`Problem::rigs`]' order, zero for a held rig) followed by every parameter block's
    /// (as [`Precision::parameters_covariance`], its offsets shifted by 6 per rig): the
    /// cross-covariances a pair of sensors' relative pose needs. Empty without rigs.
    #[serde(skip)]
    pub rigs_and_parameters_covariance: DMatrix<f64>,
}

impl Precision {
    /// The covariance of parameter block `a`'s update with block `b`'s.
    pub fn parameter_covariance(&self, a: usize, b: usize) -> DMatrix<f64> {
        let (oa, ob) = (self.parameter_offsets[a], self.parameter_offsets[b]);
        let (na, nb) = (
            self.parameter_offsets[a + 1] - oa,
            self.parameter_offsets[b + 1] - ob,
        );
        self.parameters_covariance
            .view((oa, ob), (na, nb))
            .into_owned()
    }

    /// Standard deviations of a point's coordinates.
    pub fn point_sigma(&self, p: usize) -> Option<Vector3<f64>> {
        self.point_covariances[p]
            .map(|c| Vector3::new(c[(0, 0)].sqrt(), c[(1, 1)].sqrt(), c[(2, 2)].sqrt()))
    }
}

/// Why the precision cannot be computed.
#[derive(Debug, thiserror::Error)]
pub enum PrecisionError {
    /// The problem is malformed or does not project.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// The datum is not defined: S is singular.
    #[error("the network has a datum defect: {0}")]
    DatumDefect(String),
    /// A combination of camera-model parameters that the network does not determine
    /// ([`super::estimability::check_intrinsics`]).
    #[error("{0}")]
    NotDeterminable(String),
    /// A point's position is not determined by its observations.
    #[error("point '{0}' is not determined: it needs rays from at least two images with an angle between them")]
    PointUndetermined(String),
    /// The reduced system is too large for the precision (what it would need is said).
    #[error("{0}")]
    TooLarge(String),
    /// More unknowns than observations.
    #[error("redundancy {0} is not positive: more unknowns than observations")]
    NoRedundancy(i64),
}

/// Standard deviations and correlations of every camera's free intrinsics, from the
/// cofactor matrix `q` (indexed in the reduced system) scaled by σ0².
pub(crate) fn intrinsics_precision(
    problem: &Problem,
    layout: &Layout,
    s02: f64,
    q: impl Fn(usize, usize) -> f64,
) -> Vec<IntrinsicsPrecision> {
    let mut out = Vec::new();
    for (c, cam) in problem.cameras.iter().enumerate() {
        let Some(slot) = layout.camera_slot[c] else {
            continue;
        };
        let o = layout.slot_offset(slot);
        let free = &layout.camera_free[c];
        let k = free.len();
        let cov = DMatrix::from_fn(k, k, |i, j| s02 * q(o + i, o + j));
        let sig: Vec<f64> = (0..k).map(|i| cov[(i, i)].max(0.0).sqrt()).collect();
        let names: Vec<String> = free
            .iter()
            .map(|&i| cam.model.parameter_names()[i].to_string())
            .collect();
        let corr: Vec<Vec<f64>> = (0..k)
            .map(|i| (0..k).map(|j| cov[(i, j)] / (sig[i] * sig[j])).collect())
            .collect();
        let mut high = Vec::new();
        for i in 0..k {
            for j in i + 1..k {
                if corr[i][j].abs() > 0.95 {
                    high.push((names[i].clone(), names[j].clone(), corr[i][j]));
                }
            }
        }
        out.push(IntrinsicsPrecision {
            camera: cam.name.clone(),
            values: free.iter().map(|&i| cam.params[i]).collect(),
            names,
            sigmas: sig,
            correlation: corr,
            high_correlations: high,
        });
    }
    out
}

/// The joint covariance of the parameter blocks' updates and the blocks' offsets in it
/// ([`Precision::parameters_covariance`]).
pub(crate) fn parameters_covariance(
    problem: &Problem,
    layout: &Layout,
    s02: f64,
    q: &dyn CofactorLookup,
) -> (DMatrix<f64>, Vec<usize>) {
    let mut offsets = vec![0];
    for pb in &problem.parameters {
        offsets.push(offsets.last().unwrap() + pb.tangent_dim());
    }
    let mut rows = Vec::new();
    let n = parameter_rows(problem, layout, 0, &mut rows);
    (covariance_of(&rows, n, s02, q), offsets)
}

/// [`Precision::rigs_and_parameters_covariance`] from the cofactors `q` (empty without rigs).
pub(crate) fn rigs_and_parameters_covariance(
    problem: &Problem,
    layout: &Layout,
    s02: f64,
    q: &dyn CofactorLookup,
) -> DMatrix<f64> {
    let n_rigs = problem.rigs.len();
    if n_rigs == 0 {
        return DMatrix::zeros(0, 0);
    }
    let mut rows = Vec::new();
    for (r, slot) in layout.rig_slot.iter().enumerate() {
        if let Some(s) = slot {
            let o = layout.slot_offset(*s);
            rows.extend((0..6).map(|i| (6 * r + i, o + i)));
        }
    }
    let n = parameter_rows(problem, layout, 6 * n_rigs, &mut rows);
    // sorted, so that the selected inverse reads them from its pattern where it can
    rows.sort_by_key(|&(_, reduced)| reduced);
    covariance_of(&rows, n, s02, q)
}

/// Appends (row in the covariance, row in the reduced system) of every free component of
/// the parameter blocks, the first block's rows from `first` on; returns where they end.
fn parameter_rows(
    problem: &Problem,
    layout: &Layout,
    first: usize,
    rows: &mut Vec<(usize, usize)>,
) -> usize {
    let mut offset = first;
    for (k, slot) in layout.parameter_slot.iter().enumerate() {
        if let Some(s) = slot {
            let o = layout.slot_offset(*s);
            for (i, &c) in layout.parameter_free[k].iter().enumerate() {
                rows.push((offset + c, o + i));
            }
        }
        offset += problem.parameters[k].tangent_dim();
    }
    offset
}

/// The `n × n` covariance `s02 · q` on `rows` (row in the covariance, row in the reduced
/// system); zero elsewhere (held components).
fn covariance_of(
    rows: &[(usize, usize)],
    n: usize,
    s02: f64,
    q: &dyn CofactorLookup,
) -> DMatrix<f64> {
    let reduced: Vec<usize> = rows.iter().map(|&(_, r)| r).collect();
    let sub = q.restricted(&reduced);
    let mut cov = DMatrix::zeros(n, n);
    for (x, &(a, _)) in rows.iter().enumerate() {
        for (y, &(b, _)) in rows.iter().enumerate() {
            cov[(a, b)] = s02 * sub[(x, y)];
        }
    }
    cov
}

/// Each rig's `(δω, δt)` covariance ([`Precision::rig_covariances`]) from the cofactors `q`
/// of the reduced system.
pub(crate) fn rig_covariances(
    layout: &Layout,
    s02: f64,
    q: impl Fn(usize, usize) -> f64,
) -> Vec<Option<Matrix6<f64>>> {
    layout
        .rig_slot
        .iter()
        .map(|slot| {
            let o = layout.slot_offset((*slot)?);
            Some(Matrix6::from_fn(|a, b| s02 * q(o + a, o + b)))
        })
        .collect()
}

/// Standard deviations of every free pose: rotation about the camera axes and the
/// projection centre C = −Rᵀt, whose derivative with respect to (δω, δt) is
/// `[−Rᵀ[t]×, −Rᵀ]`.
pub(crate) fn pose_sigmas(
    problem: &Problem,
    layout: &Layout,
    s02: f64,
    q: impl Fn(usize, usize) -> f64,
) -> Vec<Option<PoseSigma>> {
    problem
        .images
        .iter()
        .enumerate()
        .map(|(i, im)| {
            let o = layout.slot_offset(layout.image_slot[i]?);
            if let Some(axes) = &layout.image_centre_axes[i] {
                // (δω, δC): the centre's σ directly, 0 for a held coordinate.
                let mut centre = [0.0; 3];
                for (k, &a) in axes.iter().enumerate() {
                    centre[a] = (s02 * q(o + 3 + k, o + 3 + k)).max(0.0).sqrt();
                }
                return Some(PoseSigma {
                    rotation_rad: std::array::from_fn(|a| (s02 * q(o + a, o + a)).max(0.0).sqrt()),
                    centre,
                });
            }
            let qq = DMatrix::from_fn(6, 6, |a, b| s02 * q(o + a, o + b));
            let rt = im.camera_from_object.rotation.transpose();
            let jw = -(rt * pingcal_geometry::skew(&im.camera_from_object.translation));
            let mut j = DMatrix::<f64>::zeros(3, 6);
            for a in 0..3 {
                for b in 0..3 {
                    j[(a, b)] = jw[(a, b)];
                    j[(a, 3 + b)] = -rt[(a, b)];
                }
            }
            let cc = &j * &qq * j.transpose();
            Some(PoseSigma {
                rotation_rad: [qq[(0, 0)].sqrt(), qq[(1, 1)].sqrt(), qq[(2, 2)].sqrt()],
                centre: [cc[(0, 0)].sqrt(), cc[(1, 1)].sqrt(), cc[(2, 2)].sqrt()],
            })
        })
        .collect()
}

/// The redundancy numbers and standardized residuals of every constraint, by kind
/// ([`split_constraint_redundancy`]).
pub(crate) struct ConstraintRedundancy {
    /// [`Precision::distance_redundancy_numbers`].
    pub distance_redundancy_numbers: Vec<f64>,
    /// [`Precision::distance_standardized`].
    pub distance_standardized: Vec<f64>,
    /// [`Precision::control_redundancy_numbers`].
    pub control_redundancy_numbers: Vec<[f64; 3]>,
    /// [`Precision::control_standardized`].
    pub control_standardized: Vec<[f64; 3]>,
    /// [`Precision::residual_redundancy_numbers`].
    pub residual_redundancy_numbers: Vec<Vec<f64>>,
    /// [`Precision::residual_standardized`].
    pub residual_standardized: Vec<Vec<f64>>,
}

/// From every constraint's redundancy numbers `q` (in the order of
/// [`Problem::constraints`]): those of the distances, the control points and
/// [`Problem::residuals`], each with its standardized residuals `r / √q_vv` (whitened: the
/// residual over its σ; NaN where the component has no redundancy).
pub(crate) fn split_constraint_redundancy(
    problem: &Problem,
    lin: &Linearization,
    q: Vec<Vec<f64>>,
) -> ConstraintRedundancy {
    let standardized: Vec<Vec<f64>> = (q.iter().zip(&lin.constraints))
        .map(|(qv, c)| {
            (qv.iter().zip(&c.r))
                .map(|(&q, &r)| if q > 1e-9 { r / q.sqrt() } else { f64::NAN })
                .collect()
        })
        .collect();
    let nd = problem.distances.len();
    let first_residual = nd + problem.point_priors.len();
    let three = |v: &Vec<f64>| -> [f64; 3] { std::array::from_fn(|k| v[k]) };
    ConstraintRedundancy {
        distance_redundancy_numbers: q[..nd].iter().map(|v| v[0]).collect(),
        distance_standardized: standardized[..nd].iter().map(|v| v[0]).collect(),
        control_redundancy_numbers: q[nd..first_residual].iter().map(three).collect(),
        control_standardized: standardized[nd..first_residual].iter().map(three).collect(),
        residual_standardized: standardized[first_residual..].to_vec(),
        residual_redundancy_numbers: q[first_residual..].to_vec(),
    }
}
