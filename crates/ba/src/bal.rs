//! Reading and writing BAL ("Bundle Adjustment in the Large") problem files, plain or
//! bzip2-compressed.
//!
//! Format (Agarwal et al. 2010): a header `ncam npts nobs`; `nobs` lines `cam pt x y`;
//! then 9 values per camera (angle-axis R, t, f, k1, k2) and 3 per point, whitespace
//! separated. Errors name the line and what was expected there.
//!
//! The header's counts are checked against the body both ways: a file that ends early is
//! refused, and so is one with anything but whitespace after the last point (a duplicated
//! or extra line shifts every value after it, so reading on would solve a wrong problem).
//! Values beyond ±1e12 are refused as corrupt.

use crate::camera::BalCamera;
use crate::io::measurements::MAX_MAGNITUDE;
use crate::keys::{CameraKey, ImageKey, PointKey};
use crate::problem::{Camera, Image, Observation, Point, Problem};
use nalgebra::{Vector2, Vector3};
use pingcal_geometry::Rigid3;
use pingcal_geometry::{exp_so3, log_so3};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;
use std::sync::Arc;

/// A BAL file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum BalError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file's path as given.
        path: String,
        /// The underlying error (opening, reading or decompressing).
        source: std::io::Error,
    },
    /// The content is not a valid BAL problem.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file's path as given.
        path: String,
        /// 1-based line of the (decompressed) text; for a file that ends early, its last
        /// line.
        line: usize,
        /// What was found and what was expected.
        message: String,
    },
}

/// Reads a BAL problem from `path` (`.bz2` is decompressed). All observations get σ = 1 px.
pub fn read_bal(path: &Path) -> Result<Problem, BalError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| BalError::Io {
        path: name.clone(),
        source,
    })?;
    let reader: Box<dyn Read> = if path.extension().is_some_and(|e| e == "bz2") {
        Box::new(bzip2::read::MultiBzDecoder::new(file))
    } else {
        Box::new(file)
    };
    parse_bal(BufReader::with_capacity(1 << 20, reader), &name)
}

/// Token reader that knows the line it is on.
struct Tokens<R: BufRead> {
    reader: R,
    line: String,
    pos: usize,
    line_no: usize,
    path: String,
}

impl<R: BufRead> Tokens<R> {
    fn err(&self, message: impl Into<String>) -> BalError {
        BalError::Parse {
            path: self.path.clone(),
            line: self.line_no,
            message: message.into(),
        }
    }

    fn next(&mut self, what: &str) -> Result<&str, BalError> {
        loop {
            let rest = &self.line[self.pos..];
            let trimmed = rest.trim_start();
            if !trimmed.is_empty() {
                let start = self.pos + (rest.len() - trimmed.len());
                let len = trimmed.find(char::is_whitespace).unwrap_or(trimmed.len());
                self.pos = start + len;
                return Ok(&self.line[start..start + len]);
            }
            self.line.clear();
            self.pos = 0;
            let n = self
                .reader
                .read_line(&mut self.line)
                .map_err(|e| BalError::Io {
                    path: self.path.clone(),
                    source: e,
                })?;
            if n == 0 {
                return Err(BalError::Parse {
                    path: self.path.clone(),
                    line: self.line_no,
                    message: format!("file ends early: expected {what}"),
                });
            }
            self.line_no += 1;
            if self.line_no == 1 {
                // A UTF-8 byte-order mark is not part of the data.
                if let Some(rest) = self.line.strip_prefix('\u{feff}') {
                    self.line = rest.to_string();
                }
            }
        }
    }

