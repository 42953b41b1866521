//! The registry of camera models: every model pingcal knows, one line each in [`REGISTRY`],
//! with everything the rest of pingcal asks of a model besides its projection — its name in
//! files, the keys of its parameters, whether they are in millimetres, whether a sphere's
//! silhouette under it is taken as an ellipse, which lenses it is for, its forms in other
//! ecosystems' files ([`super::forms`]), its start and the lens the simulator gives it.
//! Nothing outside `crates/camera` matches on a model: it asks [`ModelKind`], whose methods
//! read the model's line.
//!
//! Adding a model: its file (a [`CameraModel`]), a variant of [`ModelKind`] and its line in
//! [`REGISTRY`] (in the variant's position; a test checks the order and that every name
//! reads back).

use super::forms::{self, Ecosystem, Form, Source};
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

/// What lenses a model is meant for: the verdict's advice when a lens bends more than its
/// camera's model holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LensClass {
    /// A perspective projection with polynomial distortion, for ordinary lenses.
    Standard,
    /// A perspective projection for wide-angle lenses (suggested for one).
    WideAngle,
    /// Not a perspective projection: fisheyes, to 180° and beyond (suggested for one).
    Fisheye,
}

/// The lenses of the simulator's stereo head for a model (`pingcal simulate
/// --camera-model`), on its 1280 × 720 sensor of 3.75 µm pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleLens {
    /// What lens it is, in words.
    pub about: &'static str,
    /// The left camera's parameters, in the model's slice order.
    pub left: &'static [f64],
    /// The right camera's: a few tenths of a percent off the left's, as two lenses of one
    /// make.
    pub right: &'static [f64],
    /// The parameters a user of this lens holds at 0 (the terms it does not have).
    pub held: &'static [&'static str],
}

/// ∂(separable parameters)/∂(the model's) over the parameters named, given all the
/// model's values ([`ModelKind::separable_jacobian`]).
pub type SeparableJacobian = fn(&[f64], &[&str]) -> Vec<Vec<f64>>;

/// One model's line in the [`REGISTRY`].
#[derive(Clone, Copy)]
pub struct ModelEntry {
    /// The kind, in its position in the registry.
    pub kind: ModelKind,
    /// The name files use (`[[cameras]] model = "…"`, results.json, camera files).
    pub name: &'static str,
    /// Other words a camera file accepts for it (the ecosystems' own name).
    pub aliases: &'static [&'static str],
    /// Its parameters' names, in slice order (those of the [`CameraModel`] it builds).
    pub parameters: &'static [&'static str],
    /// Its parameters' keys in project and results files, in slice order.
    pub keys: &'static [&'static str],
    /// Whether its parameters are in millimetres on the sensor (rather than in pixels).
    pub in_mm: bool,
    /// Whether a ball's centre through it is taken from its silhouette's fitted ellipse
    /// (else from the cone fitted to the silhouette's edge points).
    pub silhouette_is_ellipse: bool,
    /// The lenses it is for.
    pub lens: LensClass,
    /// Whether its OpenCV pinhole form is the closed form of
    /// [`forms::opencv_of_photogrammetric`] (B1 to first order, B2 dropped).
    pub opencv_closed_form: bool,
    /// Builds its [`CameraModel`] for a sensor of width × height pixels of a pitch (mm).
    pub build: fn(u32, u32, f64) -> Arc<dyn CameraModel>,
    /// Its start from a focal length ([`ModelKind::nominal`]).
    pub nominal: fn(&mut [f64], f64, [f64; 4]),
    /// Its parameters' map to those a network separates, where they differ
    /// ([`ModelKind::separable_jacobian`]).
    pub separable: Option<SeparableJacobian>,
    /// What is wrong with a set of its parameter values that no lens can have, if anything.
    pub check: fn(&[f64]) -> Option<String>,
    /// Its forms in other ecosystems' files ([`forms::form`]).
    pub forms: fn(&Source, Ecosystem) -> Option<Form>,
    /// The simulator's lens of this model.
    pub sample: SampleLens,
}

