//! The scene of a bundle adjustment: cameras (intrinsics shared by all their images),
//! images (exterior orientation), object points, and image observations.
//!
//! Everything the solver may change lives here and is updated in place by
//! [`crate::solver::solve`]; what is held fixed is said here too.

use crate::camera::CameraModel;
use crate::keys::{CameraKey, ImageKey, ParameterKey, PointKey};
use crate::loss::Loss;
use crate::residual::{
    Block, Jacobians, ParameterBlock, ParameterValue, Residual, ResidualBlock, Value,
};
use nalgebra::{Vector2, Vector3};
use pingcal_geometry::Rigid3;
use std::sync::Arc;

/// A physical camera: its model, intrinsic parameter values and which are held fixed.
#[derive(Clone, Debug)]
pub struct Camera {
    /// Name used in reports (e.g. "left").
    pub name: String,
    /// The camera model.
    pub model: Arc<dyn CameraModel>,
    /// Intrinsic parameter values, in the model's order.
    pub params: Vec<f64>,
    /// `true` for each parameter held fixed.
    pub fixed: Vec<bool>,
}

impl Camera {
    /// A camera with all intrinsics free.
    pub fn new(name: impl Into<String>, model: Arc<dyn CameraModel>, params: Vec<f64>) -> Self {
        let n = params.len();
        Self {
            name: name.into(),
            model,
            params,
            fixed: vec![false; n],
        }
    }

    /// Holds every intrinsic fixed.
    pub fn fix_all(mut self) -> Self {
        self.fixed.iter_mut().for_each(|f| *f = true);
        self
    }

    /// Indices of the free intrinsics.
    pub fn free_indices(&self) -> Vec<usize> {
        (0..self.params.len()).filter(|&k| !self.fixed[k]).collect()
    }
}

/// One photograph: which camera took it and from where.
#[derive(Clone, Debug)]
pub struct Image {
    /// Name used in reports (e.g. the file name).
    pub name: String,
    /// The camera.
    pub camera: CameraKey,
    /// Exterior orientation: object → camera (`x_cam = R·X + t`).
    pub camera_from_object: Rigid3,
    /// Pose held fixed.
    pub fixed: bool,
    /// Coordinates of the projection centre `C = −Rᵀt` held one by one, `[X, Y, Z]` (the
    /// rotation stays free); `fixed` holds the whole pose whatever these say. Such an image
    /// is adjusted in the unknowns `(δω, δC)` — `R ← exp([δω]×) R`, `C ← C + δC`,
    /// `t = −R C` — of which the held coordinates of δC are not unknowns at all. Not for a
    /// rig member (its pose follows its base image).
    pub fixed_centre: [bool; 3],
}

impl Image {
    /// Some centre coordinates held (and the pose not fixed as a whole).
    pub fn is_centre_held(&self) -> bool {
        !self.fixed && self.fixed_centre.iter().any(|h| *h)
    }

    /// Indices (0 = X, 1 = Y, 2 = Z) of the free centre coordinates, in order.
    pub fn free_centre_axes(&self) -> Vec<usize> {
        (0..3).filter(|&k| !self.fixed_centre[k]).collect()
    }
}

/// An object point.
#[derive(Clone, Debug)]
pub struct Point {
    /// Name used in reports (target number, ball label).
    pub name: String,
    /// Object-space coordinates.
    pub position: Vector3<f64>,
    /// Held fixed (e.g. a fixed control point): all three coordinates.
    pub fixed: bool,
    /// Coordinates held one by one, `[X, Y, Z]` (e.g. only the height of a levelled point,
    /// or single coordinates of a minimal datum); `fixed` holds all three whatever these
    /// say. A held coordinate is not an unknown: its step is exactly 0, its σ is 0.
    pub fixed_axes: [bool; 3],
}

impl Point {
    /// A point with every coordinate free.
    pub fn new(name: impl Into<String>, position: Vector3<f64>) -> Self {
        Self {
            name: name.into(),
            position,
            fixed: false,
            fixed_axes: [false; 3],
        }
    }

    /// Per coordinate (X, Y, Z): held, by `fixed` or by `fixed_axes`.
    pub fn held(&self) -> [bool; 3] {
        std::array::from_fn(|k| self.fixed || self.fixed_axes[k])
    }

    /// All three coordinates held: the point is no unknown at all.
    pub fn is_held(&self) -> bool {
        self.held().iter().all(|h| *h)
    }

