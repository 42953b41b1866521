//! Reader of the text files of DBAT (the Damped Bundle Adjustment Toolbox, Börlin &
//! Grussenmeyer): mark points (`markpts.txt`) and control points, so that DBAT's published
//! cases run unchanged.
//!
//! # The files
//! * Mark points: one measurement per line, `image id, point id, x, y, sxy` (comma and/or
//!   whitespace separated; `#` starts a comment), x and y in pixels, sxy the standard
//!   deviation of each coordinate in pixels.
//! * Control points: `id, label, X, Y, Z` (fixed) or `id, label, X, Y, Z, sxyz` (weighted,
//!   one σ for the three axes) or `id, label, X, Y, Z, sx, sy, sz`, in DBAT's object unit
//!   (metres in the `camcaldemo` case).
//!
//!
//! A UTF-8 byte-order mark at the start of either file is skipped; numbers beyond ±1e12
//! ([`MAX_MAGNITUDE`]) are refused, and so is a point measured twice in one image.
//!
//! # Pixel convention
//! DBAT (like PhotoModeler, whose exports it reads) puts the pixel origin at the *corner* of
//! the image: the top-left pixel covers [0, 1] × [0, 1] and its centre is (0.5, 0.5), x to
//! the right and y down; its image (mm) coordinates are the pixel coordinates times the
//! pixel size, y still down, and its principal point is measured from that corner. The
//! initial principal point DBAT uses (`setcamvals(s, 'default', …)`) is half the sensor
//! size, i.e. the centre of the array in that system. pingcal's origin is the centre of the
//! top-left pixel, so `u = x − 0.5`, `v = y − 0.5`.
//!
//! A DBAT principal point (px, py), as DBAT reports it in mm from the image corner with y
//! down, corresponds to pingcal's (xp, yp), relative to the array centre with y up, of
//! `xp = px − (W/2)·ps`, `yp = (H/2)·ps − py` ([`dbat_principal_point`]). DBAT's model 3
//! scales the measured x by 1 + as (its aspect parameter) *before* subtracting the
//! principal point, and reports px in unscaled mm (its internal value divided by 1 + as):
//! re-adjusting the `camcaldemo` data with DBAT's model written out
//! (`tests/dbat_camcal.rs`) reproduces the published px only with that reading.

use super::measurements::{
    CameraSpec, ControlPoint, ImagePoint, ImageSpec, Measurements, MAX_MAGNITUDE,
};
use nalgebra::Vector2;
use std::collections::BTreeMap;
use std::path::Path;

/// An error in a DBAT file, naming the file and the line (1-based).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DbatError {
    /// The file could not be read.
    #[error("{file}: {message}")]
    Io { file: String, message: String },
    /// A line that is not a valid record.
    #[error("{file}:{line}: {message}")]
    Line {
        file: String,
        line: usize,
        message: String,
    },
    /// A file without any record.
    #[error("{file}: no {what} found")]
    Empty { file: String, what: &'static str },
}

/// One DBAT mark point (pixels, DBAT's corner origin).
#[derive(Clone, Debug, PartialEq)]
pub struct MarkPoint {
    /// Image id.
    pub image: String,
    /// Point id.
    pub point: String,
    /// x, pixels from the left edge of the image.
    pub x: f64,
    /// y, pixels from the top edge, down.
    pub y: f64,
    /// σ of each coordinate, pixels.
    pub sigma: f64,
}

/// One DBAT control point (DBAT's object unit).
#[derive(Clone, Debug, PartialEq)]
pub struct DbatControl {
    /// Point id (as in the mark points).
    pub id: String,
    /// Label.
    pub label: String,
    /// Coordinates.
    pub xyz: [f64; 3],
    /// Standard deviations per axis (weighted control), `None` for fixed control.
    pub sigma: Option<[f64; 3]>,
}

/// The camera of a DBAT project as pingcal needs it.
#[derive(Clone, Debug, PartialEq)]
pub struct DbatCamera {
    /// Name.
    pub name: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Pixel pitch, mm (DBAT: sensor height / image height when the sensor width is `auto`).
    pub pixel_size_mm: f64,
    /// Initial camera constant, mm.
    pub c_mm: f64,
}

impl DbatCamera {
    /// The Olympus Camedia C4040Z of DBAT's `camcaldemo` (`c4040z.xml`): 2272 × 1704 px,
    /// sensor height 5.43764 mm (so square pixels of 3.1911 µm), nominal focal length 7.5 mm.
    pub fn c4040z() -> Self {
        Self {
            name: "C4040Z".into(),
            width: 2272,
            height: 1704,
            pixel_size_mm: 5.43764 / 1704.0,
            c_mm: 7.5,
        }
    }
}

