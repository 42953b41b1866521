//! Exterior orientation: the rigid transform from object (world) space to a camera frame.

use crate::rotation::{exp_so3, orthonormalize};
use nalgebra::{Matrix3, Vector3};

/// A camera pose as the object-to-camera transform `x_cam = R · X + t`.
///
/// The projection centre in object space is `C = −Rᵀ t`. Which camera axis is the optical
/// axis is the camera model's business (BAL looks down −z; the photogrammetric model of
/// SPEC.md looks along +Y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Rotation object → camera.
    pub rotation: Matrix3<f64>,
    /// Translation (camera-frame coordinates of the object origin).
    pub translation: Vector3<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    /// The identity pose.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// A pose from its rotation and its projection centre `C` in object space.
    pub fn from_rotation_and_centre(rotation: Matrix3<f64>, centre: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation: -(rotation * centre),
        }
    }

    /// The projection centre in object space, `C = −Rᵀ t`.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.rotation.transpose() * self.translation)
    }

    /// Maps an object point into the camera frame.
    #[inline]
    pub fn transform(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * x + self.translation
    }

    /// The inverse transform (camera → object).
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Composition: `(self ∘ other)(x) = self(other(x))`.
    pub fn compose(&self, other: &Pose) -> Self {
        Self {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// Applies the solver's local update `δ = (δω, δt)`: `R ← exp(δω) R`, `t ← t + δt`.
    pub fn plus(&self, delta: &[f64]) -> Self {
        let dw = Vector3::new(delta[0], delta[1], delta[2]);
        let mut rotation = exp_so3(&dw) * self.rotation;
        if !rotation.iter().all(|v| v.is_finite()) {
            rotation = self.rotation;
        }
        Self {
            rotation: orthonormalize_if_drifted(rotation),
            translation: self.translation + Vector3::new(delta[3], delta[4], delta[5]),
        }
    }
}

fn orthonormalize_if_drifted(r: Matrix3<f64>) -> Matrix3<f64> {
    if (r.transpose() * r - Matrix3::identity()).norm() > 1e-12 {
        orthonormalize(&r)
    } else {
        r
    }
}