    /// Some coordinates held and some free.
    pub fn is_partly_held(&self) -> bool {
        let h = self.held();
        h.iter().any(|x| *x) && !h.iter().all(|x| *x)
    }

    /// Indices (0 = X, 1 = Y, 2 = Z) of the free coordinates, in order.
    pub fn free_axes(&self) -> Vec<usize> {
        let h = self.held();
        (0..3).filter(|&k| !h[k]).collect()
    }
}

/// An image measurement of a point, with its standard deviation in pixels.
#[derive(Clone, Copy, Debug)]
pub struct Observation {
    /// The image.
    pub image: ImageKey,
    /// The point.
    pub point: PointKey,
    /// Measured pixel coordinates.
    pub uv: Vector2<f64>,
    /// Standard deviation of each coordinate, pixels.
    pub sigma: f64,
}

/// A measured distance between two object points (a caliper-measured scale bar), an
/// observation equation `|X_a − X_b| − value` with standard deviation `sigma`, in the
/// object-space unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Distance {
    /// One end.
    pub a: PointKey,
    /// The other end.
    pub b: PointKey,
    /// Measured distance.
    pub value: f64,
    /// Its standard deviation.
    pub sigma: f64,
}

/// A weighted control point: an observation `X − position` of a point's coordinates with
/// a standard deviation per axis (a fixed control point is a [`Point`] with `fixed`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointPrior {
    /// The point.
    pub point: PointKey,
    /// Measured coordinates.
    pub position: Vector3<f64>,
    /// Standard deviation of each coordinate.
    pub sigma: Vector3<f64>,
}

/// A camera rig (e.g. a stereo head): the relative pose between its cameras is the same at
/// every station. A member image's pose is `member_from_base ∘ base image's pose`
/// ([`Rig::member_from_base`] maps the base camera's frame into the member camera's frame);
/// the member's own [`Image::camera_from_object`] is kept equal to that composition by the
/// solver, and its `fixed` flag is ignored.
#[derive(Clone, Debug)]
pub struct Rig {
    /// Name used in reports (e.g. "stereo").
    pub name: String,
    /// Base camera frame → member camera frame.
    pub member_from_base: Rigid3,
    /// Held fixed (a calibrated rig).
    pub fixed: bool,
    /// Member images and their base images (same station).
    pub members: Vec<RigMember>,
}

/// One image whose pose follows a base image through a [`Rig`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RigMember {
    /// The member image (e.g. the right image of a station).
    pub image: ImageKey,
    /// The base image of the same station (e.g. the left image).
    pub base: ImageKey,
}

/// A bundle-adjustment problem.
#[derive(Clone, Debug, Default)]
pub struct Problem {
    /// Cameras (intrinsics).
    pub cameras: Vec<Camera>,
    /// Images (poses).
    pub images: Vec<Image>,
    /// Object points.
    pub points: Vec<Point>,
    /// Image observations.
    pub observations: Vec<Observation>,
    /// Robust loss applied to every image observation.
    pub loss: Loss,
    /// Measured distances between points (observation equations, not a rescaling).
    pub distances: Vec<Distance>,
    /// Weighted control points.
    pub point_priors: Vec<PointPrior>,
    /// Camera rigs (relative orientation constraints between images of one station).
    pub rigs: Vec<Rig>,
    /// Parameter blocks of the problem's own (an extrinsic, a sensor's mount), on which
    /// [`Problem::residuals`] may depend.
    pub parameters: Vec<ParameterBlock>,
    /// Observations of further kinds ([`crate::residual`]): weighted pose priors, or a kind
    /// defined outside this crate.
    pub residuals: Vec<ResidualBlock>,
}

