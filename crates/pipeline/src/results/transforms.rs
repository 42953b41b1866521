//! The transforms of `results.json`: each written as R and t, a 4×4 matrix, a unit
//! quaternion and again in OpenCV's camera frame (`p_cv = C · p`, C =
//! [`cv_from_photogrammetric`]), with the σ's of the extrinsic and of the stereo rig.

use crate::adjust::rig_cameras;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use pingcal_geometry::to_opk;
use pingcal_geometry::{Rigid3, Sim3};
use pingcal_project::Project;
use serde::Serialize;

/// The extrinsic as `results.json` writes it.
#[derive(Clone, Debug, Serialize)]
pub struct ExtrinsicJson {
    /// R (row-major), `p_camera = R · p_lrf + t`.
    pub rotation: [[f64; 3]; 3],
    /// t (mm).
    pub translation_mm: [f64; 3],
    /// σ of t (mm); null for the corner baseline (it gives none).
    pub sigma_translation_mm: Option<[f64; 3]>,
    /// σ of ω, φ, κ (degrees).
    pub sigma_rotation_deg: Option<[f64; 3]>,
    /// ω, φ, κ (degrees), R = R_ω R_φ R_κ.
    pub opk_deg: [f64; 3],
    /// `[[R, t], [0, 0, 0, 1]]` (row-major, t in mm).
    pub matrix_4x4: [[f64; 4]; 4],
    /// R as a unit quaternion (x, y, z, w), w ≥ 0.
    pub quaternion_xyzw: [f64; 4],
    /// The same transform into OpenCV's camera frame: `p_cv = R_cv · p_lrf + t_cv`.
    pub opencv: TransformJson,
}

/// A rigid transform `p_to = R · p_from + t` in the forms other programs read.
#[derive(Clone, Debug, Serialize)]
pub struct TransformJson {
    /// R (row-major).
    pub rotation: [[f64; 3]; 3],
    /// t (mm).
    pub translation_mm: [f64; 3],
    /// σ of t (mm), where known.
    pub sigma_translation_mm: Option<[f64; 3]>,
    /// `[[R, t], [0, 0, 0, 1]]` (row-major, t in mm).
    pub matrix_4x4: [[f64; 4]; 4],
    /// R as a unit quaternion (x, y, z, w), w ≥ 0.
    pub quaternion_xyzw: [f64; 4],
}

/// The stereo rig.
#[derive(Clone, Debug, Serialize)]
pub struct RigJson {
    /// R (row-major), `p_right = R · p_left + t`.
    pub rotation: [[f64; 3]; 3],
    /// t (mm).
    pub translation_mm: [f64; 3],
    /// Baseline length (mm).
    pub baseline_mm: f64,
    /// The left camera's id.
    pub left: String,
    /// The right camera's id.
    pub right: String,
    /// `[[R, t], [0, 0, 0, 1]]` (row-major, t in mm).
    pub matrix_4x4: [[f64; 4]; 4],
    /// R as a unit quaternion (x, y, z, w), w ≥ 0.
    pub quaternion_xyzw: [f64; 4],
    /// The same rig in OpenCV's camera frames (`stereoCalibrate`'s R and T).
    pub opencv: TransformJson,
    /// σ of the small rotations of R about the right camera's axes, degrees, from the
    /// bundle's covariance (None: the rig was held or had no precision).
    pub sigma_rotation_deg: Option<[f64; 3]>,
    /// σ of t (mm, as `translation_mm`).
    pub sigma_translation_mm: Option<[f64; 3]>,
}

/// A 3×3 matrix as rows.
pub(super) fn mat(r: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
        [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
        [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
    ]
}

/// C, from the photogrammetric camera frame (X right, Y forward, Z up) to OpenCV's (x
/// right, y down, z forward): `p_cv = C · p = (X, −Z, Y)` (docs/formats.md, "Frames").
pub fn cv_from_photogrammetric() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0)
}

/// `[[R, t], [0, 0, 0, 1]]`, row-major.
pub fn matrix_4x4(r: &Matrix3<f64>, t: &Vector3<f64>) -> [[f64; 4]; 4] {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().take(3).enumerate() {
        *row = [r[(i, 0)], r[(i, 1)], r[(i, 2)], t[i]];
    }
    m[3][3] = 1.0;
    m
}

/// The unit quaternion (x, y, z, w) of the rotation `r` (Hamilton, active: it rotates a
/// vector as `r` does), with w ≥ 0.
pub fn quaternion_xyzw(r: &Matrix3<f64>) -> [f64; 4] {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.i, s * q.j, s * q.k, s * q.w]
}

