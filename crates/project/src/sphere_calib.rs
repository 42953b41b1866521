//! # The files of `pingcal sphere-calib`
//!
//! The single-sphere calibration of a camera against any lidar (Tóth, Pusztai & Hajder,
//! ICRA 2020) has a project file of its own, much smaller than `project.toml`:
//!
//! ```toml
//! version = 1
//! camera = "camera.toml"        # the camera's known intrinsics (below)
//! sphere_diameter_mm = 600.0
//!
//! [lidar]
//! unit = "m"                    # the clouds' unit: m | mm
//! noise = "VLP-16"              # a named range-noise profile, or
//! # noise_sigma_mm = [10.0, 0.0] # σ = a + b·r (a in mm, b per mm of range)
//!
//! [[frames]]
//! cloud = "clouds/F01.xyz"      # PLY, PCD or XYZ, in the lidar's frame
//! image = "images/F01.png"
//! ```
//!
//! and the camera file ([`crate::camera_file`]: a `camera.toml` of the photogrammetric,
//! OpenCV or fisheye model, a ROS `camera_info` or OpenCV YAML, or a Kalibr camchain, whose
//! entry `camera_entry` names when it holds several cameras).
//!
//! Every path is relative to the folder of the file that names it. Errors name the file and
//! the line, as those of `project.toml` do.

use crate::parse::{invalid, syntax};
use crate::ProjectError;
use pingcal_lrf::cloud_file::CloudUnit;
use pingcal_lrf::sensor::{NoiseProfile, RangeNoise};
use serde::{Deserialize, Serialize};

/// `sphere-calib.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereCalibFile {
    /// Always 1.
    pub version: u32,
    /// Optional name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The camera file ([`crate::CameraFile`]), relative to this file's folder.
    pub camera: String,
    /// The entry of a Kalibr camchain to take (`cam0`, `cam1`, …) when it holds several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_entry: Option<String>,
    /// The sphere's diameter, mm.
    pub sphere_diameter_mm: f64,
    /// The lidar.
    pub lidar: SphereCalibLidar,
    /// The frames: one cloud and one image of the sphere at one place each.
    pub frames: Vec<SphereCalibFrame>,
}

/// `[lidar]` of [`SphereCalibFile`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereCalibLidar {
    /// Unit of the clouds' coordinates: `m` or `mm`.
    pub unit: CloudUnit,
    /// A named range-noise profile (`URG-04LX`, `UTM-30LX`, `UST-10LX`, `VLP-16`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseProfile>,
    /// Or a linear profile σ = a + b·r: `[a_mm, b]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_sigma_mm: Option<[f64; 2]>,
    /// Optional model name (for the report only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
}

/// One `[[frames]]` entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereCalibFrame {
    /// Optional id (default: `F1`, `F2`, … in file order).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<String>,
    /// The cloud (PLY, PCD or XYZ, lidar frame).
    pub cloud: String,
    /// The image.
    pub image: String,
}