/// Why a problem cannot be adjusted as given.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProblemError {
    /// The problem has no observations.
    #[error("the problem has no observations")]
    NoObservations,
    /// An observation refers to an image that does not exist.
    #[error("observation {index} refers to image {image}, but there are only {count} images")]
    UnknownImage {
        /// The observation: 0-based index into [`Problem::observations`].
        index: usize,
        /// The image it names: 0-based index into [`Problem::images`].
        image: usize,
        /// How many images the problem has.
        count: usize,
    },
    /// An observation refers to a point that does not exist.
    #[error("observation {index} refers to point {point}, but there are only {count} points")]
    UnknownPoint {
        /// The observation: 0-based index into [`Problem::observations`].
        index: usize,
        /// The point it names: 0-based index into [`Problem::points`].
        point: usize,
        /// How many points the problem has.
        count: usize,
    },
    /// An image refers to a camera that does not exist.
    #[error("image '{name}' refers to camera {camera}, but there are only {count} cameras")]
    UnknownCamera {
        /// The image's [`Image::name`].
        name: String,
        /// The camera it names: 0-based index into [`Problem::cameras`].
        camera: usize,
        /// How many cameras the problem has.
        count: usize,
    },
    /// A camera's parameter count does not match its model.
    #[error("camera '{name}' has {got} parameters, its model '{model}' takes {expected}")]
    ParameterCount {
        /// The camera's [`Camera::name`].
        name: String,
        /// The model's name ([`CameraModel::name`]).
        model: &'static str,
        /// Length of [`Camera::params`] (also reported when only [`Camera::fixed`] has the
        /// wrong length).
        got: usize,
        /// The number of parameters the model takes ([`CameraModel::num_params`]).
        expected: usize,
    },
    /// A value is NaN or infinite.
    #[error("{what} is not a finite number")]
    NotFinite {
        /// Which value, in words (e.g. "the pose of image 'IMG_0001.JPG'").
        what: String,
    },
    /// An observation's σ is not positive.
    #[error("observation {index} has σ = {sigma}, expected a positive number")]
    BadSigma {
        /// The observation: 0-based index into [`Problem::observations`].
        index: usize,
        /// Its [`Observation::sigma`], pixels.
        sigma: f64,
    },
    /// The loss scale is not positive.
    #[error("the robust loss scale must be positive and finite")]
    BadLoss,
    /// A distance or control point refers to a point that does not exist.
    #[error("{what} refers to point {point}, but there are only {count} points")]
    UnknownPointIn {
        /// The distance or control point, in words (e.g. "distance 2", "control point 0",
        /// numbered from 0 in [`Problem::distances`] / [`Problem::point_priors`]).
        what: String,
        /// The point it names: 0-based index into [`Problem::points`].
        point: usize,
        /// How many points the problem has.
        count: usize,
    },
    /// A distance or control observation is unusable.
    #[error("{0}")]
    BadConstraint(
        /// What is wrong, naming the distance, control point, rig or observation concerned.
        String,
    ),
    /// A point is not imaged by the camera model at the current estimate.
    #[error("point '{point}' cannot be projected into image '{image}' (behind the camera?)")]
    NotProjectable {
        /// The point's [`Point::name`].
        point: String,
        /// The image's [`Image::name`].
        image: String,
    },
}

impl Problem {
    /// Checks indices, counts and values; the solver calls it before anything else.
    pub fn validate(&self) -> Result<(), ProblemError> {
        if self.observations.is_empty() {
            return Err(ProblemError::NoObservations);
        }
        if !self.loss.is_valid() {
            return Err(ProblemError::BadLoss);
        }
        self.validate_unknowns()?;
        self.validate_observations()?;
        self.validate_distances()?;
        let member_of = self.validate_rigs()?;
        self.validate_point_priors()?;
        self.validate_residuals(&member_of)
    }

    /// Every camera's parameter count, every image's camera, the values finite.
    fn validate_unknowns(&self) -> Result<(), ProblemError> {
        for c in &self.cameras {
            let expected = c.model.num_params();
            if c.params.len() != expected || c.fixed.len() != expected {
                return Err(ProblemError::ParameterCount {
                    name: c.name.clone(),
                    model: c.model.name(),
                    got: c.params.len(),
                    expected,
                });
            }
            if !c.params.iter().all(|v| v.is_finite()) {
                return Err(ProblemError::NotFinite {
                    what: format!("an intrinsic of camera '{}'", c.name),
                });
            }
        }
        for im in &self.images {
            if im.camera.0 >= self.cameras.len() {
                return Err(ProblemError::UnknownCamera {
                    name: im.name.clone(),
                    camera: im.camera.0,
                    count: self.cameras.len(),
                });
            }
            let p = &im.camera_from_object;
            if !p
                .rotation
                .iter()
                .chain(p.translation.iter())
                .all(|v| v.is_finite())
            {
                return Err(ProblemError::NotFinite {
                    what: format!("the pose of image '{}'", im.name),
                });
            }
        }
        for pt in &self.points {
            if !pt.position.iter().all(|v| v.is_finite()) {
                return Err(ProblemError::NotFinite {
                    what: format!("point '{}'", pt.name),
                });
            }
        }
        Ok(())
    }