    /// Refuses anything but whitespace after the last value the header declares.
    fn expect_end(&mut self, header: &str) -> Result<(), BalError> {
        match self.next("") {
            Ok(extra) => {
                let extra = crate::io::printable(extra);
                Err(self.err(format!(
                    "trailing data '{extra}' after the last point (the header declares {header}): \
                     a duplicated or extra line?"
                )))
            }
            Err(BalError::Parse { .. }) => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn f64(&mut self, what: &str) -> Result<f64, BalError> {
        let t = self.next(what)?;
        match t.parse::<f64>() {
            Ok(v) if v.abs() <= MAX_MAGNITUDE => Ok(v),
            Ok(v) if v.is_finite() => {
                Err(self.err(format!("{what}: {v:e} is beyond ±{MAX_MAGNITUDE:e}")))
            }
            _ => {
                let t = crate::io::printable(t);
                Err(self.err(format!("expected {what} (a finite number), found '{t}'")))
            }
        }
    }

    fn count(&mut self, what: &str) -> Result<usize, BalError> {
        let t = self.next(what)?;
        match t.parse::<usize>() {
            Ok(v) => Ok(v),
            Err(_) => {
                let t = crate::io::printable(t);
                Err(self.err(format!(
                    "expected {what} (a non-negative integer), found '{t}'"
                )))
            }
        }
    }
}

/// Parses a BAL problem from a reader; `path` is used in error messages.
pub fn parse_bal<R: BufRead>(reader: R, path: &str) -> Result<Problem, BalError> {
    let mut t = Tokens {
        reader,
        line: String::new(),
        pos: 0,
        line_no: 0,
        path: path.to_string(),
    };
    let ncam = t.count("the number of cameras")?;
    let npts = t.count("the number of points")?;
    let nobs = t.count("the number of observations")?;
    if nobs == 0 {
        return Err(t.err("the problem has no observations"));
    }
    // Guard against absurd headers before allocating.
    const LIMIT: usize = 200_000_000;
    if ncam > LIMIT || npts > LIMIT || nobs > LIMIT {
        return Err(t.err(format!(
            "implausible header: {ncam} cameras, {npts} points, {nobs} observations"
        )));
    }
    let mut observations = Vec::with_capacity(nobs.min(1 << 24));
    for _ in 0..nobs {
        let cam = t.count("a camera index")?;
        if cam >= ncam {
            return Err(t.err(format!(
                "camera index {cam} out of range (the header declares {ncam} cameras)"
            )));
        }
        let pt = t.count("a point index")?;
        if pt >= npts {
            return Err(t.err(format!(
                "point index {pt} out of range (the header declares {npts} points)"
            )));
        }
        let x = t.f64("an image x coordinate")?;
        let y = t.f64("an image y coordinate")?;
        observations.push(Observation {
            image: ImageKey(cam),
            point: PointKey(pt),
            uv: Vector2::new(x, y),
            sigma: 1.0,
        });
    }
    let model = Arc::new(BalCamera);
    let mut cameras = Vec::with_capacity(ncam.min(1 << 20));
    let mut images = Vec::with_capacity(ncam.min(1 << 20));
    for c in 0..ncam {
        let mut v = [0.0; 9];
        for (k, x) in v.iter_mut().enumerate() {
            *x = t.f64(&format!("camera {c} parameter {k} of 9"))?;
        }
        let rotation = exp_so3(&Vector3::new(v[0], v[1], v[2]));
        cameras.push(Camera::new(
            format!("cam{c}"),
            model.clone(),
            vec![v[6], v[7], v[8]],
        ));
        images.push(Image {
            name: format!("image{c}"),
            camera: CameraKey(c),
            camera_from_object: Rigid3 {
                rotation,
                translation: Vector3::new(v[3], v[4], v[5]),
            },
            fixed: false,
            fixed_centre: [false; 3],
        });
    }
    let mut points = Vec::with_capacity(npts.min(1 << 24));
    for p in 0..npts {
        let x = t.f64(&format!("point {p} X"))?;
        let y = t.f64(&format!("point {p} Y"))?;
        let z = t.f64(&format!("point {p} Z"))?;
        points.push(Point {
            name: p.to_string(),
            position: Vector3::new(x, y, z),
            fixed: false,
            fixed_axes: [false; 3],
        });
    }
    t.expect_end(&format!(
        "{ncam} cameras, {npts} points, {nobs} observations"
    ))?;
    Ok(Problem {
        cameras,
        images,
        points,
        observations,
        ..Default::default()
    })
}

/// Writes `problem` as BAL. Every image must use the BAL camera model with its own camera.
pub fn write_bal<W: Write>(problem: &Problem, mut w: W) -> std::io::Result<()> {
    writeln!(
        w,
        "{} {} {}",
        problem.images.len(),
        problem.points.len(),
        problem.observations.len()
    )?;
    for o in &problem.observations {
        writeln!(w, "{} {} {:.17e} {:.17e}", o.image, o.point, o.uv.x, o.uv.y)?;
    }
    for im in &problem.images {
        let aa = log_so3(&im.camera_from_object.rotation);
        let p = &problem.cameras[im.camera].params;
        for v in aa
            .iter()
            .chain(im.camera_from_object.translation.iter())
            .chain(p.iter().take(3))
        {
            writeln!(w, "{v:.17e}")?;
        }
    }
    for pt in &problem.points {
        for v in pt.position.iter() {
            writeln!(w, "{v:.17e}")?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "2 2 3\n0 0 1.0 2.0\n1 0 -1.0 0.5\n1 1 3.0 -2.0\n\
        0.1\n0.2\n0.3\n1\n2\n3\n500\n0.01\n0.001\n\
        0\n0\n0\n0\n0\n-5\n600\n0\n0\n\
        1 2 -10\n0.5 0.5 -12\n";

    #[test]
    fn reads_a_small_problem_and_round_trips() {
        let p = parse_bal(SMALL.as_bytes(), "small").unwrap();
        assert_eq!(
            (p.cameras.len(), p.points.len(), p.observations.len()),
            (2, 2, 3)
        );
        assert_eq!(p.cameras[0].params, vec![500.0, 0.01, 0.001]);
        assert!(
            (log_so3(&p.images[0].camera_from_object.rotation) - Vector3::new(0.1, 0.2, 0.3))
                .norm()
                < 1e-15
        );
        let mut out = Vec::new();
        write_bal(&p, &mut out).unwrap();
        let q = parse_bal(out.as_slice(), "again").unwrap();
        assert!(
            (q.images[0].camera_from_object.rotation - p.images[0].camera_from_object.rotation)
                .norm()
                < 1e-15
        );
        assert_eq!(q.points[1].position, p.points[1].position);
        assert_eq!(q.observations[2].uv, p.observations[2].uv);
    }

    fn error_of(text: &str) -> String {
        parse_bal(text.as_bytes(), "f.bal").unwrap_err().to_string()
    }

    #[test]
    fn bad_input_names_the_line_and_what_was_expected() {
        assert_eq!(
            error_of("2 2 3\n0 0 1.0 2.0\n"),
            "f.bal:2: file ends early: expected a camera index"
        );
        assert_eq!(
            error_of("2 2 0\n"),
            "f.bal:1: the problem has no observations"
        );
        assert_eq!(
            error_of("2 -2 3\n"),
            "f.bal:1: expected the number of points (a non-negative integer), found '-2'"
        );
        assert_eq!(
            error_of("2 2 1\n5 0 1 2\n"),
            "f.bal:2: camera index 5 out of range (the header declares 2 cameras)"
        );
        assert_eq!(
            error_of("2 2 1\n0 7 1 2\n"),
            "f.bal:2: point index 7 out of range (the header declares 2 points)"
        );
        assert_eq!(
            error_of("1 1 1\n0 0 nan 2\n"),
            "f.bal:2: expected an image x coordinate (a finite number), found 'nan'"
        );
        let truncated = &SMALL[..SMALL.len() - 12];
        assert!(
            error_of(truncated).contains("file ends early: expected point 1"),
            "{}",
            error_of(truncated)
        );
    }

    #[test]
    fn trailing_data_is_refused_with_the_line() {
        let e = error_of(&format!("{SMALL}7\n"));
        assert_eq!(
            e,
            "f.bal:25: trailing data '7' after the last point (the header declares 2 cameras, \
             2 points, 3 observations): a duplicated or extra line?"
        );
        // A duplicated observation line shifts everything after it: caught at the end.
        let dup = SMALL.replacen("1 0 -1.0 0.5\n", "1 0 -1.0 0.5\n1 0 -1.0 0.5\n", 1);
        assert!(
            error_of(&dup).contains("trailing data"),
            "{}",
            error_of(&dup)
        );
        // Trailing whitespace and blank lines are fine.
        assert!(parse_bal(format!("{SMALL}\n  \n").as_bytes(), "f.bal").is_ok());
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let p = parse_bal(format!("\u{feff}{SMALL}").as_bytes(), "f.bal").unwrap();
        assert_eq!(p.observations.len(), 3);
    }

    #[test]
    fn control_characters_are_not_echoed() {
        let e = error_of("1 1 1\n0 0 1\x1b[2J 2\n");
        assert!(e.contains("found '1\\u{1b}[2J'"), "{e}");
    }

    #[test]
    fn the_bad_input_with_a_duplicated_line_is_refused() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(
            "../../../shared/data/bad-inputs/bal_duplicated_line_accepted_rms75100px_rc0.bal",
        );
        if !path.exists() {
            println!("skipped: {} is absent", path.display());
            return;
        }
        let e = read_bal(&path).unwrap_err().to_string();
        assert!(
            e.contains("bal_duplicated_line_accepted_rms75100px_rc0.bal:")
                && e.contains("trailing data"),
            "{e}"
        );
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(1000))]

        /// Duplicating any line of a valid file, or cutting it anywhere before its last
        /// value, never passes silently: the reader refuses it, naming the file.
        #[test]
        fn duplicated_lines_and_truncations_are_refused(line in 0usize..25, cut in 0usize..200) {
            let lines: Vec<&str> = SMALL.lines().collect();
            let k = line % lines.len();
            let mut dup: Vec<&str> = lines.clone();
            dup.insert(k, lines[k]);
            let text = dup.join("\n") + "\n";
            let e = parse_bal(text.as_bytes(), "f.bal").unwrap_err().to_string();
            proptest::prop_assert!(e.starts_with("f.bal:"), "{}", e);
            let body = SMALL.trim_end();
            let at = cut.min(body.len() - 1);
            // A cut inside the last number leaves a shorter, still valid number.
            if at < body.len() - 4 {
                let e = parse_bal(&body.as_bytes()[..at], "f.bal").unwrap_err().to_string();
                proptest::prop_assert!(e.starts_with("f.bal:"), "{}", e);
            }
            let huge = SMALL.replacen("1.0 2.0", "1e309 2.0", 1);
            proptest::prop_assert!(parse_bal(huge.as_bytes(), "f.bal").is_err());
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..400)) {
            let _ = parse_bal(bytes.as_slice(), "fuzz");
        }

        #[test]
        fn mutated_valid_files_never_panic(cut in 0usize..200, insert in "[0-9 .e\\-\\n]{0,12}") {
            let mut s = SMALL.to_string();
            let at = cut.min(s.len());
            s.insert_str(at, &insert);
            let _ = parse_bal(s.as_bytes(), "fuzz");
        }
    }
}