/// DBAT's pixel coordinates (corner origin) → pingcal's (centre of the top-left pixel).
pub fn dbat_pixel_to_pingcal(x: f64, y: f64) -> Vector2<f64> {
    Vector2::new(x - 0.5, y - 0.5)
}

/// DBAT's principal point as DBAT reports it (mm from the image corner, y down) →
/// pingcal's (xp, yp) in mm relative to the array centre, y up (see the module doc).
pub fn dbat_principal_point(px: f64, py: f64, camera: &DbatCamera) -> (f64, f64) {
    let ps = camera.pixel_size_mm;
    (
        px - 0.5 * camera.width as f64 * ps,
        0.5 * camera.height as f64 * ps - py,
    )
}

/// `text` without a UTF-8 byte-order mark at its start.
fn without_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

fn fields(line: &str) -> Vec<&str> {
    line.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect()
}

fn content(line: &str) -> &str {
    match line.find('#') {
        Some(k) => &line[..k],
        None => line,
    }
}

fn number(file: &str, line: usize, what: &str, s: &str) -> Result<f64, DbatError> {
    match s.parse::<f64>() {
        Ok(v) if v.abs() <= MAX_MAGNITUDE => Ok(v),
        Ok(v) if v.is_finite() => Err(DbatError::Line {
            file: file.into(),
            line,
            message: format!("{what} {v:e} is beyond ±{MAX_MAGNITUDE:e}"),
        }),
        _ => Err(DbatError::Line {
            file: file.into(),
            line,
            message: format!("{what} '{}' is not a finite number", super::printable(s)),
        }),
    }
}

/// Parses a mark-point file; `file` names it in errors.
pub fn parse_markpts(text: &str, file: &str) -> Result<Vec<MarkPoint>, DbatError> {
    let mut out = Vec::new();
    let mut first_line = std::collections::HashMap::new();
    for (k, raw) in without_bom(text).lines().enumerate() {
        let line = k + 1;
        let f = fields(content(raw));
        if f.is_empty() {
            continue;
        }
        if f.len() != 5 {
            return Err(DbatError::Line {
                file: file.into(),
                line,
                message: format!(
                    "expected 5 fields (image id, point id, x, y, sxy), found {}",
                    f.len()
                ),
            });
        }
        let sigma = number(file, line, "sxy", f[4])?;
        if sigma <= 0.0 {
            return Err(DbatError::Line {
                file: file.into(),
                line,
                message: format!("sxy {sigma} must be positive"),
            });
        }
        if let Some(prev) = first_line.insert((f[0], f[1]), line) {
            return Err(DbatError::Line {
                file: file.into(),
                line,
                message: format!(
                    "point '{}' is measured twice in image '{}' (first on line {prev})",
                    super::printable(f[1]),
                    super::printable(f[0])
                ),
            });
        }
        out.push(MarkPoint {
            image: f[0].into(),
            point: f[1].into(),
            x: number(file, line, "x", f[2])?,
            y: number(file, line, "y", f[3])?,
            sigma,
        });
    }
    if out.is_empty() {
        return Err(DbatError::Empty {
            file: file.into(),
            what: "mark points",
        });
    }
    Ok(out)
}

/// Parses a control-point file; `file` names it in errors.
pub fn parse_control(text: &str, file: &str) -> Result<Vec<DbatControl>, DbatError> {
    let mut out: Vec<DbatControl> = Vec::new();
    for (k, raw) in without_bom(text).lines().enumerate() {
        let line = k + 1;
        let f = fields(content(raw));
        if f.is_empty() {
            continue;
        }
        if !matches!(f.len(), 5 | 6 | 8) {
            return Err(DbatError::Line {
                file: file.into(),
                line,
                message: format!(
                    "expected 5 (id, label, X, Y, Z), 6 (…, sxyz) or 8 (…, sx, sy, sz) fields, found {}",
                    f.len()
                ),
            });
        }
        let xyz = [
            number(file, line, "X", f[2])?,
            number(file, line, "Y", f[3])?,
            number(file, line, "Z", f[4])?,
        ];
        let sigma = match f.len() {
            6 => {
                let s = number(file, line, "sxyz", f[5])?;
                Some([s, s, s])
            }
            8 => Some([
                number(file, line, "sx", f[5])?,
                number(file, line, "sy", f[6])?,
                number(file, line, "sz", f[7])?,
            ]),
            _ => None,
        };
        if let Some(s) = sigma {
            if s.iter().any(|v| *v <= 0.0) {
                return Err(DbatError::Line {
                    file: file.into(),
                    line,
                    message: "standard deviations must be positive".into(),
                });
            }
        }
        if out.iter().any(|c| c.id == f[0]) {
            return Err(DbatError::Line {
                file: file.into(),
                line,
                message: format!("control point '{}' is listed twice", super::printable(f[0])),
            });
        }
        out.push(DbatControl {
            id: f[0].into(),
            label: f[1].into(),
            xyz,
            sigma,
        });
    }
    if out.is_empty() {
        return Err(DbatError::Empty {
            file: file.into(),
            what: "control points",
        });
    }
    Ok(out)
}