    /// Every observation's image and point exist, its σ positive, its values finite.
    fn validate_observations(&self) -> Result<(), ProblemError> {
        for (index, o) in self.observations.iter().enumerate() {
            if o.image.0 >= self.images.len() {
                return Err(ProblemError::UnknownImage {
                    index,
                    image: o.image.0,
                    count: self.images.len(),
                });
            }
            if o.point.0 >= self.points.len() {
                return Err(ProblemError::UnknownPoint {
                    index,
                    point: o.point.0,
                    count: self.points.len(),
                });
            }
            if !(o.sigma > 0.0 && o.sigma.is_finite()) {
                return Err(ProblemError::BadSigma {
                    index,
                    sigma: o.sigma,
                });
            }
            if !o.uv.iter().all(|v| v.is_finite()) {
                return Err(ProblemError::NotFinite {
                    what: format!("observation {index}"),
                });
            }
        }
        Ok(())
    }

    /// Every distance joins two different points with a positive value and σ.
    fn validate_distances(&self) -> Result<(), ProblemError> {
        let np = self.points.len();
        for (k, d) in self.distances.iter().enumerate() {
            for p in [d.a, d.b] {
                if p.0 >= np {
                    return Err(ProblemError::UnknownPointIn {
                        what: format!("distance {k}"),
                        point: p.0,
                        count: np,
                    });
                }
            }
            if d.a == d.b {
                return Err(ProblemError::BadConstraint(format!(
                    "distance {k} joins point '{}' to itself",
                    self.points[d.a].name
                )));
            }
            if !(d.value > 0.0 && d.value.is_finite() && d.sigma > 0.0 && d.sigma.is_finite()) {
                return Err(ProblemError::BadConstraint(format!(
                    "distance {k} ('{}'–'{}'): value {} and σ {} must be positive and finite",
                    self.points[d.a].name, self.points[d.b].name, d.value, d.sigma
                )));
            }
        }
        Ok(())
    }

    /// The rigs' members and bases: existing images, each a member once, no base a member,
    /// no member holding its centre; which images are members.
    fn validate_rigs(&self) -> Result<Vec<bool>, ProblemError> {
        let mut member_of = vec![false; self.images.len()];
        for rig in &self.rigs {
            for m in &rig.members {
                if m.image.0 >= self.images.len() || m.base.0 >= self.images.len() {
                    return Err(ProblemError::BadConstraint(format!(
                        "rig '{}' refers to image {} but there are only {} images",
                        rig.name,
                        m.image.max(m.base),
                        self.images.len()
                    )));
                }
                if m.image == m.base || member_of[m.image.0] {
                    return Err(ProblemError::BadConstraint(format!(
                        "rig '{}': image '{}' is its own base or a member twice",
                        rig.name, self.images[m.image].name
                    )));
                }
                member_of[m.image.0] = true;
            }
        }
        if let Some(i) = (0..self.images.len())
            .find(|&i| member_of[i] && self.images[i].fixed_centre.iter().any(|h| *h))
        {
            return Err(ProblemError::BadConstraint(format!(
                "image '{}' holds centre coordinates but is a rig member, whose pose follows its base image: hold the base image's centre",
                self.images[i].name
            )));
        }
        for rig in &self.rigs {
            if let Some(m) = rig.members.iter().find(|m| member_of[m.base.0]) {
                return Err(ProblemError::BadConstraint(format!(
                    "rig '{}': base image '{}' is itself a rig member",
                    rig.name, self.images[m.base].name
                )));
            }
        }
        Ok(member_of)
    }

    /// Every control point's point exists, its coordinates finite and σ positive.
    fn validate_point_priors(&self) -> Result<(), ProblemError> {
        let np = self.points.len();
        for (k, c) in self.point_priors.iter().enumerate() {
            if c.point.0 >= np {
                return Err(ProblemError::UnknownPointIn {
                    what: format!("control point {k}"),
                    point: c.point.0,
                    count: np,
                });
            }
            if !(c.position.iter().all(|v| v.is_finite())
                && c.sigma.iter().all(|s| *s > 0.0 && s.is_finite()))
            {
                return Err(ProblemError::BadConstraint(format!(
                    "control point '{}': coordinates must be finite and σ positive",
                    self.points[c.point].name
                )));
            }
        }
        Ok(())
    }

