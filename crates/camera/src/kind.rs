//! The models a project names (`[[cameras]] model = "…"`), as one closed set: each kind
//! builds its [`CameraModel`] for a sensor, names its parameters in their slice order, and
//! says which are in pixels and which in millimetres.

use super::{
    BrownBackwardCamera, CameraModel, DoubleSphereCamera, FisheyeCamera, OpenCvCamera,
    PhotogrammetricCamera,
};
use std::sync::Arc;

/// A camera model a project, a results file or an export can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ModelKind {
    /// The photogrammetric (Australis, forward Brown) model: c, xp, yp, K1–K3, P1, P2,
    /// B1, B2 in mm on the sensor.
    Photogrammetric,
    /// The Brown model as a correction of the measured point (DBAT, PhotoModeler): the same
    /// ten parameters.
    BrownBackward,
    /// OpenCV's pinhole model with the rational radial distortion (k1–k6), tangential (p1,
    /// p2) and thin-prism (s1–s4) terms, in pixels.
    OpenCv,
    /// Kannala–Brandt, equidistant with k1–k4 (OpenCV's `fisheye`, Kalibr's
    /// `pinhole-equi`), in pixels.
    KannalaBrandt,
    /// The double-sphere model (Usenko et al. 2018, Kalibr's `ds`), in pixels: lenses
    /// beyond 180°.
    DoubleSphere,
}

impl ModelKind {
    /// Every kind, in the order of [`Self::NAMES`].
    pub const ALL: [ModelKind; 5] = [
        ModelKind::Photogrammetric,
        ModelKind::BrownBackward,
        ModelKind::OpenCv,
        ModelKind::KannalaBrandt,
        ModelKind::DoubleSphere,
    ];

    /// The names files use, in the order of [`Self::ALL`].
    pub const NAMES: [&'static str; 5] = [
        "photogrammetric",
        "brown-backward",
        "opencv",
        "kannala-brandt",
        "double-sphere",
    ];

    /// The name files use.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// The kind named `word` (one of [`Self::NAMES`]).
    pub fn from_name(word: &str) -> Option<Self> {
        Self::NAMES
            .iter()
            .position(|n| *n == word)
            .map(|k| Self::ALL[k])
    }

    /// The model of a sensor of `width × height` pixels of pitch `pixel_size_mm` (the
    /// photogrammetric models need the sensor; the others work in pixels and ignore it).
    pub fn model(self, width: u32, height: u32, pixel_size_mm: f64) -> Arc<dyn CameraModel> {
        match self {
            ModelKind::Photogrammetric => {
                Arc::new(PhotogrammetricCamera::new(width, height, pixel_size_mm))
            }
            ModelKind::BrownBackward => {
                Arc::new(BrownBackwardCamera::new(width, height, pixel_size_mm))
            }
            ModelKind::OpenCv => Arc::new(OpenCvCamera),
            ModelKind::KannalaBrandt => Arc::new(FisheyeCamera),
            ModelKind::DoubleSphere => Arc::new(DoubleSphereCamera),
        }
    }

    /// Its parameters' names, in slice order.
    pub fn parameter_names(self) -> &'static [&'static str] {
        match self {
            ModelKind::Photogrammetric => &super::PHOTOGRAMMETRIC_PARAMS,
            ModelKind::BrownBackward => &super::BROWN_BACKWARD_PARAMS,
            ModelKind::OpenCv => &super::OPENCV_PARAMS,
            ModelKind::KannalaBrandt => &super::FISHEYE_PARAMS,
            ModelKind::DoubleSphere => &super::DOUBLE_SPHERE_PARAMS,
        }
    }

    /// Whether its parameters are in millimetres on the sensor (the photogrammetric
    /// models) rather than in pixels.
    pub fn in_mm(self) -> bool {
        matches!(self, ModelKind::Photogrammetric | ModelKind::BrownBackward)
    }

    /// Parameters of a lens of focal length `focal_px` (pixels) centred on a `width ×
    /// height` image of pitch `pixel_size_mm`: a start for a calibration that knows only
    /// the focal length. No distortion, but for the double sphere ξ = −0.2, α = ½: near the
    /// values fitted to lenses of 180–200° and able to image everything in front of the
    /// lens and beside it (its field is 2 × 180°), so that every point a real fisheye sees
    /// projects at the start (ξ = 0, α = ½, the stereographic projection, is a singular
    /// point of the model: there ∂D/∂ξ = D, so ξ and the two focal lengths are not
    /// separable from any data).
    pub fn nominal(self, focal_px: f64, width: u32, height: u32, pixel_size_mm: f64) -> Vec<f64> {
        let (cx, cy) = (0.5 * (width as f64 - 1.0), 0.5 * (height as f64 - 1.0));
        let mut p = vec![0.0; self.parameter_names().len()];
        match self {
            ModelKind::Photogrammetric | ModelKind::BrownBackward => {
                p[0] = focal_px * pixel_size_mm;
            }
            ModelKind::OpenCv | ModelKind::KannalaBrandt => {
                p[..4].copy_from_slice(&[focal_px, focal_px, cx, cy]);
            }
            ModelKind::DoubleSphere => {
                // the scale on the axis is f/(1 + ξ)
                let (xi, alpha) = (-0.2, 0.5);
                let f = focal_px * (1.0 + xi);
                p.copy_from_slice(&[f, f, cx, cy, xi, alpha]);
            }
        }
        p
    }
}

impl ModelKind {
    /// The parameters a network separates, as functions of the model's own, for judging
    /// their correlations: for the double sphere the image scales on the axis fx/(1 + ξ),
    /// fy/(1 + ξ) in place of fx, fy (ξ and the focal lengths move together: a change of ξ
    /// is mostly a change of scale), for the others the parameters themselves. Over the
    /// parameters named `names` (a subset of the model's, with `values` all of the
    /// model's), the Jacobian ∂new/∂old, row-major `names.len()` × `names.len()`.
    pub fn separable_jacobian(self, values: &[f64], names: &[&str]) -> Vec<Vec<f64>> {
        let n = names.len();
        let mut j: Vec<Vec<f64>> = (0..n)
            .map(|a| (0..n).map(|b| f64::from(u8::from(a == b))).collect())
            .collect();
        if self != ModelKind::DoubleSphere {
            return j;
        }
        let at = |name: &str| names.iter().position(|n| *n == name);
        let Some(k_xi) = at("xi") else {
            return j;
        };
        let xi = values[4];
        for (name, idx) in [("fx", 0), ("fy", 1)] {
            if let Some(k) = at(name) {
                j[k][k] = 1.0 / (1.0 + xi);
                j[k][k_xi] = -values[idx] / ((1.0 + xi) * (1.0 + xi));
            }
        }
        j
    }
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
