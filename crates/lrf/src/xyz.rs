//! Text coordinate files: plain XYZ clouds (`x y z [anything...]`) and labelled points
//! (`id x y z [sx sy sz]`) as `pingcal register` reads them. Whitespace or commas separate
//! the fields; `#` starts a comment. A UTF-8 byte-order mark at the start is skipped.
//! Coordinates (and standard deviations) beyond ±[`MAX_COORDINATE_MM`] (10 km) are refused,
//! naming the file and line: no calibration set-up spans that, and such a number (a
//! `1e308`) would only turn into infinite means and null JSON further on.

use crate::cloud::Cloud;
use crate::error::{LrfError, Result};
use nalgebra::Vector3;
use std::io::BufRead;

fn fields(line: &str) -> Vec<&str> {
    let body = line.split('#').next().unwrap_or("");
    body.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect()
}

/// Coordinates beyond ± this many millimetres (10 km) are refused.
pub const MAX_COORDINATE_MM: f64 = 1e7;

fn num(file: &str, line: usize, what: &str, s: &str) -> Result<f64> {
    match s.parse::<f64>() {
        Ok(v) if v.abs() <= MAX_COORDINATE_MM => Ok(v),
        Ok(v) if v.is_finite() => Err(LrfError::parse(
            file,
            line,
            format!("{what}: {v:e} mm is beyond ±{MAX_COORDINATE_MM:e} mm (10 km)"),
        )),
        _ => Err(LrfError::parse(
            file,
            line,
            format!("{what}: expected a number, found {s:?}"),
        )),
    }
}

fn lines<R: BufRead>(
    input: R,
    file: &str,
    mut f: impl FnMut(usize, &str) -> Result<()>,
) -> Result<()> {
    let mut input = input;
    let mut buf = Vec::new();
    let mut n = 0;
    loop {
        buf.clear();
        n += 1;
        if input
            .read_until(b'\n', &mut buf)
            .map_err(|e| LrfError::io(file, e))?
            == 0
        {
            return Ok(());
        }
        if !buf.ends_with(b"\n") && !buf.iter().all(u8::is_ascii_whitespace) {
            return Err(LrfError::cut_short(file, n));
        }
        let s =
            std::str::from_utf8(&buf).map_err(|_| LrfError::parse(file, n, "not UTF-8 text"))?;
        f(n, LrfError::without_bom(n, s))?;
    }
}

/// Reads an XYZ cloud: the first three numeric columns of each line are x, y, z in mm.
pub fn read_xyz<R: BufRead>(input: R, file: &str) -> Result<Cloud> {
    let mut pts = Vec::new();
    lines(input, file, |n, s| {
        let f = fields(s);
        if f.is_empty() {
            return Ok(());
        }
        if f.len() < 3 {
            return Err(LrfError::parse(
                file,
                n,
                format!("expected `x y z`, found {} field(s)", f.len()),
            ));
        }
        pts.push(Vector3::new(
            num(file, n, "x", f[0])?,
            num(file, n, "y", f[1])?,
            num(file, n, "z", f[2])?,
        ));
        Ok(())
    })?;
    if pts.is_empty() {
        return Err(LrfError::Empty {
            file: file.into(),
            msg: "no points".into(),
        });
    }
    Ok(Cloud::from_points(pts))
}

/// Reads an XYZ file from disk.
pub fn read_xyz_file(path: &std::path::Path) -> Result<Cloud> {
    let name = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| LrfError::io(&name, e))?;
    read_xyz(std::io::BufReader::new(f), &name)
}

/// One labelled point: an id, coordinates in mm and optional standard deviations in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledPoint {
    /// Point id as written in the file.
    pub id: String,
    /// Coordinates, mm.
    pub xyz: Vector3<f64>,
    /// Standard deviations of x, y, z in mm, when the file gives them.
    pub sigma: Option<Vector3<f64>>,
}

impl LabelledPoint {
    /// As an observation for a registration: its σ's on the diagonal of the covariance, or
    /// 1 mm where the file gives none (the registration then scales the weights by σ₀²).
    pub fn to_obs(&self) -> crate::registration::PointObs {
        let s = self.sigma.unwrap_or(Vector3::new(1.0, 1.0, 1.0));
        crate::registration::PointObs {
            id: self.id.clone(),
            xyz: self.xyz,
            cov: nalgebra::Matrix3::from_diagonal(&s.component_mul(&s)),
        }
    }
}

