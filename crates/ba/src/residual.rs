//! Residual kinds beside the image observations: one trait, so that a kind of observation
//! is added in one place and the solver never knows what it means.
//!
//! The image observations are the adjustment's own kind: the Schur complement is built on
//! them (each touches one point, which is eliminated). Every other observation — a measured
//! distance, a weighted control point, a weighted pose prior, a laser beam on a sphere — is
//! a [`Residual`]: a whitened residual vector `r(x)` of [`Residual::dim`] components (already
//! divided by its σ, so that the adjustment minimises ½ Σ |r|²), the parameter [`Block`]s it
//! depends on, and its analytic Jacobian `∂r/∂δ` with respect to each block's local update δ.
//! The models are Ceres' cost functions and factrs' residuals.
//!
//! **Blocks and their updates.** A [`Block::Point`] (3: `X ← X + δ`), an image's pose
//! [`Block::Pose`] (6: the solver's left update `δ = (δω, δt)`, `R ← exp([δω]×) R`,
//! `t ← t + δt`, [`pingcal_geometry::Rigid3::plus`]) and a [`Block::Parameter`] of the
//! problem's own [`ParameterBlock`]s (an extrinsic, a sensor's mount, a plane): a
//! [`ParameterValue::Vector`] is updated additively, a [`ParameterValue::Pose`] as an image
//! pose. The Jacobian is always with respect to the whole local update; the solver keeps the
//! columns of what is free (a vector's components can be held one by one).
//!
//! **Where the solver puts them.** A residual that depends on a single point and nothing
//! else (a control point) adds to that point's 3 × 3 block, which is still eliminated by the
//! Schur complement; a point that a residual couples to anything else joins the reduced
//! system, as do the parameter blocks. Its precision, redundancy numbers and the variance
//! component of its [`Residual::group`] come from the same normal equations as everything
//! else.
//!
//! A new kind is checked with [`check_residual_jacobians`] (central differences through the
//! same updates the solver applies).

use nalgebra::{DMatrix, Vector3};
use pingcal_geometry::{exp_so3, log_so3, skew, Rigid3};
use std::sync::Arc;

pub use crate::keys::{ImageKey, ParameterKey, PointKey};

/// A parameter block a [`Residual`] depends on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Block {
    /// Object point.
    Point(PointKey),
    /// An image's exterior orientation; not a rig member's, whose pose follows its base
    /// image.
    Pose(ImageKey),
    /// One of the problem's own parameter blocks.
    Parameter(ParameterKey),
}

impl std::fmt::Display for Block {
    /// As error messages name it: `point 12`, `image 3's pose`, `parameter block 1`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Block::Point(k) => write!(f, "point {}", k.0),
            Block::Pose(k) => write!(f, "image {}'s pose", k.0),
            Block::Parameter(k) => write!(f, "parameter block {}", k.0),
        }
    }
}

/// The current value of a [`Block`], as the residual sees it.
#[derive(Clone, Copy, Debug)]
pub enum Value<'a> {
    /// A point's coordinates.
    Point(&'a Vector3<f64>),
    /// A pose (an image's `camera_from_object`, or a pose parameter block).
    Pose(&'a Rigid3),
    /// A vector parameter block.
    Vector(&'a [f64]),
}

impl<'a> Value<'a> {
    /// The point, if this is one.
    pub fn point(&self) -> Option<&'a Vector3<f64>> {
        match self {
            Value::Point(x) => Some(x),
            _ => None,
        }
    }

    /// The pose, if this is one.
    pub fn pose(&self) -> Option<&'a Rigid3> {
        match self {
            Value::Pose(p) => Some(p),
            _ => None,
        }
    }

    /// The vector, if this is one.
    pub fn vector(&self) -> Option<&'a [f64]> {
        match self {
            Value::Vector(v) => Some(v),
            _ => None,
        }
    }

    /// Dimension of the local update.
    pub fn tangent_dim(&self) -> usize {
        match self {
            Value::Point(_) => 3,
            Value::Pose(_) => 6,
            Value::Vector(v) => v.len(),
        }
    }
}

/// The Jacobian blocks a residual fills when asked: one matrix per block of
/// [`Residual::blocks`], in that order, each `dim × the block's tangent size` (3 for a point,
/// 6 for a pose as (δω, δt), the parameter's length for a parameter); `None` when only the
/// residual is wanted.
pub type Jacobians<'a> = Option<&'a mut [DMatrix<f64>]>;