/// Every model, in the order of [`ModelKind`]'s variants.
pub const REGISTRY: [ModelEntry; 5] = [
    ModelEntry {
        kind: ModelKind::Photogrammetric,
        name: "photogrammetric",
        aliases: &[],
        parameters: &super::PHOTOGRAMMETRIC_PARAMS,
        keys: &MM_KEYS,
        in_mm: true,
        silhouette_is_ellipse: true,
        lens: LensClass::Standard,
        opencv_closed_form: true,
        build: |w, h, pitch| Arc::new(PhotogrammetricCamera::new(w, h, pitch)),
        nominal: nominal_mm,
        separable: None,
        check: no_check,
        forms: forms::photogrammetric_forms,
        sample: SampleLens {
            about: "the MYNT EYE D1000's ~90° lens: K1 r² ≈ −15 % at the corner of its 1280 × 720 sensor of 3.75 µm pixels (r = 2.75 mm)",
            left: &[
                2.45, 0.012, -0.009, -0.021, 4.0e-4, -2.0e-6, 1.5e-4, -1.0e-4, 1.0e-4, 0.0,
            ],
            right: &[
                2.452, -0.010, 0.007, -0.020, 3.6e-4, -1.0e-6, -1.2e-4, 0.8e-4, -0.5e-4, 0.0,
            ],
            held: &[],
        },
    },
    ModelEntry {
        kind: ModelKind::BrownBackward,
        name: "brown-backward",
        aliases: &[],
        parameters: &super::BROWN_BACKWARD_PARAMS,
        keys: &MM_KEYS,
        in_mm: true,
        silhouette_is_ellipse: true,
        lens: LensClass::Standard,
        opencv_closed_form: false,
        build: |w, h, pitch| Arc::new(BrownBackwardCamera::new(w, h, pitch)),
        nominal: nominal_mm,
        separable: None,
        check: no_check,
        forms: forms::brown_backward_forms,
        sample: SampleLens {
            about: "the same ~90° lens, as a correction of the measured point",
            left: &[
                2.45, 0.012, -0.009, 0.021, -3.0e-4, 1.0e-6, -1.5e-4, 1.0e-4, 1.0e-4, 0.0,
            ],
            right: &[
                2.452, -0.010, 0.007, 0.020, -2.7e-4, 0.5e-6, 1.2e-4, -0.8e-4, -0.5e-4, 0.0,
            ],
            held: &[],
        },
    },
    ModelEntry {
        kind: ModelKind::OpenCv,
        name: "opencv",
        aliases: &[],
        parameters: &super::OPENCV_PARAMS,
        keys: &super::OPENCV_PARAMS,
        in_mm: false,
        silhouette_is_ellipse: false,
        lens: LensClass::WideAngle,
        opencv_closed_form: false,
        build: |_, _, _| Arc::new(OpenCvCamera),
        nominal: nominal_px,
        separable: None,
        check: no_check,
        forms: forms::opencv_forms,
        sample: SampleLens {
            about: "a 120° (horizontal) wide-angle lens, rational radial model",
            left: &[
                611.0, 611.3, 641.2, 358.9, 0.05, 0.0, 1.5e-4, -1.0e-4, 0.0, 0.3, 0.0, 0.0, 0.0,
                0.0, 0.0, 0.0,
            ],
            right: &[
                611.8, 611.6, 637.9, 361.4, 0.048, 0.0, -1.2e-4, 0.8e-4, 0.0, 0.297, 0.0, 0.0,
                0.0, 0.0, 0.0, 0.0,
            ],
            held: &["k2", "k3", "k5", "k6", "s1", "s2", "s3", "s4"],
        },
    },
    ModelEntry {
        kind: ModelKind::KannalaBrandt,
        name: "kannala-brandt",
        aliases: &["fisheye"],
        parameters: &super::FISHEYE_PARAMS,
        keys: &super::FISHEYE_PARAMS,
        in_mm: false,
        silhouette_is_ellipse: false,
        lens: LensClass::Fisheye,
        opencv_closed_form: false,
        build: |_, _, _| Arc::new(FisheyeCamera),
        nominal: nominal_px,
        separable: None,
        check: no_check,
        forms: forms::kannala_brandt_forms,
        sample: SampleLens {
            about: "a 190° fisheye",
            left: &[374.0, 374.2, 641.2, 358.9, 0.02, -0.005, 0.001, -1.0e-4],
            right: &[374.6, 374.5, 637.9, 361.4, 0.019, -0.0048, 0.0009, -0.9e-4],
            held: &[],
        },
    },
    ModelEntry {
        kind: ModelKind::DoubleSphere,
        name: "double-sphere",
        aliases: &[],
        parameters: &super::DOUBLE_SPHERE_PARAMS,
        keys: &super::DOUBLE_SPHERE_PARAMS,
        in_mm: false,
        silhouette_is_ellipse: false,
        lens: LensClass::Fisheye,
        opencv_closed_form: false,
        build: |_, _, _| Arc::new(DoubleSphereCamera),
        nominal: nominal_double_sphere,
        separable: Some(separable_double_sphere),
        check: check_double_sphere,
        forms: forms::double_sphere_forms,
        sample: SampleLens {
            about: "a 190° fisheye",
            left: &[317.0, 317.2, 641.2, 358.9, -0.2, 0.59],
            right: &[317.5, 317.4, 637.9, 361.4, -0.198, 0.591],
            held: &[],
        },
    },
];

