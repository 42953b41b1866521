//! # The camera file of `pingcal sphere-calib`: a camera with known intrinsics
//!
//! Four forms are read, each directly (docs/sphere-calib.md, docs/formats.md):
//!
//! * **`camera.toml`**, any of pingcal's camera models (`project.toml`'s `model` words, with
//!   the keys of [`crate::intrinsics`]; `fisheye` is read as `kannala-brandt`, OpenCV's
//!   `cv::fisheye`):
//!   ```toml
//!   model = "photogrammetric"      # docs/formats.md's model, parameters as project.toml's [cameras.initial]
//!   width = 1280
//!   height = 720
//!   pixel_size_mm = 0.00375
//!   [params]
//!   c_mm = 2.45                    # the others (xp_mm … b2) default to 0
//!   ```
//!   ```toml
//!   model = "opencv"               # OpenCV's pinhole: K and k1 k2 p1 p2 k3 (k4 k5 k6 s1 … s4 of the rational and thin-prism models)
//!   width = 1280
//!   height = 1024
//!   [params]
//!   fx = 4548.4
//!   fy = 4544.4
//!   cx = 703.2                     # pixels, (0, 0) the centre of the top-left pixel (OpenCV's own numbers)
//!   cy = 609.2
//!   k1 = -0.1                      # the coefficients default to 0
//!   ```
//!   ```toml
//!   model = "kannala-brandt"       # or "fisheye": OpenCV's cv::fisheye, fx fy cx cy k1 k2 k3 k4
//!   ```
//!   ```toml
//!   model = "double-sphere"        # Usenko et al.: fx fy cx cy xi alpha
//!   ```
//! * **a ROS `camera_info` YAML** (`camera_calibration_parsers`' file: `image_width`,
//!   `image_height`, `camera_matrix`, `distortion_model` plumb_bob, rational_polynomial or
//!   equidistant, `distortion_coefficients`), or **OpenCV's FileStorage YAML** with the same
//!   keys (what `pingcal calibrate` writes in `opencv/`);
//! * **a Kalibr camchain** entry (`camN:` with `camera_model: pinhole`, `intrinsics: [fu, fv,
//!   pu, pv]`, `distortion_model` radtan, equidistant or none, `distortion_coeffs`,
//!   `resolution`; or `camera_model: ds`, `intrinsics: [xi, alpha, fu, fv, pu, pv]`); with
//!   several cameras in the file the project names the entry.
//!
//! Whatever the form, the camera is one of pingcal's models with its parameters
//! ([`Intrinsics`], the type `project.toml` and `results.json` use), so the image side and
//! the exports go through the same camera code as `pingcal calibrate`.
//!
//! [`CameraFile::read`] tells the forms apart by the file's extension (`.toml`, `.yaml` /
//! `.yml`) and, for any other name, by its content; a file in none of them is refused in one
//! line that lists what is read. Every error names the file and, where there is one, the
//! line.

use crate::closed_sets::CameraModel;
use crate::intrinsics::{keys, Intrinsics, KeyedValues};
use crate::parse::{invalid, syntax};
use crate::schema::CameraParams;
use crate::yaml::{self, Yaml};
use crate::ProjectError;
use serde::{Deserialize, Serialize};

/// The form a camera file was read in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CameraFormat {
    /// `camera.toml`.
    Toml,
    /// ROS `camera_info` YAML.
    RosCameraInfo,
    /// OpenCV FileStorage YAML.
    OpenCvYaml,
    /// A Kalibr camchain's entry (`cam0`, …).
    KalibrCamchain(String),
}

/// A camera with known intrinsics.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraFile {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Pixel pitch, mm: the file's for the photogrammetric models; the models in pixels
    /// ignore it ([`NOMINAL_PIXEL_MM`]).
    pub pixel_size_mm: f64,
    /// The model and its parameters.
    pub intrinsics: Intrinsics,
    /// The form it was read in.
    pub format: CameraFormat,
    /// The camera's name in the file (`camera_name`, the camchain entry), if any.
    pub name: Option<String>,
}

/// The pixel pitch given to a camera in a model that works in pixels (which ignores it), mm.
pub const NOMINAL_PIXEL_MM: f64 = 0.001;

/// `camera.toml`, as read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraToml {
    model: CameraModel,
    width: u32,
    height: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pixel_size_mm: Option<f64>,
    params: KeyedValues,
}

