//! PLY clouds: reads ascii, binary little- and big-endian files (the `vertex` element's
//! `x`, `y`, `z`, any scalar type); writes binary little-endian PLY with colours, which
//! CloudCompare and MeshLab open.
//!
//! The header's counts are held to: a file that ends early is refused, and so is data
//! after the last element when that element is the vertex list. A byte-order mark before
//! `ply` is skipped; coordinates beyond ±1e7 mm ([`crate::xyz::MAX_COORDINATE_MM`]) are
//! refused.

use crate::cloud::Cloud;
use crate::error::{LrfError, Result};
use crate::xyz::MAX_COORDINATE_MM;
use nalgebra::Vector3;
use std::io::{BufRead, Read, Write};

#[derive(Clone, Copy, PartialEq, Debug)]
enum Format {
    Ascii,
    BinLe,
    BinBe,
}

#[derive(Clone, Copy, Debug)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
    fn decode(self, b: &[u8], be: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                (if be {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2),
            Scalar::U16 => get!(u16, 2),
            Scalar::I32 => get!(i32, 4),
            Scalar::U32 => get!(u32, 4),
            Scalar::F32 => get!(f32, 4),
            Scalar::F64 => get!(f64, 8),
        }
    }
}

struct Element {
    name: String,
    count: usize,
    /// (name, type); `None` type marks a list property.
    props: Vec<(String, Option<Scalar>)>,
}

