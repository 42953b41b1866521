//! Rigid and similarity transforms, named by the frames they join.
//!
//! [`Rigid3`] `a_from_b` maps coordinates of frame `b` into frame `a`: `x_a = R x_b + t`.
//! [`Sim3`] adds a scale: `x_a = s R x_b + t`. Name the variable after its frames
//! (`camera_from_object`, `camera_from_lrf`); `compose` then chains by name:
//! `a_from_c = a_from_b.compose(&b_from_c)`.
//!
//! An image's exterior orientation is a `Rigid3` `camera_from_object`; its projection
//! centre in object space is [`Rigid3::centre`] `C = −Rᵀ t`. Which camera axis is the
//! optical axis is the camera model's business (BAL looks down −z; the photogrammetric
//! model of docs/formats.md looks along +Y).

use crate::opk::to_opk_deg;
use crate::so3::{exp_so3, orthonormalize};
use nalgebra::{Matrix3, Matrix4, Vector3};

/// A rigid transform `x_a = R · x_b + t` (name values `a_from_b`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid3 {
    /// Rotation `a_from_b` (proper, orthonormal).
    pub rotation: Matrix3<f64>,
    /// Translation: the origin of frame `b` in frame `a`.
    pub translation: Vector3<f64>,
}

impl Default for Rigid3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Rigid3 {
    /// The identity.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// From its rotation and translation.
    pub fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation,
        }
    }

    /// `a_from_b` from its rotation and the origin of frame `a` written in frame `b` (for
    /// `camera_from_object`: the projection centre `C` in object space), `t = −R C`.
    pub fn from_rotation_and_centre(rotation: Matrix3<f64>, centre: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation: -(rotation * centre),
        }
    }

    /// The `camera_from_object` of a camera at `centre` whose optical axis points at
    /// `target`, rolled by `roll` (radians, positive turns the image's right towards its
    /// up) about that axis, in the camera frame of docs/formats.md (X right, Y along the optical
    /// axis, Z up): with `roll = 0` the image's up is the object's +Z (or +Y when looking
    /// straight up or down). The rows of the rotation are the camera's axes in object
    /// space.
    pub fn looking_at(centre: Vector3<f64>, target: Vector3<f64>, roll: f64) -> Self {
        let fwd = (target - centre).normalize();
        let up_world = if fwd.cross(&Vector3::z()).norm() < 1e-6 {
            Vector3::y()
        } else {
            Vector3::z()
        };
        let right = fwd.cross(&up_world).normalize();
        let up = right.cross(&fwd);
        let (s, c) = roll.sin_cos();
        let right_r = right * c + up * s;
        let up_r = up * c - right * s;
        let r = Matrix3::from_rows(&[right_r.transpose(), fwd.transpose(), up_r.transpose()]);
        Self::from_rotation_and_centre(r, centre)
    }

    /// The origin of frame `a` written in frame `b`, `C = −Rᵀ t` (the projection centre of
    /// a `camera_from_object`).
    pub fn centre(&self) -> Vector3<f64> {
        -(self.rotation.transpose() * self.translation)
    }

    /// Maps a point of frame `b` into frame `a`.
    #[inline]
    pub fn transform(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * x + self.translation
    }

    /// The inverse, `b_from_a`.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Composition `a_from_c = self (a_from_b) ∘ other (b_from_c)`:
    /// `self.compose(other).transform(x) = self.transform(&other.transform(x))`.
    pub fn compose(&self, other: &Rigid3) -> Self {
        Self {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The solver's local update `δ = (δω, δt)`: `R ← exp([δω]×) R`, `t ← t + δt` (δω in
    /// radians about the axes of frame `a`). A non-finite rotation update is ignored.
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

    /// ω, φ, κ of the rotation in degrees, in pingcal's one convention ([`crate::opk`]).
    pub fn opk_deg(&self) -> [f64; 3] {
        to_opk_deg(&self.rotation)
    }

    /// The homogeneous 4×4 matrix `[R t; 0 1]`.
    pub fn to_matrix(&self) -> Matrix4<f64> {
        Sim3::from(*self).to_matrix()
    }
}

fn orthonormalize_if_drifted(r: Matrix3<f64>) -> Matrix3<f64> {
    if (r.transpose() * r - Matrix3::identity()).norm() > 1e-12 {
        orthonormalize(&r)
    } else {
        r
    }
}

/// A similarity transform `x_a = s · R · x_b + t` (name values `a_from_b`); with `s = 1` a
/// rigid transform, as the paper's 3D conformal transform (eq. 1) usually is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sim3 {
    /// Rotation `a_from_b` (proper, orthonormal).
    pub rotation: Matrix3<f64>,
    /// Translation: the origin of frame `b` in frame `a`.
    pub translation: Vector3<f64>,
    /// Scale (1 for a rigid transform).
    pub scale: f64,
}