/// Assembles pingcal [`Measurements`] from DBAT's marks and control: one camera with all
/// ten intrinsics fixed at (c, 0, …, 0) (the caller chooses what to calibrate), one image
/// per DBAT image id (in order of first appearance; no poses), pixel coordinates converted
/// to pingcal's convention, control coordinates multiplied by `object_unit_mm` (1000 for
/// DBAT's metres; 1 keeps DBAT's unit).
pub fn to_measurements(
    marks: &[MarkPoint],
    control: &[DbatControl],
    camera: &DbatCamera,
    object_unit_mm: f64,
) -> Measurements {
    let mut images: Vec<ImageSpec> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for m in marks {
        if seen.insert(m.image.clone()) {
            images.push(ImageSpec {
                name: m.image.clone(),
                camera: camera.name.clone(),
                pose: None,
                fixed: false,
            });
        }
    }
    let mut intrinsics = BTreeMap::new();
    intrinsics.insert("c".to_string(), camera.c_mm);
    Measurements {
        format: None,
        cameras: vec![CameraSpec {
            name: camera.name.clone(),
            model: "photogrammetric".into(),
            width: camera.width,
            height: camera.height,
            pixel_size_mm: camera.pixel_size_mm,
            intrinsics,
            calibrate: Vec::new(),
        }],
        images,
        image_points: marks
            .iter()
            .map(|m| {
                let uv = dbat_pixel_to_pingcal(m.x, m.y);
                ImagePoint {
                    image: m.image.clone(),
                    point: m.point.clone(),
                    x: uv.x,
                    y: uv.y,
                    sigma_px: m.sigma,
                }
            })
            .collect(),
        distances: Vec::new(),
        control_points: control
            .iter()
            .map(|c| ControlPoint {
                id: c.id.clone(),
                xyz: c.xyz.map(|v| v * object_unit_mm),
                sigma_mm: c.sigma.map(|s| s.map(|v| v * object_unit_mm)),
                fixed: c.sigma.is_none(),
            })
            .collect(),
    }
}

fn read(path: &Path) -> Result<String, DbatError> {
    std::fs::read_to_string(path).map_err(|e| DbatError::Io {
        file: path.display().to_string(),
        message: e.to_string(),
    })
}