/// Reads a PLY cloud (the vertex positions).
pub fn read_ply<R: BufRead>(mut input: R, file: &str) -> Result<Cloud> {
    let mut buf = Vec::new();
    let mut line_no = 0;
    let mut next_line = |input: &mut R, line_no: &mut usize| -> Result<String> {
        buf.clear();
        *line_no += 1;
        let n = input
            .read_until(b'\n', &mut buf)
            .map_err(|e| LrfError::io(file, e))?;
        if n == 0 {
            return Err(LrfError::parse(
                file,
                *line_no,
                "end of file inside the PLY header (no `end_header`)",
            ));
        }
        let s = std::str::from_utf8(&buf)
            .map_err(|_| LrfError::parse(file, *line_no, "header is not text"))?;
        Ok(LrfError::without_bom(*line_no, s).trim().to_string())
    };
    let first = next_line(&mut input, &mut line_no).map_err(|e| match e {
        LrfError::Parse { .. } => LrfError::Empty {
            file: file.into(),
            msg: "empty file (expected `ply`)".into(),
        },
        e => e,
    })?;
    if first != "ply" {
        return Err(LrfError::parse(file, 1, "expected `ply` as the first line"));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let l = next_line(&mut input, &mut line_no)?;
        let w: Vec<&str> = l.split_whitespace().collect();
        match w.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                format = Some(match w.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::BinLe,
                    Some("binary_big_endian") => Format::BinBe,
                    other => {
                        return Err(LrfError::parse(
                            file,
                            line_no,
                            format!("unknown format {other:?} (expected ascii, binary_little_endian or binary_big_endian)"),
                        ))
                    }
                })
            }
            Some("element") => {
                let (Some(name), Some(count)) = (w.get(1), w.get(2).and_then(|c| c.parse::<usize>().ok())) else {
                    return Err(LrfError::parse(file, line_no, "expected `element NAME COUNT`"));
                };
                elements.push(Element { name: name.to_string(), count, props: Vec::new() });
            }
            Some("property") => {
                let Some(el) = elements.last_mut() else {
                    return Err(LrfError::parse(file, line_no, "property before any element"));
                };
                if w.get(1) == Some(&"list") {
                    el.props.push((w.get(4).unwrap_or(&"").to_string(), None));
                } else {
                    let (Some(t), Some(name)) = (w.get(1).and_then(|t| Scalar::parse(t)), w.get(2)) else {
                        return Err(LrfError::parse(file, line_no, "expected `property TYPE NAME`"));
                    };
                    el.props.push((name.to_string(), Some(t)));
                }
            }
            Some("end_header") => break,
            Some(other) => return Err(LrfError::parse(file, line_no, format!("unknown header keyword {other:?}"))),
        }
    }
    let format =
        format.ok_or_else(|| LrfError::parse(file, line_no, "header has no `format` line"))?;
    let Some(vi) = elements.iter().position(|e| e.name == "vertex") else {
        return Err(LrfError::parse(
            file,
            line_no,
            "header has no `element vertex`",
        ));
    };
    let vertex = &elements[vi];
    let find = |n: &str| vertex.props.iter().position(|(p, _)| p == n);
    let (Some(ix), Some(iy), Some(iz)) = (find("x"), find("y"), find("z")) else {
        return Err(LrfError::parse(
            file,
            line_no,
            "vertex element lacks an x, y or z property",
        ));
    };
    let skip_before: usize = elements[..vi].iter().map(|e| e.count).sum();
    let mut pts = Vec::with_capacity(vertex.count.min(1 << 24));
    if format == Format::Ascii {
        if elements[..vi].iter().any(|e| e.count > 0) {
            // skip the lines of the elements written before the vertices
            for _ in 0..skip_before {
                next_line(&mut input, &mut line_no).map_err(|_| {
                    LrfError::parse(file, line_no, "file ends before the vertex list")
                })?;
            }
        }
        for k in 0..vertex.count {
            let l = next_line(&mut input, &mut line_no).map_err(|_| {
                LrfError::parse(
                    file,
                    line_no,
                    format!("file ends after {k} of {} vertices", vertex.count),
                )
            })?;
            let w: Vec<&str> = l.split_whitespace().collect();
            if w.len() < vertex.props.len() {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!("expected {} values, found {}", vertex.props.len(), w.len()),
                ));
            }
            let g = |i: usize, n: &str| -> Result<f64> {
                match w[i].parse::<f64>() {
                    Ok(v) if v.abs() <= MAX_COORDINATE_MM => Ok(v),
                    Ok(v) if v.is_finite() => Err(LrfError::parse(
                        file,
                        line_no,
                        format!("{n}: {v:e} mm is beyond ±{MAX_COORDINATE_MM:e} mm (10 km)"),
                    )),
                    _ => Err(LrfError::parse(
                        file,
                        line_no,
                        format!("{n}: expected a number, found {:?}", w[i]),
                    )),
                }
            };
            pts.push(Vector3::new(g(ix, "x")?, g(iy, "y")?, g(iz, "z")?));
        }
        if vi + 1 == elements.len() {
            // Nothing but blank lines may follow the last element.
            let mut rest = String::new();
            loop {
                rest.clear();
                line_no += 1;
                let n = input
                    .read_line(&mut rest)
                    .map_err(|e| LrfError::io(file, e))?;
                if n == 0 {
                    break;
                }
                if !rest.trim().is_empty() {
                    return Err(trailing(file, line_no, vertex.count));
                }
            }
        }
    } else {
        let be = format == Format::BinBe;
        for e in &elements[..vi] {
            if e.props.iter().any(|p| p.1.is_none()) && e.count > 0 {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!(
                        "binary element {:?} with a list before the vertices is not supported",
                        e.name
                    ),
                ));
            }
            let rec: usize = e.props.iter().map(|p| p.1.map_or(0, |s| s.size())).sum();
            let bytes = (rec as u64).saturating_mul(e.count as u64);
            let skipped = std::io::copy(&mut (&mut input).take(bytes), &mut std::io::sink())
                .map_err(|ev| LrfError::io(file, ev))?;
            if skipped != bytes {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    "file ends before the vertex list",
                ));
            }
        }
        if vertex.props.iter().any(|p| p.1.is_none()) {
            return Err(LrfError::parse(
                file,
                line_no,
                "binary vertex element with a list property is not supported",
            ));
        }
        let offs: Vec<(usize, Scalar)> = vertex
            .props
            .iter()
            .scan(0usize, |o, p| {
                let s = p.1.unwrap_or(Scalar::U8);
                let r = (*o, s);
                *o += s.size();
                Some(r)
            })
            .collect();
        let rec: usize = offs.iter().map(|o| o.1.size()).sum();
        let mut r = vec![0u8; rec];
        for k in 0..vertex.count {
            input.read_exact(&mut r).map_err(|_| {
                LrfError::parse(
                    file,
                    k + 1,
                    format!(
                        "binary vertex {} of {}: file ends early",
                        k + 1,
                        vertex.count
                    ),
                )
            })?;
            let v = |i: usize| offs[i].1.decode(&r[offs[i].0..], be);
            let p = Vector3::new(v(ix), v(iy), v(iz));
            if !p.iter().all(|c| c.abs() <= MAX_COORDINATE_MM) {
                return Err(LrfError::parse(
                    file,
                    k + 1,
                    format!(
                        "binary vertex {}: not a finite number within ±{MAX_COORDINATE_MM:e} mm",
                        k + 1
                    ),
                ));
            }
            pts.push(p);
        }
        if vi + 1 == elements.len() {
            let mut one = [0u8; 1];
            if input.read(&mut one).map_err(|e| LrfError::io(file, e))? > 0 {
                return Err(trailing(file, vertex.count + 1, vertex.count));
            }
        }
    }
    if pts.is_empty() {
        return Err(LrfError::Empty {
            file: file.into(),
            msg: "no vertices".into(),
        });
    }
    Ok(Cloud::from_points(pts))
}