/// Only the model's word (an alias is read as its model's name).
#[derive(Deserialize)]
struct ModelWord {
    model: Option<String>,
}

/// What a file in no form pingcal reads is told: the forms, and the models a camera.toml
/// names (the camera crate's registry, with the other words it reads for each).
pub fn formats() -> String {
    let words: Vec<String> = CameraModel::ALL
        .iter()
        .map(|m| {
            let aliases: Vec<String> = m
                .entry()
                .aliases
                .iter()
                .map(|a| format!("\"{a}\""))
                .collect();
            match aliases.is_empty() {
                true => format!("\"{m}\""),
                false => format!("\"{m}\" (or {})", aliases.join(" or ")),
            }
        })
        .collect();
    let (last, rest) = words.split_last().expect("the registry has models");
    format!("a camera.toml (model = {} or {last}), a ROS camera_info or OpenCV YAML, or a Kalibr camchain YAML (docs/sphere-calib.md)", rest.join(", "))
}

/// A model in pixels from its `fx fy cx cy` and then its other values in its key order
/// (missing ones 0).
fn pixel_model(model: CameraModel, k: [f64; 4], rest: &[f64]) -> Intrinsics {
    let mut values = vec![0.0; keys(model).len()];
    values[..4].copy_from_slice(&k);
    values[4..4 + rest.len()].copy_from_slice(rest);
    Intrinsics { model, values }
}

impl Intrinsics {
    /// The photogrammetric model's ten values `[c, xp, yp, K1, K2, K3, P1, P2, B1, B2]`.
    pub fn photogrammetric(values: [f64; 10]) -> Self {
        Self {
            model: CameraModel::Photogrammetric,
            values: values.to_vec(),
        }
    }
}

impl CameraFile {
    /// A photogrammetric camera.
    pub fn photogrammetric(
        width: u32,
        height: u32,
        pixel_size_mm: f64,
        params: CameraParams,
    ) -> Self {
        CameraFile {
            width,
            height,
            pixel_size_mm,
            intrinsics: Intrinsics::photogrammetric(params.to_slice()),
            format: CameraFormat::Toml,
            name: None,
        }
    }

    /// Reads a camera file in any of its forms (see the module doc); `file` names it in
    /// errors, its extension says the form; `entry`: the camchain entry to take.
    pub fn read(text: &str, file: &str, entry: Option<&str>) -> Result<Self, ProjectError> {
        let lower = file.to_ascii_lowercase();
        if lower.ends_with(".toml") {
            return Self::parse(text, file);
        }
        if lower.ends_with(".yaml") || lower.ends_with(".yml") {
            return Self::parse_yaml(text, file, entry);
        }
        let head = text.trim_start();
        if !(head.starts_with('{') || head.starts_with('<') || head.contains('\0')) {
            if let Ok(c) = Self::parse_yaml(text, file, entry) {
                return Ok(c);
            }
            if let Ok(c) = Self::parse(text, file) {
                return Ok(c);
            }
        }
        Err(invalid(
            file,
            format!("not a camera file pingcal reads: expected {}", formats()),
        ))
    }