/// Reads DBAT's mark-point and control files into [`Measurements`] (see
/// [`to_measurements`]).
pub fn read_dbat(
    markpts: &Path,
    control: &Path,
    camera: &DbatCamera,
    object_unit_mm: f64,
) -> Result<Measurements, DbatError> {
    let marks = parse_markpts(&read(markpts)?, &markpts.display().to_string())?;
    let ctrl = parse_control(&read(control)?, &control.display().to_string())?;
    Ok(to_measurements(&marks, &ctrl, camera, object_unit_mm))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MARKS: &str = "# Mark points\n# Format: image id, point id, x, y, sxy\n 1,    2, 1429.1871, 1456.4278, 0.1\n 1, 1001, 10.5, 20.5, 0.1\n 2, 2, 100, 200, 0.2\n";
    const CTRL: &str = "# Id,label,X,Y,Z\n1001,CP1,0,1,0\n1002,CP2,1,1,0\n";
    const WEIGHTED: &str = "# Id,label,X,Y,Z,sxyz\n1001,CP1,0,1,0,0.001\n";

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let m = parse_markpts(&format!("\u{feff}{MARKS}"), "markpts.txt").unwrap();
        assert_eq!(m.len(), 3);
        let c = parse_control("\u{feff}1001,CP1,0,1,0\n", "c.txt").unwrap();
        assert_eq!(c[0].id, "1001");
    }

    #[test]
    fn parses_marks_and_control() {
        let m = parse_markpts(MARKS, "markpts.txt").unwrap();
        assert_eq!(m.len(), 3);
        assert_eq!(m[0].image, "1");
        assert_eq!(m[0].point, "2");
        assert_eq!(m[0].x, 1429.1871);
        assert_eq!(m[2].sigma, 0.2);
        let c = parse_control(CTRL, "c.txt").unwrap();
        assert_eq!(c[1].xyz, [1.0, 1.0, 0.0]);
        assert!(c[0].sigma.is_none());
        let w = parse_control(WEIGHTED, "w.txt").unwrap();
        assert_eq!(w[0].sigma, Some([0.001; 3]));
    }

    #[test]
    fn builds_a_problem_in_pingcal_pixels_and_mm() {
        let m = parse_markpts(MARKS, "markpts.txt").unwrap();
        let c = parse_control(CTRL, "c.txt").unwrap();
        let meas = to_measurements(&m, &c, &DbatCamera::c4040z(), 1000.0);
        let b = meas.to_problem().unwrap();
        assert_eq!(b.problem.images.len(), 2);
        assert_eq!(b.problem.observations.len(), 3);
        let o = b.problem.observations[1];
        assert_eq!(o.uv, Vector2::new(10.0, 20.0));
        let k = b.point_index["1002"];
        assert_eq!(b.problem.points[k].position.x, 1000.0);
        assert!(b.problem.points[k].fixed);
    }

    #[test]
    fn errors_name_file_and_line() {
        let e = parse_markpts("# h\n1, 2, 3\n", "markpts.txt").unwrap_err();
        assert!(matches!(e, DbatError::Line { line: 2, .. }));
        assert!(e.to_string().starts_with("markpts.txt:2:"), "{e}");
        let e = parse_markpts("1, 2, 3, nan, 0.1\n", "m.txt").unwrap_err();
        assert!(e.to_string().contains("m.txt:1"), "{e}");
        let e = parse_markpts("1, 2, 3, 4, -0.1\n", "m.txt").unwrap_err();
        assert!(e.to_string().contains("positive"), "{e}");
        let e = parse_control("1001,CP1,0,1\n", "c.txt").unwrap_err();
        assert!(e.to_string().starts_with("c.txt:1:"), "{e}");
        let e = parse_control("1,a,0,0,0\n1,b,1,1,1\n", "c.txt").unwrap_err();
        assert!(e.to_string().contains("twice"), "{e}");
        assert!(matches!(
            parse_markpts("# nothing\n", "m.txt"),
            Err(DbatError::Empty { .. })
        ));
    }

    #[test]
    fn a_point_measured_twice_in_an_image_names_the_file_and_both_lines() {
        let e = parse_markpts(
            "16, 36, 1, 2, 0.1\n16, 5, 1, 2, 0.1\n16, 36, 3, 4, 0.1\n",
            "markpts.txt",
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "markpts.txt:3: point '36' is measured twice in image '16' (first on line 1)"
        );
        // The same point in another image is fine.
        assert!(parse_markpts("16, 36, 1, 2, 0.1\n17, 36, 3, 4, 0.1\n", "m.txt").is_ok());
        // Control characters of the file are not echoed raw.
        let e = parse_markpts("1, 2, 3\u{1b}[2J, 4, 0.1\n", "m.txt")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("x '3\\u{1b}[2J'") && !e.contains('\u{1b}'),
            "{e}"
        );
    }

    #[test]
    fn principal_point_conversion() {
        let cam = DbatCamera::c4040z();
        // The array centre in DBAT's system maps to (0, 0).
        let (xp, yp) = dbat_principal_point(
            0.5 * 2272.0 * cam.pixel_size_mm,
            0.5 * 1704.0 * cam.pixel_size_mm,
            &cam,
        );
        assert!(xp.abs() < 1e-12 && yp.abs() < 1e-12);
        // A principal point above the centre in the image (smaller DBAT y) has yp > 0.
        let (_, yp) = dbat_principal_point(3.6, 2.6, &cam);
        assert!(yp > 0.0);
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_text_never_panics(s in "\\PC{0,300}") {
            let _ = parse_markpts(&s, "m.txt");
            let _ = parse_control(&s, "c.txt");
        }

        #[test]
        fn numeric_lines_never_panic(a in proptest::collection::vec("[-+0-9.eE, naif]{0,12}", 0..8)) {
            let s = a.join(",");
            let _ = parse_markpts(&s, "m.txt");
            let _ = parse_control(&s, "c.txt");
        }
    }
}