/// Reads labelled points: `id x y z` or `id x y z sx sy sz` per line. Ids must be unique.
pub fn read_labelled<R: BufRead>(input: R, file: &str) -> Result<Vec<LabelledPoint>> {
    let mut out: Vec<LabelledPoint> = Vec::new();
    let mut seen = std::collections::HashMap::new();
    lines(input, file, |n, s| {
        let f = fields(s);
        if f.is_empty() {
            return Ok(());
        }
        if f.len() != 4 && f.len() != 7 {
            return Err(LrfError::parse(
                file,
                n,
                format!(
                    "expected `id x y z` or `id x y z sx sy sz`, found {} field(s)",
                    f.len()
                ),
            ));
        }
        let xyz = Vector3::new(
            num(file, n, "x", f[1])?,
            num(file, n, "y", f[2])?,
            num(file, n, "z", f[3])?,
        );
        let sigma = if f.len() == 7 {
            let s = Vector3::new(
                num(file, n, "sx", f[4])?,
                num(file, n, "sy", f[5])?,
                num(file, n, "sz", f[6])?,
            );
            if s.iter().any(|&v| v <= 0.0) {
                return Err(LrfError::parse(
                    file,
                    n,
                    "standard deviations must be positive",
                ));
            }
            Some(s)
        } else {
            None
        };
        if let Some(prev) = seen.insert(f[0].to_string(), n) {
            return Err(LrfError::parse(
                file,
                n,
                format!("id {:?} already on line {prev}", f[0]),
            ));
        }
        out.push(LabelledPoint {
            id: f[0].to_string(),
            xyz,
            sigma,
        });
        Ok(())
    })?;
    if out.is_empty() {
        return Err(LrfError::Empty {
            file: file.into(),
            msg: "no points (expected `id x y z` lines)".into(),
        });
    }
    Ok(out)
}

/// Reads a labelled-point file from disk.
pub fn read_labelled_file(path: &std::path::Path) -> Result<Vec<LabelledPoint>> {
    let name = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| LrfError::io(&name, e))?;
    read_labelled(std::io::BufReader::new(f), &name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xyz_with_comments_commas_and_extra_columns() {
        let c = read_xyz(
            "# cloud\n1 2 3\n4,5,6, 255 0 0\n\n7\t8\t9 # c\n".as_bytes(),
            "a.xyz",
        )
        .unwrap();
        assert_eq!(c.len(), 3);
        assert_eq!(c.points[1], Vector3::new(4.0, 5.0, 6.0));
        let e = read_xyz("1 2 3\n1 2\n".as_bytes(), "a.xyz")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "a.xyz:2: expected `x y z`, found 2 field(s)");
        let e = read_xyz("1 2 zz\n".as_bytes(), "a.xyz")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "a.xyz:1: z: expected a number, found \"zz\"");
        assert!(read_xyz("# nothing\n".as_bytes(), "a.xyz").is_err());
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let v = read_labelled("\u{feff}B1 1 2 3\n".as_bytes(), "p.txt").unwrap();
        assert_eq!(v[0].id, "B1");
        let c = read_xyz("\u{feff}1 2 3\n".as_bytes(), "a.xyz").unwrap();
        assert_eq!(c.points[0], Vector3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn huge_coordinates_are_refused_with_the_line() {
        let e = read_labelled("B1 1 2 3\nB4 1e308 2 3\n".as_bytes(), "p.txt")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "p.txt:2: x: 1e308 mm is beyond ±1e7 mm (10 km)");
        let e = read_labelled("B1 1 2 inf\n".as_bytes(), "p.txt")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "p.txt:1: z: expected a number, found \"inf\"");
        let e = read_xyz("1 2 3\n1 -2e7 3\n".as_bytes(), "a.xyz")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "a.xyz:2: y: -2e7 mm is beyond ±1e7 mm (10 km)");
        assert!(read_labelled("B1 1e7 -1e7 0\n".as_bytes(), "p.txt").is_ok());
    }

    #[test]
    fn the_bad_input_with_a_check_point_of_1e308_is_refused() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(
            "../../../shared/data/bad-inputs/register_check_point_1e308_gives_inf_mean_and_null_json.txt",
        );
        if !path.exists() {
            println!("skipped: {} is absent", path.display());
            return;
        }
        let e = read_labelled_file(&path).unwrap_err().to_string();
        assert!(
            e.contains("register_check_point_1e308_gives_inf_mean_and_null_json.txt:")
                && e.contains("is beyond ±1e7 mm"),
            "{e}"
        );
    }

    #[test]
    fn labelled_points() {
        let v = read_labelled("B1 1 2 3\nB2, 4, 5, 6, 0.5, 0.5, 1\n".as_bytes(), "p.txt").unwrap();
        assert_eq!(v[0].id, "B1");
        assert_eq!(v[1].sigma, Some(Vector3::new(0.5, 0.5, 1.0)));
        let e = read_labelled("B1 1 2 3\nB1 1 2 3\n".as_bytes(), "p.txt")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "p.txt:2: id \"B1\" already on line 1");
        let e = read_labelled("B1 1 2\n".as_bytes(), "p.txt")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("p.txt:1: expected `id x y z`"), "{e}");
    }
}