/// The keys of the two photogrammetric models' parameters in files.
pub const MM_KEYS: [&str; 10] = [
    "c_mm", "xp_mm", "yp_mm", "k1", "k2", "k3", "p1", "p2", "b1", "b2",
];

/// A model in mm: the principal distance of `focal_px` on the sensor, nothing else.
fn nominal_mm(p: &mut [f64], focal_px: f64, [_, _, _, pixel_size_mm]: [f64; 4]) {
    p[0] = focal_px * pixel_size_mm;
}

/// A model in pixels: fx = fy = `focal_px`, the principal point at the image centre.
fn nominal_px(p: &mut [f64], focal_px: f64, [cx, cy, _, _]: [f64; 4]) {
    p[..4].copy_from_slice(&[focal_px, focal_px, cx, cy]);
}

/// The double sphere: ξ = −0.2, α = ½ and fx, fy such that the scale on the axis,
/// f/(1 + ξ), is `focal_px`.
fn nominal_double_sphere(p: &mut [f64], focal_px: f64, [cx, cy, _, _]: [f64; 4]) {
    let (xi, alpha) = (-0.2, 0.5);
    let f = focal_px * (1.0 + xi);
    p.copy_from_slice(&[f, f, cx, cy, xi, alpha]);
}

/// Any values.
fn no_check(_: &[f64]) -> Option<String> {
    None
}

/// The double sphere's α lies in [0, 1).
fn check_double_sphere(p: &[f64]) -> Option<String> {
    let alpha = p[5];
    (!(0.0..1.0).contains(&alpha))
        .then(|| format!("alpha = {alpha}: the double sphere's α lies in [0, 1)"))
}

impl ModelKind {
    /// Every kind, in the order of the [`REGISTRY`].
    pub const ALL: [ModelKind; REGISTRY.len()] = {
        let mut all = [ModelKind::Photogrammetric; REGISTRY.len()];
        let mut k = 0;
        while k < REGISTRY.len() {
            all[k] = REGISTRY[k].kind;
            k += 1;
        }
        all
    };

    /// The names files use, in the order of [`Self::ALL`].
    pub const NAMES: [&'static str; REGISTRY.len()] = {
        let mut names = [""; REGISTRY.len()];
        let mut k = 0;
        while k < REGISTRY.len() {
            names[k] = REGISTRY[k].name;
            k += 1;
        }
        names
    };

    /// The model of a camera a file does not name.
    pub const DEFAULT: ModelKind = ModelKind::Photogrammetric;