/// `p_to = r · p_from + t` in [`TransformJson`]'s forms.
pub fn transform_json(
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    sigma_t: Option<[f64; 3]>,
) -> TransformJson {
    TransformJson {
        rotation: mat(r),
        translation_mm: [t.x, t.y, t.z],
        sigma_translation_mm: sigma_t,
        matrix_4x4: matrix_4x4(r, t),
        quaternion_xyzw: quaternion_xyzw(r),
    }
}

/// The extrinsic `p_camera = R · p_lrf + t` as `results.json` writes it; in OpenCV's frame
/// `R_cv = C R`, `t_cv = C t`, and σ of t_cv is σ of t permuted (C only permutes axes and
/// flips a sign).
pub fn extrinsic_json(
    t: &Sim3,
    sigma_t: Option<[f64; 3]>,
    sigma_r: Option<[f64; 3]>,
) -> ExtrinsicJson {
    let (o, p, k) = to_opk(&t.rotation);
    let c = cv_from_photogrammetric();
    ExtrinsicJson {
        rotation: mat(&t.rotation),
        translation_mm: [t.translation.x, t.translation.y, t.translation.z],
        sigma_translation_mm: sigma_t,
        sigma_rotation_deg: sigma_r,
        opk_deg: [o.to_degrees(), p.to_degrees(), k.to_degrees()],
        matrix_4x4: matrix_4x4(&t.rotation, &t.translation),
        quaternion_xyzw: quaternion_xyzw(&t.rotation),
        opencv: transform_json(
            &(c * t.rotation),
            &(c * t.translation),
            sigma_t.map(|s| [s[0], s[2], s[1]]),
        ),
    }
}

/// The rig `p_right = R · p_left + t` (`left`, `right`: the cameras' ids); in OpenCV's
/// frames `R_cv = C R Cᵀ`, `t_cv = C t`.
pub fn rig_json(right_from_left: &Rigid3, left: &str, right: &str) -> RigJson {
    let (r, t) = (&right_from_left.rotation, &right_from_left.translation);
    let c = cv_from_photogrammetric();
    RigJson {
        rotation: mat(r),
        translation_mm: [t.x, t.y, t.z],
        baseline_mm: right_from_left.centre().norm(),
        left: left.into(),
        right: right.into(),
        matrix_4x4: matrix_4x4(r, t),
        quaternion_xyzw: quaternion_xyzw(r),
        opencv: transform_json(&(c * r * c.transpose()), &(c * t), None),
        sigma_rotation_deg: None,
        sigma_translation_mm: None,
    }
}

/// The Jacobian of the inverse of `m` (`(Rᵀ, −Rᵀ t)`) in its update `(δω, δt)`
/// ([`Rigid3::plus`]) with respect to `m`'s: `exp(δω)R` inverts to `exp(−Rᵀδω) Rᵀ`, and
/// `−Rᵀ exp(−δω)(t + δt) ≈ −Rᵀ t − Rᵀ δt − Rᵀ [t]× δω`.
pub(super) fn inverse_update_jacobian(m: &Rigid3) -> nalgebra::Matrix6<f64> {
    let rt = m.rotation.transpose();
    let mut j = nalgebra::Matrix6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-rt));
    j.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(-rt * pingcal_geometry::skew(&m.translation)));
    j.fixed_view_mut::<3, 3>(3, 3).copy_from(&(-rt));
    j
}

/// The rig of the bundle adjustment (base → member camera frame, the base being the main
/// camera's side) as left → right, with its σ from `cov` (the bundle's covariance of the
/// rig's update, [`pingcal_ba::solver::Precision::rig_covariances`]).
pub(super) fn rig_of(
    project: &Project,
    member_from_base: &Rigid3,
    cov: Option<&nalgebra::Matrix6<f64>>,
) -> Option<RigJson> {
    let st = project.file.stereo.as_ref()?;
    let (base, _) = rig_cameras(project)?;
    let (right_from_left, cov) = if base == st.left {
        (*member_from_base, cov.copied())
    } else {
        let j = inverse_update_jacobian(member_from_base);
        (
            member_from_base.inverse(),
            cov.map(|c| j * c * j.transpose()),
        )
    };
    let mut json = rig_json(&right_from_left, &st.left, &st.right);
    if let Some(c) = cov {
        let sd = |k: usize| c[(k, k)].max(0.0).sqrt();
        json.sigma_rotation_deg = Some([0, 1, 2].map(|k| sd(k).to_degrees()));
        json.sigma_translation_mm = Some([3, 4, 5].map(sd));
    }
    Some(json)
}