/// The error for data after the last element the header declares (a duplicated or extra
/// line shifts the vertices, so the cloud read would be wrong).
fn trailing(file: &str, line: usize, count: usize) -> LrfError {
    LrfError::parse(
        file,
        line,
        format!("trailing data after the {count} vertices the header declares: a duplicated or extra line?"),
    )
}

/// Reads a PLY file from disk.
pub fn read_ply_file(path: &std::path::Path) -> Result<Cloud> {
    let name = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| LrfError::io(&name, e))?;
    read_ply(std::io::BufReader::new(f), &name)
}

/// Writes points with RGB colours as a binary little-endian PLY (`float x y z`,
/// `uchar red green blue`). `colors` must be as long as `points`.
pub fn write_ply<W: Write>(
    mut w: W,
    points: &[Vector3<f64>],
    colors: &[[u8; 3]],
    comments: &[String],
) -> std::io::Result<()> {
    write_vertex_header(&mut w, points.len(), comments)?;
    writeln!(w, "end_header")?;
    w.write_all(&vertex_records(points, colors))
}

/// The header up to and with the `vertex` element of [`write_ply`] (no `end_header`).
fn write_vertex_header<W: Write>(w: &mut W, n: usize, comments: &[String]) -> std::io::Result<()> {
    writeln!(w, "ply\nformat binary_little_endian 1.0")?;
    for c in comments {
        writeln!(w, "comment {}", c.replace('\n', " "))?;
    }
    writeln!(w, "element vertex {n}")?;
    writeln!(w, "property float x\nproperty float y\nproperty float z")?;
    writeln!(
        w,
        "property uchar red\nproperty uchar green\nproperty uchar blue"
    )
}

/// The binary records of the `vertex` element of [`write_ply`].
fn vertex_records(points: &[Vector3<f64>], colors: &[[u8; 3]]) -> Vec<u8> {
    assert_eq!(points.len(), colors.len(), "one colour per point");
    let mut rec = Vec::with_capacity(points.len() * 15);
    for (p, c) in points.iter().zip(colors) {
        for k in 0..3 {
            rec.extend_from_slice(&(p[k] as f32).to_le_bytes());
        }
        rec.extend_from_slice(c);
    }
    rec
}

/// Colours of the balls in [`write_cloud_with_spheres`], in turn.
pub const PALETTE: [[u8; 3]; 8] = [
    [230, 25, 75],
    [60, 180, 75],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
    [210, 245, 60],
];