    /// Its line in the [`REGISTRY`].
    pub fn entry(self) -> &'static ModelEntry {
        &REGISTRY[self as usize]
    }

    /// The name files use.
    pub fn name(self) -> &'static str {
        self.entry().name
    }

    /// The kind named `word` (one of [`Self::NAMES`]).
    pub fn from_name(word: &str) -> Option<Self> {
        REGISTRY.iter().find(|e| e.name == word).map(|e| e.kind)
    }

    /// The kind named `word` in a camera file: one of [`Self::NAMES`] or an alias (the
    /// ecosystems' own name of the model, e.g. OpenCV's `fisheye`).
    pub fn from_file_word(word: &str) -> Option<Self> {
        Self::from_name(word).or_else(|| {
            REGISTRY
                .iter()
                .find(|e| e.aliases.contains(&word))
                .map(|e| e.kind)
        })
    }

    /// The kind whose [`CameraModel::name`] is `word` (the names of pingcal's measurement
    /// file and of its reports).
    pub fn from_model_name(word: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.model_name() == word)
    }

    /// The name of the [`CameraModel`] it builds ([`CameraModel::name`]: pingcal's
    /// measurement file and its reports).
    pub fn model_name(self) -> &'static str {
        self.model(1, 1, 1.0).name()
    }

    /// Whether it is the model of a camera a file does not name ([`Self::DEFAULT`]).
    pub fn is_default(self) -> bool {
        self == Self::DEFAULT
    }

    /// The model of a sensor of `width × height` pixels of pitch `pixel_size_mm` (the
    /// photogrammetric models need the sensor; the others work in pixels and ignore it).
    pub fn model(self, width: u32, height: u32, pixel_size_mm: f64) -> Arc<dyn CameraModel> {
        (self.entry().build)(width, height, pixel_size_mm)
    }

    /// Its parameters' names, in slice order.
    pub fn parameter_names(self) -> &'static [&'static str] {
        self.entry().parameters
    }

    /// Its parameters' keys in project and results files, in slice order.
    pub fn keys(self) -> &'static [&'static str] {
        self.entry().keys
    }

    /// Whether its parameters are in millimetres on the sensor (the photogrammetric
    /// models) rather than in pixels.
    pub fn in_mm(self) -> bool {
        self.entry().in_mm
    }

    /// The parameters that give its focal length: the principal distance, or fx and fy.
    pub fn focal_parameters(self) -> &'static [&'static str] {
        &self.parameter_names()[..if self.in_mm() { 1 } else { 2 }]
    }

    /// The parameters a camera file must give: the principal distance, or fx, fy, cx, cy
    /// (the others default to 0).
    pub fn required_parameters(self) -> &'static [&'static str] {
        &self.parameter_names()[..if self.in_mm() { 1 } else { 4 }]
    }

    /// Whether a ball's centre through a lens of this model is taken from its silhouette's
    /// fitted ellipse (the cone through 72 of its points), rather than from the cone fitted
    /// to the edge points themselves. The photogrammetric (Brown) models keep the ellipse:
    /// their results stay as they were. Through the wide-angle and fisheye models the
    /// outline is no ellipse; the edge points are kept and fitted in ray space: exact
    /// whatever the outline's shape, robust to edge points of a stem or a neighbouring
    /// target, and with a covariance of its own per ball. (The ellipse's cone is not biased
    /// by the shape either: within 2·10⁻⁴ px of the exact centre on exact fisheye
    /// outlines.)
    pub fn silhouette_is_ellipse(self) -> bool {
        self.entry().silhouette_is_ellipse
    }

    /// The lenses it is for.
    pub fn lens(self) -> LensClass {
        self.entry().lens
    }

    /// Whether it is a perspective projection (with a distortion polynomial), which no
    /// lens much beyond 120° across fits.
    pub fn perspective(self) -> bool {
        self.lens() != LensClass::Fisheye
    }

    /// Whether its OpenCV pinhole form is the closed form of
    /// [`forms::opencv_of_photogrammetric`] (exact but for B1 to first order and B2).
    pub fn opencv_closed_form(self) -> bool {
        self.entry().opencv_closed_form
    }

    /// What is wrong with parameter values `p` (its slice order) that no lens can have,
    /// as `name = value: why`, or `None`.
    pub fn check(self, p: &[f64]) -> Option<String> {
        (self.entry().check)(p)
    }

    /// The simulator's lens of this model.
    pub fn sample(self) -> &'static SampleLens {
        &self.entry().sample
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
        (self.entry().nominal)(&mut p, focal_px, [cx, cy, 0.0, pixel_size_mm]);
        p
    }
}