    /// Checks the parameter blocks and that every residual's blocks exist (a pose not a rig
    /// member's) and are listed once.
    fn validate_residuals(&self, member_of: &[bool]) -> Result<(), ProblemError> {
        for pb in &self.parameters {
            let finite = match &pb.value {
                ParameterValue::Vector(v) => v.iter().all(|x| x.is_finite()),
                ParameterValue::Pose(p) => (p.rotation.iter())
                    .chain(p.translation.iter())
                    .all(|x| x.is_finite()),
            };
            if !finite {
                return Err(ProblemError::NotFinite {
                    what: format!("parameter block '{}'", pb.name),
                });
            }
            if pb.fixed.len() != pb.tangent_dim() {
                return Err(ProblemError::BadConstraint(format!(
                    "parameter block '{}' has {} fixed flags for {} parameters",
                    pb.name,
                    pb.fixed.len(),
                    pb.tangent_dim()
                )));
            }
        }
        let mut used = vec![false; self.parameters.len()];
        for (k, rb) in self.residuals.iter().enumerate() {
            let what = || format!("residual {k} ({})", rb.residual.group());
            let blocks = rb.residual.blocks();
            if rb.residual.dim() == 0 || blocks.is_empty() {
                return Err(ProblemError::BadConstraint(format!(
                    "{} has no components or no blocks",
                    what()
                )));
            }
            if !(rb.sigma_scale > 0.0 && rb.sigma_scale.is_finite()) {
                return Err(ProblemError::BadConstraint(format!(
                    "{}: σ factor {} must be positive and finite",
                    what(),
                    rb.sigma_scale
                )));
            }
            for (i, b) in blocks.iter().enumerate() {
                if blocks[..i].contains(b) {
                    return Err(ProblemError::BadConstraint(format!(
                        "{} lists {b} twice",
                        what()
                    )));
                }
                let (exists, count) = match *b {
                    Block::Point(PointKey(p)) => (p < self.points.len(), self.points.len()),
                    Block::Pose(ImageKey(i)) => (i < self.images.len(), self.images.len()),
                    Block::Parameter(ParameterKey(q)) => {
                        (q < self.parameters.len(), self.parameters.len())
                    }
                };
                if !exists {
                    return Err(ProblemError::BadConstraint(format!(
                        "{} refers to {b}, but there are only {count}",
                        what()
                    )));
                }
                if let Block::Parameter(ParameterKey(q)) = *b {
                    used[q] = true;
                }
                if let Block::Pose(ImageKey(i)) = *b {
                    if member_of[i] {
                        return Err(ProblemError::BadConstraint(format!(
                            "{} is on the pose of rig member '{}', which follows its base image: put it on the base image",
                            what(),
                            self.images[i].name
                        )));
                    }
                }
            }
        }
        if let Some(pb) = (self.parameters.iter().zip(&used))
            .find(|(pb, used)| !**used && pb.fixed.iter().any(|f| !f))
            .map(|(pb, _)| pb)
        {
            return Err(ProblemError::BadConstraint(format!(
                "parameter block '{}' is free but no residual depends on it: hold it or remove it",
                pb.name
            )));
        }
        Ok(())
    }

    /// Every observation beside the image points, as the solver sees it: the distances, the
    /// control points, then [`Problem::residuals`], each with its σ factor.
    pub fn constraints(&self) -> impl Iterator<Item = (&dyn Residual, f64)> + '_ {
        let distances = self.distances.iter().map(|d| (d as &dyn Residual, 1.0));
        let priors = self.point_priors.iter().map(|p| (p as &dyn Residual, 1.0));
        let rest = (self.residuals.iter()).map(|r| (&*r.residual, r.sigma_scale));
        distances.chain(priors).chain(rest)
    }

    /// Sets every rig member's pose to `member_from_base ∘ base pose`.
    pub fn sync_rigs(&mut self) {
        for rig in &self.rigs {
            for m in &rig.members {
                self.images[m.image].camera_from_object = rig
                    .member_from_base
                    .compose(&self.images[m.base].camera_from_object);
            }
        }
    }

    /// Reprojection residual (predicted − measured, pixels) of one observation, or `None`
    /// if the point does not project.
    pub fn residual(&self, o: &Observation) -> Option<Vector2<f64>> {
        let im = &self.images[o.image];
        let cam = &self.cameras[im.camera];
        let xc = im
            .camera_from_object
            .transform(&self.points[o.point].position);
        cam.model
            .project(&cam.params, &xc, None, None)
            .map(|uv| uv - o.uv)
    }

    /// RMS of the reprojection residuals in pixels (over both coordinates of every
    /// observation that projects).
    pub fn rms_px(&self) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for o in &self.observations {
            if let Some(r) = self.residual(o) {
                s += r.norm_squared();
                n += 2;
            }
        }
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    }
}