impl SphereCalibFile {
    /// Parses and checks the text of a sphere-calib project; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, ProjectError> {
        Self::read(text, file).map(|(f, _)| f)
    }

    /// [`SphereCalibFile::parse`], with the lidar's range noise it resolved
    /// ([`SphereCalibFile::noise`]).
    pub fn read(text: &str, file: &str) -> Result<(Self, RangeNoise), ProjectError> {
        let f: SphereCalibFile = toml::from_str(text).map_err(|e| syntax(file, text, e))?;
        if f.version != 1 {
            return Err(invalid(
                file,
                format!("version = {}: expected 1", f.version),
            ));
        }
        let d = f.sphere_diameter_mm;
        if !(d > 0.0 && d.is_finite()) {
            return Err(invalid(
                file,
                format!("sphere_diameter_mm = {d}: expected a positive number of mm"),
            ));
        }
        let noise = f.noise(file)?;
        if f.frames.len() < 3 {
            return Err(invalid(
                file,
                format!(
                    "{} [[frames]]: at least 3 are needed for a rotation",
                    f.frames.len()
                ),
            ));
        }
        let ids = f.frame_ids();
        for (k, id) in ids.iter().enumerate() {
            if ids[..k].contains(id) {
                return Err(invalid(file, format!("[[frames]] id {id:?} given twice")));
            }
        }
        Ok((f, noise))
    }

    /// The lidar's range noise: `[lidar] noise`'s profile or `noise_sigma_mm`'s σ = a + b·r
    /// ([`pingcal_lrf::settings::range_noise`]), one of them given; `file` names the file in
    /// errors.
    pub fn noise(&self, file: &str) -> Result<RangeNoise, ProjectError> {
        let l = &self.lidar;
        pingcal_lrf::settings::range_noise(
            l.noise,
            l.noise_sigma_mm,
            ["[lidar] noise", "[lidar] noise_sigma_mm"],
        )
        .and_then(|n| {
            n.ok_or_else(|| {
                "[lidar]: give the sensor's noise (a profile name, e.g. noise = \"VLP-16\") or noise_sigma_mm = [a, b]".to_string()
            })
        })
        .map_err(|what| invalid(file, what))
    }

    /// The frames' ids: each one's `id`, or `F1`, `F2`, … by position.
    pub fn frame_ids(&self) -> Vec<String> {
        self.frames
            .iter()
            .enumerate()
            .map(|(k, fr)| fr.id.clone().unwrap_or_else(|| format!("F{}", k + 1)))
            .collect()
    }

    /// The text of the file.
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a sphere-calib file always serialises")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PROJECT: &str = r#"version = 1
camera = "camera.toml"
sphere_diameter_mm = 600.0

[lidar]
unit = "m"
noise = "VLP-16"

[[frames]]
cloud = "a.xyz"
image = "a.png"

[[frames]]
cloud = "b.xyz"
image = "b.png"

[[frames]]
id = "last"
cloud = "c.xyz"
image = "c.png"
"#;

    #[test]
    fn the_module_example_parses_and_round_trips() {
        let f = SphereCalibFile::parse(PROJECT, "p.toml").unwrap();
        assert_eq!(f.frame_ids(), ["F1", "F2", "last"]);
        assert_eq!(SphereCalibFile::parse(&f.to_toml_string(), "p").unwrap(), f);
        let cam = "model = \"photogrammetric\"\nwidth = 1280\nheight = 720\npixel_size_mm = 0.00375\n[params]\nc_mm = 2.45\n";
        let c = crate::CameraFile::parse(cam, "camera.toml").unwrap();
        assert!(
            c.intrinsics.model == crate::CameraModel::Photogrammetric
                && c.intrinsics.values[0] == 2.45
        );
        assert_eq!(
            crate::CameraFile::parse(&c.to_toml_string(), "c").unwrap(),
            c
        );
    }

    #[test]
    fn bad_values_name_the_file_and_entry() {
        let e = SphereCalibFile::parse(&PROJECT.replace("600.0", "0.0"), "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: sphere_diameter_mm = 0: expected a positive number of mm"
        );
        let e = SphereCalibFile::parse(&PROJECT.replace("\"m\"", "\"cm\""), "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "p.toml: line 6: unit = \"cm\": expected one of mm, m");
        let e = SphereCalibFile::parse(&PROJECT.replace("VLP-16", "bogus"), "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: line 7: noise = \"bogus\": expected one of URG-04LX, UTM-30LX, UST-10LX, VLP-16"
        );
        let both = PROJECT.replace(
            "noise = \"VLP-16\"",
            "noise = \"VLP-16\"\nnoise_sigma_mm = [10.0, 0.0]",
        );
        let e = SphereCalibFile::parse(&both, "p.toml")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "p.toml: [lidar] noise and [lidar] noise_sigma_mm: give one, a named profile or [a, b]"
        );
        let none = PROJECT.replace("noise = \"VLP-16\"", "");
        let e = SphereCalibFile::parse(&none, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.toml: [lidar]: give the sensor's noise"),
            "{e}"
        );
        let e = SphereCalibFile::parse(&PROJECT.replace("image = \"a.png\"", ""), "p.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.toml: line") && e.contains("image"), "{e}");
    }
}