/// A kind of observation: see the module doc.
///
/// `evaluate` receives the values of [`Residual::blocks`] in their order and writes the
/// whitened residual; when `jacobians` is given it holds one `dim × tangent_dim` matrix per
/// block (zeroed), to be filled with `∂r/∂δ`. It returns `false` where the residual is not
/// defined at these values (a beam that misses its sphere); the solver then treats the step
/// that led there as failed.
pub trait Residual: Send + Sync + std::fmt::Debug {
    /// Number of residual components.
    fn dim(&self) -> usize;
    /// The blocks it depends on, each once.
    fn blocks(&self) -> Vec<Block>;
    /// The whitened residual and, if asked, its Jacobian blocks.
    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool;
    /// The group whose variance component it shares (e.g. "distances", "beams").
    fn group(&self) -> &str;
}

/// A residual of the problem beyond its typed kinds, with the factor its σ is multiplied by
/// (1 a priori; the variance-component estimation changes it).
#[derive(Clone, Debug)]
pub struct ResidualBlock {
    /// The residual.
    pub residual: Arc<dyn Residual>,
    /// σ factor: the solver divides the residual by it.
    pub sigma_scale: f64,
}

impl ResidualBlock {
    /// A residual at its a-priori weight.
    pub fn new(residual: impl Residual + 'static) -> Self {
        Self {
            residual: Arc::new(residual),
            sigma_scale: 1.0,
        }
    }
}

/// The value of a [`ParameterBlock`].
#[derive(Clone, Debug, PartialEq)]
pub enum ParameterValue {
    /// Updated additively; components can be held one by one.
    Vector(Vec<f64>),
    /// A rigid transform, updated as an image pose (6: δω, δt).
    Pose(Rigid3),
}

/// A parameter block of the problem's own (an extrinsic, a mount, a plane).
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterBlock {
    /// Name used in reports and messages.
    pub name: String,
    /// Its value, updated in place by the solver.
    pub value: ParameterValue,
    /// Per component of the local update: held fixed.
    pub fixed: Vec<bool>,
}

impl ParameterBlock {
    /// A free vector block.
    pub fn vector(name: impl Into<String>, values: Vec<f64>) -> Self {
        let n = values.len();
        Self {
            name: name.into(),
            value: ParameterValue::Vector(values),
            fixed: vec![false; n],
        }
    }

    /// A free pose block.
    pub fn pose(name: impl Into<String>, pose: Rigid3) -> Self {
        Self {
            name: name.into(),
            value: ParameterValue::Pose(pose),
            fixed: vec![false; 6],
        }
    }

    /// Dimension of the local update.
    pub fn tangent_dim(&self) -> usize {
        match &self.value {
            ParameterValue::Vector(v) => v.len(),
            ParameterValue::Pose(_) => 6,
        }
    }

    /// The value as a residual sees it.
    pub fn as_value(&self) -> Value<'_> {
        match &self.value {
            ParameterValue::Vector(v) => Value::Vector(v),
            ParameterValue::Pose(p) => Value::Pose(p),
        }
    }

    /// Indices of the free components of the local update.
    pub fn free_indices(&self) -> Vec<usize> {
        (0..self.tangent_dim())
            .filter(|&k| !self.fixed[k])
            .collect()
    }

    /// Applies a local update of the full tangent dimension.
    pub fn plus(&mut self, delta: &[f64]) {
        match &mut self.value {
            ParameterValue::Vector(v) => v.iter_mut().zip(delta).for_each(|(a, d)| *a += d),
            ParameterValue::Pose(p) => *p = p.plus(delta),
        }
    }
}

/// A weighted prior on an image's pose (a GNSS/INS position and attitude, or a pose from an
/// earlier adjustment): `r = (log(R R₀ᵀ) / σ_ω, (C − C₀) / σ_C)` with `C = −Rᵀt` the projection
/// centre, so that the position is the centre's and the attitude the rotation's. σ_ω in
/// radians (per axis of the object frame's rotation vector), σ_C in object units; an infinite
/// σ leaves that component free.
#[derive(Clone, Debug, PartialEq)]
pub struct PosePrior {
    /// The image.
    pub image: ImageKey,
    /// The prior `camera_from_object`.
    pub camera_from_object: Rigid3,
    /// σ of the rotation vector's components (radians).
    pub sigma_rotation: Vector3<f64>,
    /// σ of the projection centre's coordinates (object units).
    pub sigma_centre: Vector3<f64>,
}