impl Default for Sim3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl From<Rigid3> for Sim3 {
    fn from(r: Rigid3) -> Self {
        Self {
            rotation: r.rotation,
            translation: r.translation,
            scale: 1.0,
        }
    }
}

impl Sim3 {
    /// The identity.
    pub fn identity() -> Self {
        Self::from(Rigid3::identity())
    }

    /// From its parts.
    pub fn new(scale: f64, rotation: Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Self {
            rotation,
            translation,
            scale,
        }
    }

    /// Maps a point of frame `b` into frame `a`.
    #[inline]
    pub fn transform(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * x * self.scale + self.translation
    }

    /// The rotation and translation, the scale dropped (exact for a rigid transform).
    pub fn rigid(&self) -> Rigid3 {
        Rigid3::new(self.rotation, self.translation)
    }

    /// The inverse, `b_from_a`: `x_b = (1/s) Rᵀ (x_a − t)`.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        let s = 1.0 / self.scale;
        Self {
            rotation: rt,
            translation: -(rt * self.translation) * s,
            scale: s,
        }
    }

    /// Composition `a_from_c = self (a_from_b) ∘ other (b_from_c)`.
    pub fn compose(&self, other: &Sim3) -> Self {
        Self {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation * self.scale + self.translation,
            scale: self.scale * other.scale,
        }
    }

    /// ω, φ, κ of the rotation in degrees, in pingcal's one convention ([`crate::opk`]).
    pub fn opk_deg(&self) -> [f64; 3] {
        to_opk_deg(&self.rotation)
    }

    /// The homogeneous 4×4 matrix `[sR t; 0 1]`.
    pub fn to_matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.rotation * self.scale));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::opk::from_opk;

    fn a_from_b() -> Sim3 {
        Sim3::new(1.3, from_opk(0.2, -0.5, 1.0), Vector3::new(10.0, -4.0, 2.5))
    }

    #[test]
    fn compose_and_inverse_chain_by_frame_names() {
        let a_from_b = a_from_b();
        let b_from_c = Sim3::new(0.7, from_opk(-1.0, 0.3, 0.1), Vector3::new(-1.0, 2.0, 3.0));
        let x_c = Vector3::new(0.3, 4.0, -2.0);
        let a_from_c = a_from_b.compose(&b_from_c);
        let direct = a_from_b.transform(&b_from_c.transform(&x_c));
        assert!((a_from_c.transform(&x_c) - direct).norm() < 1e-12);
        let back = a_from_c.inverse().transform(&direct);
        assert!((back - x_c).norm() < 1e-12);
        let m = a_from_c.to_matrix() * x_c.push(1.0);
        assert!((m.xyz() - direct).norm() < 1e-12);
    }

    #[test]
    fn rigid_centre_is_the_origin_of_the_target_frame() {
        let camera_from_object = a_from_b().rigid();
        let c = camera_from_object.centre();
        assert!(camera_from_object.transform(&c).norm() < 1e-12);
        let again = Rigid3::from_rotation_and_centre(camera_from_object.rotation, c);
        assert!((again.translation - camera_from_object.translation).norm() < 1e-12);
        let id = camera_from_object.compose(&camera_from_object.inverse());
        assert!(
            (id.rotation - Matrix3::identity()).norm() < 1e-14 && id.translation.norm() < 1e-12
        );
    }

    #[test]
    fn looking_at_points_the_optical_axis_and_keeps_up() {
        let (c, t) = (
            Vector3::new(100.0, -200.0, 50.0),
            Vector3::new(400.0, 900.0, -80.0),
        );
        let p = Rigid3::looking_at(c, t, 0.0);
        let dir = p.transform(&t);
        assert!(dir.x.abs() < 1e-9 && dir.z.abs() < 1e-9 && dir.y > 0.0);
        // the object's up is in the camera's Y-Z plane, upwards
        let up = p.rotation * Vector3::z();
        assert!(up.x.abs() < 1e-12 && up.z > 0.0);
        // a quarter roll turns the image's right into its up
        let q = Rigid3::looking_at(c, t, std::f64::consts::FRAC_PI_2);
        assert!((q.rotation.row(0) - p.rotation.row(2)).norm() < 1e-12);
        assert!((p.rotation.determinant() - 1.0).abs() < 1e-12);
        let down = Rigid3::looking_at(c, c - Vector3::z(), 0.0);
        assert!(down.rotation.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn plus_is_a_left_perturbation() {
        let p = a_from_b().rigid();
        let q = p.plus(&[1e-3, -2e-3, 0.5e-3, 1.0, 2.0, 3.0]);
        let expected = exp_so3(&Vector3::new(1e-3, -2e-3, 0.5e-3)) * p.rotation;
        assert!((q.rotation - expected).norm() < 1e-14);
        assert!((q.translation - p.translation - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-14);
        let r = p.plus(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(r.rotation, p.rotation);
    }
}