impl ModelKind {
    /// The parameters a network separates, as functions of the model's own, for judging
    /// their correlations: for the double sphere the image scales on the axis fx/(1 + ξ),
    /// fy/(1 + ξ) in place of fx, fy (ξ and the focal lengths move together: a change of ξ
    /// is mostly a change of scale); `None` for a model whose parameters are those the
    /// network separates. Over the parameters named `names` (a subset of the model's, with
    /// `values` all of the model's), the Jacobian ∂new/∂old, row-major `names.len()` ×
    /// `names.len()`.
    pub fn separable_jacobian(self, values: &[f64], names: &[&str]) -> Option<Vec<Vec<f64>>> {
        self.entry().separable.map(|f| f(values, names))
    }
}

/// The identity over `n` parameters.
fn identity(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|a| (0..n).map(|b| f64::from(u8::from(a == b))).collect())
        .collect()
}

/// The double sphere's scales on the axis in place of fx, fy.
fn separable_double_sphere(values: &[f64], names: &[&str]) -> Vec<Vec<f64>> {
    let mut j = identity(names.len());
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

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl serde::Serialize for ModelKind {
    /// Its name.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for ModelKind {
    /// One of [`ModelKind::NAMES`]; anything else is refused with the list ("expected one
    /// of photogrammetric, …"), to which a file's parser adds the file, the line and the
    /// value.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_str(NameVisitor)
    }
}

/// Reads a model's name.
struct NameVisitor;

impl serde::de::Visitor<'_> for NameVisitor {
    type Value = ModelKind;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "one of {}", ModelKind::NAMES.join(", "))
    }

    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ModelKind, E> {
        ModelKind::from_name(v).ok_or_else(|| {
            E::custom(format_args!(
                "expected one of {}",
                ModelKind::NAMES.join(", ")
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every line of the registry is in its variant's place, and every name (and alias)
    /// reads back as its kind, through serde too.
    #[test]
    fn every_registry_entry_round_trips_its_name() {
        for (k, e) in REGISTRY.iter().enumerate() {
            assert_eq!(e.kind as usize, k, "{} out of place", e.name);
            assert_eq!(ModelKind::ALL[k], e.kind);
            assert_eq!(ModelKind::from_name(e.name), Some(e.kind));
            assert_eq!(ModelKind::from_file_word(e.name), Some(e.kind));
            for a in e.aliases {
                assert_eq!(ModelKind::from_file_word(a), Some(e.kind));
                assert_eq!(ModelKind::from_name(a), None, "an alias is no project name");
            }
            let m = e.kind.model(640, 480, 0.005);
            assert_eq!(ModelKind::from_model_name(m.name()), Some(e.kind));
            assert_eq!(m.parameter_names(), e.parameters);
            assert_eq!(e.keys.len(), e.parameters.len(), "{}", e.name);
            let json = format!("\"{}\"", e.name);
            let v: serde::de::value::StrDeserializer<'_, serde::de::value::Error> =
                serde::de::IntoDeserializer::into_deserializer(e.name);
            assert_eq!(
                <ModelKind as serde::Deserialize>::deserialize(v),
                Ok(e.kind)
            );
            assert_eq!(format!("\"{}\"", e.kind), json);
            let lens = e.sample;
            assert_eq!(lens.left.len(), e.parameters.len(), "{}", e.name);
            assert_eq!(lens.right.len(), e.parameters.len(), "{}", e.name);
            assert!(lens.held.iter().all(|h| e.parameters.contains(h)));
            assert_eq!(e.kind.check(lens.left), None);
        }
        let v: serde::de::value::StrDeserializer<'_, serde::de::value::Error> =
            serde::de::IntoDeserializer::into_deserializer("pinhole");
        let e = <ModelKind as serde::Deserialize>::deserialize(v).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("expected one of {}", ModelKind::NAMES.join(", "))
        );
    }
}