impl Residual for Distance {
    fn dim(&self) -> usize {
        1
    }
    fn blocks(&self) -> Vec<Block> {
        vec![Block::Point(self.a), Block::Point(self.b)]
    }
    /// `(|X_a − X_b| − value) / σ`; ∂/∂X_a = uᵀ/σ (u the unit vector from b to a), ∂/∂X_b its
    /// negative.
    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let (Some(a), Some(b)) = (values[0].point(), values[1].point()) else {
            return false;
        };
        let v = a - b;
        let l = v.norm();
        residual[0] = (l - self.value) / self.sigma;
        if let Some(j) = jacobians {
            let u = if l > 0.0 { v / l } else { Vector3::zeros() };
            let g = u / self.sigma;
            for k in 0..3 {
                j[0][(0, k)] = g[k];
                j[1][(0, k)] = -g[k];
            }
        }
        true
    }
    fn group(&self) -> &str {
        "distances"
    }
}

impl Residual for PointPrior {
    fn dim(&self) -> usize {
        3
    }
    fn blocks(&self) -> Vec<Block> {
        vec![Block::Point(self.point)]
    }
    /// `(X − position) / σ` per axis.
    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let Some(x) = values[0].point() else {
            return false;
        };
        for k in 0..3 {
            residual[k] = (x[k] - self.position[k]) / self.sigma[k];
        }
        if let Some(j) = jacobians {
            for k in 0..3 {
                j[0][(k, k)] = 1.0 / self.sigma[k];
            }
        }
        true
    }
    fn group(&self) -> &str {
        "control"
    }
}

impl Problem {
    /// Appends a camera and returns its key.
    pub fn add_camera(&mut self, camera: Camera) -> CameraKey {
        self.cameras.push(camera);
        CameraKey(self.cameras.len() - 1)
    }

    /// Appends an image and returns its key.
    pub fn add_image(&mut self, image: Image) -> ImageKey {
        self.images.push(image);
        ImageKey(self.images.len() - 1)
    }

    /// Appends an object point and returns its key.
    pub fn add_point(&mut self, point: Point) -> PointKey {
        self.points.push(point);
        PointKey(self.points.len() - 1)
    }

    /// Appends a parameter block and returns its key.
    pub fn add_parameter(&mut self, block: ParameterBlock) -> ParameterKey {
        self.parameters.push(block);
        ParameterKey(self.parameters.len() - 1)
    }
}

/// `problem[key]`, `problem.points[key]`, `images[key]` …: a block by its key, in the
/// problem or in a slice of blocks of that kind (and only of that kind).
macro_rules! keyed {
    ($key:ty, $block:ty, $field:ident) => {
        impl std::ops::Index<$key> for Problem {
            type Output = $block;
            fn index(&self, k: $key) -> &$block {
                &self.$field[k.0]
            }
        }
        impl std::ops::IndexMut<$key> for Problem {
            fn index_mut(&mut self, k: $key) -> &mut $block {
                &mut self.$field[k.0]
            }
        }
        impl std::ops::Index<$key> for [$block] {
            type Output = $block;
            fn index(&self, k: $key) -> &$block {
                &self[k.0]
            }
        }
        impl std::ops::IndexMut<$key> for [$block] {
            fn index_mut(&mut self, k: $key) -> &mut $block {
                &mut self[k.0]
            }
        }
        impl std::ops::Index<$key> for Vec<$block> {
            type Output = $block;
            fn index(&self, k: $key) -> &$block {
                &self[k.0]
            }
        }
        impl std::ops::IndexMut<$key> for Vec<$block> {
            fn index_mut(&mut self, k: $key) -> &mut $block {
                &mut self[k.0]
            }
        }
    };
}