    /// Parses and checks the text of a `camera.toml`; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, ProjectError> {
        let word = toml::from_str::<ModelWord>(text)
            .map_err(|e| syntax(file, text, e))?
            .model;
        let alias = word
            .as_deref()
            .and_then(|w| CameraModel::from_file_word(w).map(|m| (w, m)))
            .filter(|(w, m)| m.name() != *w);
        let t: CameraToml = if let Some((w, m)) = alias {
            let named = text.replacen(&format!("\"{w}\""), &format!("\"{m}\""), 1);
            toml::from_str(&named).map_err(|e| syntax(file, text, e))?
        } else {
            toml::from_str(text).map_err(|e| syntax(file, text, e))?
        };
        if let Some(e) = Intrinsics::unknown_key(t.model, &t.params) {
            return Err(invalid(file, format!("[params] {e}")));
        }
        let photogrammetric = t.model.in_mm();
        let required = &keys(t.model)[..t.model.required_parameters().len()];
        if let Some(k) = required.iter().find(|k| t.params.get(k).is_none()) {
            return Err(invalid(
                file,
                format!(
                    "[params] {k} missing: model '{}' needs {} (the others default to 0)",
                    t.model,
                    required.join(", ")
                ),
            ));
        }
        let pixel_size_mm = match (photogrammetric, t.pixel_size_mm) {
            (true, Some(p)) => p,
            (true, None) => {
                return Err(invalid(
                    file,
                    format!(
                        "pixel_size_mm missing: model '{}' needs the pixel pitch in mm",
                        t.model
                    ),
                ))
            }
            (false, p) => p.unwrap_or(NOMINAL_PIXEL_MM),
        };
        let zeros = vec![0.0; keys(t.model).len()];
        CameraFile {
            width: t.width,
            height: t.height,
            pixel_size_mm,
            intrinsics: Intrinsics::from_table(t.model, &t.params, &zeros),
            format: CameraFormat::Toml,
            name: None,
        }
        .check(file)
    }

    /// Reads a ROS `camera_info`, OpenCV FileStorage or Kalibr camchain YAML.
    pub fn parse_yaml(text: &str, file: &str, entry: Option<&str>) -> Result<Self, ProjectError> {
        let y = yaml::parse(text).map_err(|e| ProjectError::Syntax {
            path: file.to_string(),
            what: e,
        })?;
        if y.get("camera_matrix").is_some() {
            return from_camera_info(&y, text, file)?.check(file);
        }
        let cams: Vec<&str> = y
            .keys()
            .into_iter()
            .filter(|k| k.starts_with("cam") && k[3..].parse::<u32>().is_ok())
            .collect();
        if cams.is_empty() {
            return Err(invalid(
                file,
                format!("a YAML file with neither camera_matrix (ROS camera_info, OpenCV) nor cam0 (Kalibr camchain): expected {}", formats()),
            ));
        }
        let name = match (entry, cams.as_slice()) {
            (Some(e), _) if cams.contains(&e) => e,
            (Some(e), _) => {
                return Err(invalid(file, format!("camera_entry = {e:?}: the camchain has {}", cams.join(", "))))
            }
            (None, [one]) => one,
            (None, _) => {
                return Err(invalid(
                    file,
                    format!("a camchain of {} cameras ({}): say which with camera_entry = \"cam1\" (e.g.) in the project", cams.len(), cams.join(", ")),
                ))
            }
        };
        from_camchain(y.get(name).expect("a key of the map"), name, file)?.check(file)
    }

    /// The checks every form shares: a positive size, a positive focal length (and pixel
    /// pitch), finite values.
    fn check(self, file: &str) -> Result<Self, ProjectError> {
        if self.width == 0 || self.height == 0 {
            return Err(invalid(
                file,
                format!(
                    "{} × {} pixels: expected a positive size",
                    self.width, self.height
                ),
            ));
        }
        let i = &self.intrinsics;
        if i.model.in_mm() {
            let p = self.pixel_size_mm;
            if !(p > 0.0 && p.is_finite()) {
                return Err(invalid(
                    file,
                    format!("pixel_size_mm = {p}: expected a positive number"),
                ));
            }
            let c = i.values[0];
            if !(c > 0.0 && c.is_finite()) {
                return Err(invalid(
                    file,
                    format!("[params] c_mm = {c}: expected a positive principal distance"),
                ));
            }
        } else {
            check_pixel_model(
                file,
                &[i.values[0], i.values[1], i.values[2], i.values[3]],
                &i.values[4..],
            )?;
        }
        if !i.values.iter().all(|v| v.is_finite()) {
            return Err(invalid(file, "[params]: every value must be finite".into()));
        }
        Ok(self)
    }

    /// The text of a `camera.toml` holding this camera.
    pub fn to_toml_string(&self) -> String {
        toml::to_string(&CameraToml {
            model: self.intrinsics.model,
            width: self.width,
            height: self.height,
            pixel_size_mm: self.intrinsics.model.in_mm().then_some(self.pixel_size_mm),
            params: self.intrinsics.to_table(),
        })
        .expect("a camera file always serialises")
    }
}

fn check_pixel_model(file: &str, k: &[f64; 4], dist: &[f64]) -> Result<(), ProjectError> {
    if !(k[0] > 0.0 && k[1] > 0.0) {
        return Err(invalid(
            file,
            format!(
                "fx = {}, fy = {}: expected positive focal lengths in pixels",
                k[0], k[1]
            ),
        ));
    }
    if !k.iter().chain(dist).all(|v| v.is_finite()) {
        return Err(invalid(
            file,
            "every parameter must be a finite number".into(),
        ));
    }
    Ok(())
}