impl Residual for PosePrior {
    fn dim(&self) -> usize {
        6
    }
    fn blocks(&self) -> Vec<Block> {
        vec![Block::Pose(self.image)]
    }
    /// With the left update `R ← exp([δω]×) R`, `t ← t + δt`:
    /// `∂ log(R R₀ᵀ)/∂δω = J_l⁻¹(φ)` (φ = log(R R₀ᵀ), J_l the left Jacobian of SO(3)), and
    /// `C(δ) = −Rᵀ exp(−[δω]×)(t + δt)` gives `∂C/∂δω = −Rᵀ [t]×` and `∂C/∂δt = −Rᵀ`.
    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let Some(pose) = values[0].pose() else {
            return false;
        };
        let phi = log_so3(&(pose.rotation * self.camera_from_object.rotation.transpose()));
        let c = pose.centre();
        let c0 = self.camera_from_object.centre();
        let w = |s: f64| if s.is_finite() { 1.0 / s } else { 0.0 };
        for k in 0..3 {
            residual[k] = phi[k] * w(self.sigma_rotation[k]);
            residual[3 + k] = (c[k] - c0[k]) * w(self.sigma_centre[k]);
        }
        if let Some(j) = jacobians {
            let jr = left_jacobian_inverse(&phi);
            let rt = pose.rotation.transpose();
            let dc_dw = -(rt * skew(&pose.translation));
            for a in 0..3 {
                for b in 0..3 {
                    j[0][(a, b)] = jr[(a, b)] * w(self.sigma_rotation[a]);
                    j[0][(3 + a, b)] = dc_dw[(a, b)] * w(self.sigma_centre[a]);
                    j[0][(3 + a, 3 + b)] = -rt[(a, b)] * w(self.sigma_centre[a]);
                }
            }
        }
        true
    }
    fn group(&self) -> &str {
        "pose priors"
    }
}

/// A weighted prior on some components of a vector parameter block (a weak prior that makes
/// the normal equations regular while estimability is tested, or a calibrated value with
/// its σ): `r_i = (v[c_i] − value_i) / σ_i` for each listed component `c_i`.
#[derive(Clone, Debug, PartialEq)]
pub struct ParameterPrior {
    /// The parameter block (a [`ParameterValue::Vector`]).
    pub parameter: ParameterKey,
    /// The components it constrains.
    pub components: Vec<usize>,
    /// Their prior values.
    pub value: Vec<f64>,
    /// Their σ's.
    pub sigma: Vec<f64>,
}

impl Residual for ParameterPrior {
    fn dim(&self) -> usize {
        self.components.len()
    }
    fn blocks(&self) -> Vec<Block> {
        vec![Block::Parameter(self.parameter)]
    }
    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let Some(v) = values[0].vector() else {
            return false;
        };
        if self.components.iter().any(|&c| c >= v.len())
            || self.value.len() != self.components.len()
            || self.sigma.len() != self.components.len()
        {
            return false;
        }
        for (i, &c) in self.components.iter().enumerate() {
            residual[i] = (v[c] - self.value[i]) / self.sigma[i];
        }
        if let Some(j) = jacobians {
            for (i, &c) in self.components.iter().enumerate() {
                j[0][(i, c)] = 1.0 / self.sigma[i];
            }
        }
        true
    }
    fn group(&self) -> &str {
        "parameter priors"
    }
}

/// `J_l⁻¹(φ) = I − ½[φ]× + (1/θ² − (1 + cos θ)/(2θ sin θ)) [φ]×²`, θ = |φ| (series below 1e-5).
pub fn left_jacobian_inverse(phi: &Vector3<f64>) -> nalgebra::Matrix3<f64> {
    let theta = phi.norm();
    let k = skew(phi);
    let c = if theta < 1e-5 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    nalgebra::Matrix3::identity() - 0.5 * k + c * k * k
}