keyed!(PointKey, Point, points);
keyed!(ImageKey, Image, images);
keyed!(CameraKey, Camera, cameras);
keyed!(ParameterKey, ParameterBlock, parameters);

/// A residual of another problem whose own parameter blocks (from `base` on) stand `offset`
/// places later in the problem it is appended to ([`Problem::append_sensor`]); everything
/// else as the original.
#[derive(Debug)]
struct Shifted {
    inner: Arc<dyn Residual>,
    base: usize,
    offset: usize,
}

impl Residual for Shifted {
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    fn blocks(&self) -> Vec<Block> {
        (self.inner.blocks().into_iter())
            .map(|b| match b {
                Block::Parameter(k) if k.0 >= self.base => {
                    Block::Parameter(ParameterKey(k.0 + self.offset))
                }
                other => other,
            })
            .collect()
    }

    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        self.inner.evaluate(values, residual, jacobians)
    }

    fn group(&self) -> &str {
        self.inner.group()
    }
}

impl Problem {
    /// Appends what `other` adds to a problem both were built from (the first
    /// `base_parameters` parameter blocks and `base_residuals` residuals are that problem's,
    /// and its images, points and observations are this one's too): `other`'s further
    /// parameter blocks, and its further residuals with their σ factors, their parameter
    /// keys moved to follow this problem's blocks. Two sensors' adjustments of one bundle
    /// so become one problem (its covariance holds both sensors' cross terms). Returns the
    /// offset by which `other`'s keys beyond the base moved.
    pub fn append_sensor(
        &mut self,
        other: &Problem,
        base_parameters: usize,
        base_residuals: usize,
    ) -> usize {
        let offset = self.parameters.len() - base_parameters;
        self.parameters
            .extend(other.parameters[base_parameters..].iter().cloned());
        for r in &other.residuals[base_residuals..] {
            let moves = (r.residual.blocks().iter())
                .any(|b| matches!(b, Block::Parameter(k) if k.0 >= base_parameters));
            let residual: Arc<dyn Residual> = if moves && offset > 0 {
                Arc::new(Shifted {
                    inner: r.residual.clone(),
                    base: base_parameters,
                    offset,
                })
            } else {
                r.residual.clone()
            };
            self.residuals.push(ResidualBlock {
                residual,
                sigma_scale: r.sigma_scale,
            });
        }
        offset
    }
}

#[cfg(test)]
mod append_tests {
    use super::*;
    use crate::residual::ParameterPrior;

    fn with_sensor(base: &Problem, value: f64) -> Problem {
        let mut p = base.clone();
        let k = ParameterKey(p.parameters.len());
        p.parameters
            .push(ParameterBlock::vector("sensor", vec![value, 2.0 * value]));
        p.residuals.push(ResidualBlock {
            residual: Arc::new(ParameterPrior {
                parameter: k,
                components: vec![0, 1],
                value: vec![0.0, 0.0],
                sigma: vec![1.0, 4.0],
            }),
            sigma_scale: 3.0,
        });
        p
    }

    /// Two sensors' problems of one base become one: the second's block follows the
    /// first's, its residual reads it there (and keeps its σ factor), the first's is as it
    /// was; a base block stays where it is.
    #[test]
    fn a_second_sensors_blocks_follow_the_firsts() {
        let mut base = Problem::default();
        base.parameters
            .push(ParameterBlock::vector("shared", vec![7.0]));
        let (mut a, b) = (with_sensor(&base, 1.0), with_sensor(&base, 5.0));
        let offset = a.append_sensor(&b, 1, 0);
        assert_eq!((offset, a.parameters.len(), a.residuals.len()), (1, 3, 2));
        assert_eq!(
            a.residuals[0].residual.blocks(),
            vec![Block::Parameter(ParameterKey(1))]
        );
        let moved = &a.residuals[1];
        assert_eq!(
            moved.residual.blocks(),
            vec![Block::Parameter(ParameterKey(2))]
        );
        assert_eq!(moved.sigma_scale, 3.0);
        let ParameterValue::Vector(v) = &a.parameters[2].value else {
            panic!("a vector block")
        };
        let mut r = [0.0; 2];
        assert!(moved.residual.evaluate(&[Value::Vector(v)], &mut r, None));
        assert_eq!(r, [5.0, 10.0 / 4.0]);
    }
}