/// The 1-based line of the first line of `text` that starts with `key:` (for errors).
fn line_of(text: &str, key: &str) -> String {
    text.lines()
        .position(|l| l.trim_start().starts_with(&format!("{key}:")))
        .map_or(String::new(), |i| format!("line {}: ", i + 1))
}

/// A number of the YAML, or an error naming the key.
fn number(y: &Yaml, key: &str, text: &str, file: &str) -> Result<f64, ProjectError> {
    y.get(key).and_then(Yaml::num).ok_or_else(|| {
        invalid(
            file,
            format!("{}{key}: expected a number", line_of(text, key)),
        )
    })
}

/// A ROS `camera_info` or OpenCV FileStorage YAML.
fn from_camera_info(y: &Yaml, text: &str, file: &str) -> Result<CameraFile, ProjectError> {
    let w = number(y, "image_width", text, file)?;
    let h = number(y, "image_height", text, file)?;
    let data = |key: &str| -> Result<Vec<f64>, ProjectError> {
        y.get(key)
            .and_then(|m| m.get("data"))
            .and_then(Yaml::nums)
            .ok_or_else(|| {
                invalid(
                    file,
                    format!(
                        "{}{key}: expected a data list of numbers",
                        line_of(text, key)
                    ),
                )
            })
    };
    let km = data("camera_matrix")?;
    if km.len() != 9 {
        return Err(invalid(
            file,
            format!(
                "{}camera_matrix: {} numbers, expected 9 (3 × 3)",
                line_of(text, "camera_matrix"),
                km.len()
            ),
        ));
    }
    if km[1].abs() > 1e-9 * km[0].abs()
        || km[3] != 0.0
        || km[6] != 0.0
        || km[7] != 0.0
        || km[8] != 1.0
    {
        return Err(invalid(
            file,
            format!(
                "{}camera_matrix: expected [fx, 0, cx, 0, fy, cy, 0, 0, 1] (no skew)",
                line_of(text, "camera_matrix")
            ),
        ));
    }
    let k = [km[0], km[4], km[2], km[5]];
    let d = match y.get("distortion_coefficients") {
        Some(_) => data("distortion_coefficients")?,
        None => Vec::new(),
    };
    let model = y
        .get("distortion_model")
        .and_then(Yaml::str)
        .unwrap_or("plumb_bob");
    let line = line_of(text, "distortion_model");
    let intrinsics = match model {
        "plumb_bob" | "rational_polynomial" => {
            let most = if model == "plumb_bob" { 5 } else { 8 };
            if d.len() > most {
                return Err(invalid(file, format!("{line}distortion_model {model}: {} coefficients, at most {most}", d.len())));
            }
            pixel_model(CameraModel::OpenCv, k, &d)
        }
        "equidistant" | "fisheye" => {
            if d.len() > 4 {
                return Err(invalid(file, format!("{line}distortion_model {model}: {} coefficients, expected 4", d.len())));
            }
            pixel_model(CameraModel::KannalaBrandt, k, &d)
        }
        other => {
            return Err(invalid(file, format!("{line}distortion_model {other:?}: expected plumb_bob, rational_polynomial or equidistant")))
        }
    };
    Ok(CameraFile {
        width: size(w, "image_width", file)?,
        height: size(h, "image_height", file)?,
        pixel_size_mm: NOMINAL_PIXEL_MM,
        intrinsics,
        format: if text.trim_start().starts_with("%YAML") {
            CameraFormat::OpenCvYaml
        } else {
            CameraFormat::RosCameraInfo
        },
        name: y.get("camera_name").and_then(Yaml::str).map(str::to_string),
    })
}

fn size(v: f64, key: &str, file: &str) -> Result<u32, ProjectError> {
    if v >= 1.0 && v <= u32::MAX as f64 && v.fract() == 0.0 {
        Ok(v as u32)
    } else {
        Err(invalid(
            file,
            format!("{key} = {v}: expected a positive whole number of pixels"),
        ))
    }
}