/// The worst relative difference between `residual`'s analytic Jacobian at `values` and
/// central differences of step `h` through the same local updates the solver applies (a
/// pose by [`Rigid3::plus`]); `|a − n| / max(1, |n|)` per entry. None where the residual is
/// not defined at `values` or at a step.
pub fn check_residual_jacobians(residual: &dyn Residual, values: &[Value], h: f64) -> Option<f64> {
    let m = residual.dim();
    let mut r = vec![0.0; m];
    let mut jac: Vec<DMatrix<f64>> = values
        .iter()
        .map(|v| DMatrix::zeros(m, v.tangent_dim()))
        .collect();
    if !residual.evaluate(values, &mut r, Some(&mut jac)) {
        return None;
    }
    let mut worst = 0.0f64;
    for (b, v) in values.iter().enumerate() {
        for k in 0..v.tangent_dim() {
            let at = |sign: f64| -> Option<Vec<f64>> {
                let mut d = vec![0.0; v.tangent_dim()];
                d[k] = sign * h;
                let (point, pose, vector);
                let moved = match v {
                    Value::Point(x) => {
                        point = *x + Vector3::from_column_slice(&d);
                        Value::Point(&point)
                    }
                    Value::Pose(p) => {
                        pose = perturbed(p, &d);
                        Value::Pose(&pose)
                    }
                    Value::Vector(x) => {
                        vector = x.iter().zip(&d).map(|(a, b)| a + b).collect::<Vec<_>>();
                        Value::Vector(&vector)
                    }
                };
                let mut vals = values.to_vec();
                vals[b] = moved;
                let mut out = vec![0.0; m];
                residual.evaluate(&vals, &mut out, None).then_some(out)
            };
            let (plus, minus) = (at(1.0)?, at(-1.0)?);
            for row in 0..m {
                let n = (plus[row] - minus[row]) / (2.0 * h);
                let a = jac[b][(row, k)];
                worst = worst.max((a - n).abs() / n.abs().max(1.0));
            }
        }
    }
    Some(worst)
}

/// `p.plus(d)` without the drift re-orthonormalisation's threshold mattering for tiny steps.
fn perturbed(p: &Rigid3, d: &[f64]) -> Rigid3 {
    Rigid3 {
        rotation: exp_so3(&Vector3::new(d[0], d[1], d[2])) * p.rotation,
        translation: p.translation + Vector3::new(d[3], d[4], d[5]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::{Distance, PointPrior};
    use pingcal_geometry::from_opk_deg;

    #[test]
    fn built_in_kinds_have_the_jacobians_of_central_differences() {
        let a = Vector3::new(1.0, 2.0, 3.0);
        let b = Vector3::new(-0.5, 0.7, 2.2);
        let d = Distance {
            a: PointKey(0),
            b: PointKey(1),
            value: 2.0,
            sigma: 0.01,
        };
        let e = check_residual_jacobians(&d, &[Value::Point(&a), Value::Point(&b)], 1e-6);
        assert!(e.unwrap() < 1e-6, "distance {e:?}");
        let pr = PointPrior {
            point: PointKey(0),
            position: Vector3::new(1.1, 1.9, 3.05),
            sigma: Vector3::new(0.01, 0.02, 0.03),
        };
        let e = check_residual_jacobians(&pr, &[Value::Point(&a)], 1e-6);
        assert!(e.unwrap() < 1e-6, "prior {e:?}");
        let pose = Rigid3::new(
            from_opk_deg([10.0, -20.0, 35.0]),
            Vector3::new(0.3, -1.0, 4.0),
        );
        let pp = PosePrior {
            image: ImageKey(0),
            camera_from_object: Rigid3::new(
                from_opk_deg([10.5, -19.0, 34.0]),
                Vector3::new(0.25, -1.1, 4.2),
            ),
            sigma_rotation: Vector3::new(0.001, 0.002, 0.001),
            sigma_centre: Vector3::new(0.01, 0.01, f64::INFINITY),
        };
        let e = check_residual_jacobians(&pp, &[Value::Pose(&pose)], 1e-5);
        assert!(e.unwrap() < 1e-6, "pose prior {e:?}");
        let prior = ParameterPrior {
            parameter: ParameterKey(0),
            components: vec![2, 0],
            value: vec![1.0, -3.0],
            sigma: vec![0.5, 2.0],
        };
        let v = [0.3, 0.2, 1.7];
        let e = check_residual_jacobians(&prior, &[Value::Vector(&v)], 1e-6);
        assert!(e.unwrap() < 1e-6, "parameter prior {e:?}");
    }
}