/// The cloud in grey with each ball's inliers in its colour, as binary PLY, and the fitted
/// spheres after it as an element of their own, `element sphere N` with `float x y z
/// radius` and the ball's colour: the vertices are exactly the scan points, so the file
/// reads back as the same cloud ([`read_ply`] reads the `vertex` element only).
pub fn write_cloud_with_spheres<W: Write>(
    mut w: W,
    cloud: &Cloud,
    balls: &[crate::ball_finder::Ball],
    radius: f64,
    comments: &[String],
) -> std::io::Result<()> {
    let mut colors = vec![[160u8, 160, 160]; cloud.len()];
    for (k, b) in balls.iter().enumerate() {
        for &i in &b.inliers {
            colors[i] = PALETTE[k % PALETTE.len()];
        }
    }
    write_vertex_header(&mut w, cloud.len(), comments)?;
    writeln!(w, "element sphere {}", balls.len())?;
    writeln!(
        w,
        "property float x\nproperty float y\nproperty float z\nproperty float radius"
    )?;
    writeln!(
        w,
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header"
    )?;
    let mut rec = vertex_records(&cloud.points, &colors);
    for (k, b) in balls.iter().enumerate() {
        for v in [b.centre.x, b.centre.y, b.centre.z, radius] {
            rec.extend_from_slice(&(v as f32).to_le_bytes());
        }
        rec.extend_from_slice(&PALETTE[k % PALETTE.len()]);
    }
    w.write_all(&rec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_ply_with_extra_properties_and_faces() {
        let t = "ply\nformat ascii 1.0\ncomment hi\nelement vertex 2\nproperty float y\nproperty float x\nproperty double z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n1 2 3 255\n4 5 6 0\n3 0 1 1\n";
        let c = read_ply(t.as_bytes(), "a.ply").unwrap();
        assert_eq!(
            c.points,
            vec![Vector3::new(2.0, 1.0, 3.0), Vector3::new(5.0, 4.0, 6.0)]
        );
    }

    #[test]
    fn binary_round_trip_and_big_endian() {
        let pts = vec![
            Vector3::new(1.5, -2.0, 1000.25),
            Vector3::new(0.0, 3.0, -4.0),
        ];
        let mut out = Vec::new();
        write_ply(&mut out, &pts, &[[1, 2, 3], [4, 5, 6]], &["test".into()]).unwrap();
        let c = read_ply(&out[..], "b.ply").unwrap();
        assert_eq!(c.points, pts);
        let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty short z\nend_header\n".to_vec();
        be.extend_from_slice(&7.0f64.to_be_bytes());
        be.extend_from_slice(&(-8.5f64).to_be_bytes());
        be.extend_from_slice(&(-300i16).to_be_bytes());
        let c = read_ply(&be[..], "be.ply").unwrap();
        assert_eq!(c.points, vec![Vector3::new(7.0, -8.5, -300.0)]);
    }

    /// The cloud written with its spheres reads back as exactly its points: the spheres
    /// are their own element, not vertices.
    #[test]
    fn spheres_are_not_read_back_as_points() {
        let pts: Vec<Vector3<f64>> = (0..50)
            .map(|i| Vector3::new(i as f64, -2.0 * i as f64, 1000.0 + 0.25 * i as f64))
            .collect();
        let cloud = Cloud::from_points(pts.clone());
        let ball = crate::ball_finder::Ball {
            centre: Vector3::new(10.0, 20.0, 1500.0),
            cov: nalgebra::Matrix3::identity(),
            inliers: vec![3, 4, 5],
            cluster_points: 3,
            rejected_points: 0,
            sigma0: 1.0,
            range_mm: 1500.0,
            support: Default::default(),
        };
        let mut out = Vec::new();
        write_cloud_with_spheres(&mut out, &cloud, &[ball.clone(), ball], 19.0, &[]).unwrap();
        let text = String::from_utf8_lossy(&out);
        assert!(text.contains("element vertex 50\n") && text.contains("element sphere 2\n"));
        let back = read_ply(&out[..], "c.ply").unwrap();
        assert_eq!(
            back.points, pts,
            "the vertices are the scan points, no more"
        );
        let end = text.find("end_header\n").unwrap() + "end_header\n".len();
        assert_eq!(out.len() - end, 50 * 15 + 2 * 19, "50 vertices, 2 spheres");
        let r = &out[out.len() - 19 + 12..out.len() - 19 + 16];
        assert_eq!(
            f32::from_le_bytes(r.try_into().unwrap()),
            19.0,
            "the radius"
        );
    }

    #[test]
    fn errors_name_the_problem() {
        let e = read_ply("".as_bytes(), "e.ply").unwrap_err().to_string();
        assert!(e.contains("empty file"), "{e}");
        let t = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 q\n";
        let e = read_ply(t.as_bytes(), "a.ply").unwrap_err().to_string();
        assert_eq!(e, "a.ply:9: z: expected a number, found \"q\"");
        let t = t.replace("4 5 q", "4 5e300 6");
        let e = read_ply(t.as_bytes(), "a.ply").unwrap_err().to_string();
        assert_eq!(e, "a.ply:9: y: 5e300 mm is beyond ±1e7 mm (10 km)");
        let t = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0";
        let e = read_ply(t.as_bytes(), "b.ply").unwrap_err().to_string();
        assert!(e.contains("binary vertex 1 of 3: file ends early"), "{e}");
    }
}