/// One entry `cam` of a Kalibr camchain.
fn from_camchain(c: &Yaml, name: &str, file: &str) -> Result<CameraFile, ProjectError> {
    let bad = |what: String| invalid(file, format!("{name}: {what}"));
    let model = c
        .get("camera_model")
        .and_then(Yaml::str)
        .unwrap_or("pinhole");
    if model != "pinhole" && model != "ds" {
        return Err(bad(format!(
            "camera_model {model:?}: expected pinhole (with radtan, equidistant or none) or ds"
        )));
    }
    let res = c
        .get("resolution")
        .and_then(Yaml::nums)
        .filter(|v| v.len() == 2)
        .ok_or_else(|| bad("resolution: expected [width, height]".into()))?;
    let (width, height) = (
        size(res[0], "resolution", file)?,
        size(res[1], "resolution", file)?,
    );
    let entry = |intrinsics| CameraFile {
        width,
        height,
        pixel_size_mm: NOMINAL_PIXEL_MM,
        intrinsics,
        format: CameraFormat::KalibrCamchain(name.to_string()),
        name: Some(name.to_string()),
    };
    if model == "ds" {
        // Kalibr's double sphere: [xi, alpha, fu, fv, pu, pv]
        let v = c
            .get("intrinsics")
            .and_then(Yaml::nums)
            .filter(|v| v.len() == 6)
            .ok_or_else(|| {
                bad("intrinsics: expected [xi, alpha, fu, fv, pu, pv] (camera_model ds)".into())
            })?;
        return Ok(entry(pixel_model(
            CameraModel::DoubleSphere,
            [v[2], v[3], v[4], v[5]],
            &v[..2],
        )));
    }
    let k = c
        .get("intrinsics")
        .and_then(Yaml::nums)
        .filter(|v| v.len() == 4)
        .ok_or_else(|| bad("intrinsics: expected [fu, fv, pu, pv]".into()))?;
    let d = match c.get("distortion_coeffs") {
        Some(v) => v
            .nums()
            .ok_or_else(|| bad("distortion_coeffs: expected a list of numbers".into()))?,
        None => Vec::new(),
    };
    let k = [k[0], k[1], k[2], k[3]];
    let dm = c
        .get("distortion_model")
        .and_then(Yaml::str)
        .unwrap_or("none");
    let intrinsics = match dm {
        "radtan" | "none" => {
            if d.len() > 4 {
                return Err(bad(format!(
                    "distortion_model {dm}: {} coefficients, expected 4 (k1 k2 r1 r2)",
                    d.len()
                )));
            }
            pixel_model(CameraModel::OpenCv, k, &d)
        }
        "equidistant" => {
            if d.len() > 4 {
                return Err(bad(format!(
                    "distortion_model equidistant: {} coefficients, expected 4",
                    d.len()
                )));
            }
            pixel_model(CameraModel::KannalaBrandt, k, &d)
        }
        other => {
            return Err(bad(format!(
                "distortion_model {other:?}: expected radtan, equidistant or none"
            )))
        }
    };
    Ok(entry(intrinsics))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_four_forms_read_the_same_opencv_camera() {
        let toml = "model = \"opencv\"\nwidth = 1280\nheight = 1024\n[params]\nfx = 4548.4\nfy = 4544.4\ncx = 703.2\ncy = 609.2\nk1 = -0.1\np2 = 0.001\n";
        let a = CameraFile::read(toml, "camera.toml", None).unwrap();
        let ros = "image_width: 1280\nimage_height: 1024\ncamera_name: cam\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [4548.4, 0, 703.2, 0, 4544.4, 609.2, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [-0.1, 0, 0, 0.001, 0]\n";
        let b = CameraFile::read(ros, "camera_info.yaml", None).unwrap();
        let kal = "cam0:\n  camera_model: pinhole\n  intrinsics: [4548.4, 4544.4, 703.2, 609.2]\n  distortion_model: radtan\n  distortion_coeffs: [-0.1, 0.0, 0.0, 0.001]\n  resolution: [1280, 1024]\n";
        let c = CameraFile::read(kal, "camchain.yaml", None).unwrap();
        let cv = "%YAML:1.0\n---\nimage_width: 1280\nimage_height: 1024\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 4548.4, 0.0, 703.2, 0.0, 4544.4, 609.2, 0.0, 0.0, 1.0 ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ -0.1, 0.0, 0.0, 0.001, 0.0 ]\n";
        let d = CameraFile::read(cv, "camera_cam.yaml", None).unwrap();
        for x in [&b, &c, &d] {
            assert_eq!((x.width, x.height), (1280, 1024));
            assert_eq!(x.intrinsics, a.intrinsics);
        }
        assert_eq!(b.format, CameraFormat::RosCameraInfo);
        assert_eq!(c.format, CameraFormat::KalibrCamchain("cam0".into()));
        assert_eq!(d.format, CameraFormat::OpenCvYaml);
        // round trip of camera.toml
        assert_eq!(CameraFile::parse(&a.to_toml_string(), "c").unwrap(), a);
        let fish = "model = \"fisheye\"\nwidth = 640\nheight = 480\n[params]\nfx = 300.0\nfy = 300.0\ncx = 320.0\ncy = 240.0\nk1 = 0.01\n";
        let f = CameraFile::read(fish, "fish.toml", None).unwrap();
        assert_eq!(f.intrinsics.model, CameraModel::KannalaBrandt);
        assert_eq!(CameraFile::parse(&f.to_toml_string(), "c").unwrap(), f);
        // Kalibr's double sphere: [xi, alpha, fu, fv, pu, pv] into pingcal's key order
        let ds = "cam0:\n  camera_model: ds\n  intrinsics: [-0.2, 0.6, 350.0, 351.0, 640.0, 400.0]\n  distortion_model: none\n  resolution: [1280, 800]\n";
        let g = CameraFile::read(ds, "camchain.yaml", None).unwrap();
        assert_eq!(g.intrinsics.model, CameraModel::DoubleSphere);
        assert_eq!(g.intrinsics.values, [350.0, 351.0, 640.0, 400.0, -0.2, 0.6]);
        let ds_toml = "model = \"double-sphere\"\nwidth = 1280\nheight = 800\n[params]\nfx = 350.0\nfy = 351.0\ncx = 640.0\ncy = 400.0\nxi = -0.2\nalpha = 0.6\n";
        assert_eq!(
            CameraFile::read(ds_toml, "c.toml", None)
                .unwrap()
                .intrinsics,
            g.intrinsics
        );
        // a key the model does not have, a focal length missing
        let e = CameraFile::read("model = \"opencv\"\nwidth = 2\nheight = 2\n[params]\nfx = 1.0\nfy = 1.0\ncx = 1.0\ncy = 1.0\nc_mm = 3.0\n", "c.toml", None).unwrap_err().to_string();
        assert!(
            e.contains("'c_mm' is not a parameter of model 'opencv'"),
            "{e}"
        );
        let e = CameraFile::read(
            "model = \"opencv\"\nwidth = 2\nheight = 2\n[params]\nfx = 1.0\n",
            "c.toml",
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("[params] fy missing: model 'opencv' needs fx, fy, cx, cy"),
            "{e}"
        );
    }

    #[test]
    fn a_file_in_no_form_is_one_line_naming_it_and_the_forms() {
        let e = CameraFile::read("{\"fx\": 1}", "camera.json", None)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("camera.json: not a camera file pingcal reads: expected a camera.toml"),
            "{e}"
        );
        assert_eq!(e.lines().count(), 1);
        let e = CameraFile::read("foo: 1\n", "c.yaml", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("neither camera_matrix"), "{e}");
        let two = "cam0:\n  intrinsics: [1, 1, 0, 0]\n  resolution: [2, 2]\ncam1:\n  intrinsics: [1, 1, 0, 0]\n  resolution: [2, 2]\n";
        let e = CameraFile::read(two, "chain.yaml", None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a camchain of 2 cameras (cam0, cam1): say which with camera_entry"),
            "{e}"
        );
        assert!(CameraFile::read(two, "chain.yaml", Some("cam1")).is_ok());
        let e = CameraFile::read("cam0:\n  camera_model: omni\n", "chain.yaml", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cam0: camera_model \"omni\""), "{e}");
        let e = CameraFile::read("model = \"pinhole\"\n", "camera.toml", None)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("camera.toml: line 1: model"), "{e}");
        let e = CameraFile::read("model = \"opencv\"\nwidth = 10\nheight = 10\n[params]\nfx = 0.0\nfy = 1.0\ncx = 1.0\ncy = 1.0\n", "camera.toml", None).unwrap_err().to_string();
        assert!(
            e.contains("fx = 0, fy = 1: expected positive focal lengths"),
            "{e}"
        );
    }
}
