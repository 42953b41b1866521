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

/// A property of an element: one number, or a list (its count's type, its items' type).
#[derive(Clone, Copy, Debug)]
enum Prop {
    Scalar(Scalar),
    List(Scalar, Scalar),
}

struct Element {
    name: String,
    count: usize,
    props: Vec<(String, Prop)>,
}

/// Reads a PLY cloud (the vertex positions). Every element the header declares is read
/// (a list's length from its count), so a header that disagrees with its data — faces
/// declared and absent, a property missing from a line, data left over — is refused.
pub fn read_ply<R: BufRead>(mut input: R, file: &str) -> Result<Cloud> {
    let mut line_no = 0;
    let first = next_line(&mut input, file, &mut line_no).map_err(|e| match e {
        LrfError::Parse { .. } => LrfError::Empty {
            file: file.into(),
            msg: "empty file (expected `ply`)".into(),
        },
        e => e,
    })?;
    if first != "ply" {
        return Err(LrfError::parse(file, 1, "expected `ply` as the first line"));
    }
    let (format, elements) = read_header(&mut input, file, &mut line_no)?;
    let (vi, xyz) = vertex_coordinates(&elements, file, line_no)?;
    let pts = read_body(&mut input, format, &elements, (vi, xyz), file, &mut line_no)?;
    let last = elements.last().expect("the vertex element at least");
    check_nothing_after(&mut input, format, last, file, &mut line_no)?;
    if pts.is_empty() {
        return Err(LrfError::Empty {
            file: file.into(),
            msg: "no vertices".into(),
        });
    }
    Ok(Cloud::from_points(pts))
}

/// The index of the `vertex` element and of its `x`, `y`, `z` properties (numbers, not
/// lists).
fn vertex_coordinates(
    elements: &[Element],
    file: &str,
    line_no: usize,
) -> Result<(usize, [usize; 3])> {
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
    for (i, n) in [(ix, "x"), (iy, "y"), (iz, "z")] {
        if let Prop::List(..) = vertex.props[i].1 {
            return Err(LrfError::parse(
                file,
                line_no,
                format!("vertex property {n} is a list: expected one number per vertex"),
            ));
        }
    }
    Ok((vi, [ix, iy, iz]))
}

/// Every record of every element in the header's order, keeping the vertices' positions
/// (`vertex`: the vertex element's index and its `x`, `y`, `z` properties').
fn read_body<R: BufRead>(
    input: &mut R,
    format: Format,
    elements: &[Element],
    vertex: (usize, [usize; 3]),
    file: &str,
    line_no: &mut usize,
) -> Result<Vec<Vector3<f64>>> {
    let (vi, [ix, iy, iz]) = vertex;
    let mut pts = Vec::with_capacity(elements[vi].count.min(1 << 24));
    let mut record = Vec::new();
    for (e, el) in elements.iter().enumerate() {
        for k in 0..el.count {
            read_record(input, format, el, k, &mut record, file, line_no)?;
            if e == vi {
                let p = Vector3::new(record[ix], record[iy], record[iz]);
                let at = if format == Format::Ascii {
                    *line_no
                } else {
                    k + 1
                };
                check_position(&p, file, at)?;
                pts.push(p);
            }
        }
    }
    Ok(pts)
}

/// Record `k` of element `el` into `record`, in the file's format; errors name the line
/// (ascii) or the record (binary).
fn read_record<R: BufRead>(
    input: &mut R,
    format: Format,
    el: &Element,
    k: usize,
    record: &mut Vec<f64>,
    file: &str,
    line_no: &mut usize,
) -> Result<()> {
    match format {
        Format::Ascii => {
            let l = next_line(input, file, line_no).map_err(|e| {
                if e.is_cut_short() {
                    e
                } else {
                    LrfError::parse(file, *line_no, ends_after(k, el))
                }
            })?;
            ascii_record(&l, el, record).map_err(|m| LrfError::parse(file, *line_no, m))?;
        }
        f => binary_record(input, el, f == Format::BinBe, record).map_err(|m| match m {
            None => LrfError::parse(
                file,
                k + 1,
                format!(
                    "binary {} {} of {}: file ends early",
                    el.name,
                    k + 1,
                    el.count
                ),
            ),
            Some(m) => LrfError::parse(file, k + 1, format!("binary {} {}: {m}", el.name, k + 1)),
        })?,
    }
    Ok(())
}

/// Refuses a vertex with a coordinate beyond ±[`MAX_COORDINATE_MM`] or not finite; `at`
/// is its line (ascii) or record (binary).
fn check_position(p: &Vector3<f64>, file: &str, at: usize) -> Result<()> {
    if let Some(a) = (0..3).find(|&a| !(p[a].abs() <= MAX_COORDINATE_MM)) {
        let n = ["x", "y", "z"][a];
        return Err(LrfError::parse(
            file,
            at,
            if p[a].is_finite() {
                format!(
                    "{n}: {:e} mm is beyond ±{MAX_COORDINATE_MM:e} mm (10 km)",
                    p[a]
                )
            } else {
                format!("{n}: not a finite number within ±{MAX_COORDINATE_MM:e} mm")
            },
        ));
    }
    Ok(())
}

/// Refuses data after the `last` element: an ascii file may end in blank lines only, a
/// binary one not a byte more.
fn check_nothing_after<R: BufRead>(
    input: &mut R,
    format: Format,
    last: &Element,
    file: &str,
    line_no: &mut usize,
) -> Result<()> {
    if format == Format::Ascii {
        // Nothing but blank lines may follow the last element.
        let mut rest = String::new();
        loop {
            rest.clear();
            *line_no += 1;
            let n = input
                .read_line(&mut rest)
                .map_err(|e| LrfError::io(file, e))?;
            if n == 0 {
                break;
            }
            if !rest.trim().is_empty() {
                return Err(trailing(file, *line_no, last));
            }
        }
    } else {
        let mut one = [0u8; 1];
        if input.read(&mut one).map_err(|e| LrfError::io(file, e))? > 0 {
            return Err(trailing(file, last.count + 1, last));
        }
    }
    Ok(())
}

/// The next line of the header or an ascii body, trimmed (a byte-order mark before `ply`
/// skipped); an error at the end of the file.
fn next_line<R: BufRead>(input: &mut R, file: &str, line_no: &mut usize) -> Result<String> {
    let mut buf = Vec::new();
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
    if !buf.ends_with(b"\n") && !buf.iter().all(u8::is_ascii_whitespace) {
        return Err(LrfError::cut_short(file, *line_no));
    }
    let s = std::str::from_utf8(&buf).map_err(|_| LrfError::parse(file, *line_no, "not text"))?;
    Ok(LrfError::without_bom(*line_no, s).trim().to_string())
}

/// The header after `ply`: the format and the elements.
fn read_header<R: BufRead>(
    input: &mut R,
    file: &str,
    line_no: &mut usize,
) -> Result<(Format, Vec<Element>)> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let l = next_line(input, file, line_no)?;
        let line_no = *line_no;
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
                let ty = |i: usize| w.get(i).and_then(|t| Scalar::parse(t));
                let prop = if w.get(1) == Some(&"list") {
                    match (ty(2), ty(3), w.get(4), w.len()) {
                        (Some(c), Some(t), Some(name), 5) => (name.to_string(), Prop::List(c, t)),
                        _ => return Err(LrfError::parse(file, line_no, "expected `property list COUNT_TYPE ITEM_TYPE NAME`")),
                    }
                } else {
                    match (ty(1), w.get(2), w.len()) {
                        (Some(t), Some(name), 3) => (name.to_string(), Prop::Scalar(t)),
                        _ => return Err(LrfError::parse(file, line_no, "expected `property TYPE NAME`")),
                    }
                };
                el.props.push(prop);
            }
            Some("end_header") => break,
            Some(other) => return Err(LrfError::parse(file, line_no, format!("unknown header keyword {other:?}"))),
        }
    }
    let format =
        format.ok_or_else(|| LrfError::parse(file, *line_no, "header has no `format` line"))?;
    if let Some(e) = elements.iter().find(|e| e.props.is_empty() && e.count > 0) {
        return Err(LrfError::parse(
            file,
            *line_no,
            format!(
                "element {} declares {} records and no property",
                e.name, e.count
            ),
        ));
    }
    Ok((format, elements))
}

/// "file ends after k of N vertices" (or whatever the element holds).
fn ends_after(k: usize, el: &Element) -> String {
    let what = match el.name.as_str() {
        "vertex" => "vertices".to_string(),
        "face" => "faces".to_string(),
        n => format!("`{n}` elements"),
    };
    format!("file ends after {k} of {} {what}", el.count)
}

/// The longest list a PLY element may hold (a face of a million corners is none).
const MAX_LIST: f64 = 1e6;

/// The values of one ascii line of `el` into `out` (one per property, NaN for a list),
/// or what is wrong: a value missing or left over, a non-number, a list count that is not one.
fn ascii_record(line: &str, el: &Element, out: &mut Vec<f64>) -> std::result::Result<(), String> {
    out.clear();
    let mut w = line.split_whitespace();
    let mut number = |what: &str| -> std::result::Result<f64, String> {
        let t = w
            .next()
            .ok_or_else(|| format!("{} {what}: missing (the line ends early)", el.name))?;
        t.parse::<f64>()
            .map_err(|_| format!("{what}: expected a number, found {t:?}"))
    };
    for (name, p) in &el.props {
        match p {
            Prop::Scalar(_) => out.push(number(name)?),
            Prop::List(..) => {
                let n = number(name)?;
                if !((0.0..=MAX_LIST).contains(&n) && n.fract() == 0.0) {
                    return Err(format!("{name}: list length {n} is not a count"));
                }
                for _ in 0..n as usize {
                    number(name)?;
                }
                out.push(f64::NAN);
            }
        }
    }
    if let Some(t) = w.next() {
        return Err(format!(
            "{} has {} properties, the line has more values ({t:?}): a header that disagrees with its data?",
            el.name,
            el.props.len()
        ));
    }
    Ok(())
}

/// The values of one binary record of `el` into `out` (as [`ascii_record`]); `Err(None)`
/// when the file ends inside it.
fn binary_record<R: Read>(
    input: &mut R,
    el: &Element,
    be: bool,
    out: &mut Vec<f64>,
) -> std::result::Result<(), Option<String>> {
    out.clear();
    let mut b = [0u8; 8];
    let mut read = |s: Scalar, input: &mut R| -> std::result::Result<f64, Option<String>> {
        input.read_exact(&mut b[..s.size()]).map_err(|_| None)?;
        Ok(s.decode(&b, be))
    };
    for (name, p) in &el.props {
        match *p {
            Prop::Scalar(s) => out.push(read(s, input)?),
            Prop::List(c, t) => {
                let n = read(c, input)?;
                if !(0.0..=MAX_LIST).contains(&n) {
                    return Err(Some(format!("{name}: list length {n} is not a count")));
                }
                let bytes = n as u64 * t.size() as u64;
                let skipped = std::io::copy(&mut input.take(bytes), &mut std::io::sink())
                    .map_err(|_| None)?;
                if skipped != bytes {
                    return Err(None);
                }
                out.push(f64::NAN);
            }
        }
    }
    Ok(())
}

/// The error for data after the last element the header declares (a duplicated or extra
/// line shifts the vertices, so the cloud read would be wrong).
fn trailing(file: &str, line: usize, last: &Element) -> LrfError {
    let what = match last.name.as_str() {
        "vertex" => "vertices".to_string(),
        "face" => "faces".to_string(),
        n => format!("`{n}` elements"),
    };
    LrfError::parse(
        file,
        line,
        format!(
            "trailing data after the {} {what} the header declares: a duplicated or extra line?",
            last.count
        ),
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

    /// Issue 39: a header that disagrees with its data is refused, whatever element it
    /// concerns.
    #[test]
    fn a_header_that_disagrees_with_its_data_is_refused() {
        let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n";
        let faces =
            "element face 100\nproperty list uchar int vertex_indices\nend_header\n1 2 3\n4 5 6\n";
        let e = read_ply(format!("{head}{faces}").as_bytes(), "f.ply")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "f.ply:12: file ends after 0 of 100 faces");
        let one = format!("{head}{}3 0 1 1\n", faces.replace("face 100", "face 1"));
        assert_eq!(read_ply(one.as_bytes(), "f.ply").unwrap().len(), 2);
        let e = read_ply(format!("{one}3 0 1 1\n").as_bytes(), "f.ply")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("f.ply:13: trailing data after the 1 faces"),
            "{e}"
        );
        let e = read_ply(one.replace("3 0 1 1", "3 0 1").as_bytes(), "f.ply")
            .unwrap_err()
            .to_string();
        assert!(e.contains("face vertex_indices: missing"), "{e}");
        let z_list = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty list uchar float z\nend_header\n1 2 1 3\n";
        let e = read_ply(z_list.as_bytes(), "z.ply")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "z.ply:7: vertex property z is a list: expected one number per vertex"
        );
        let extra = format!("{head}end_header\n1 2 3 4\n5 6 7\n");
        let e = read_ply(extra.as_bytes(), "x.ply").unwrap_err().to_string();
        assert!(
            e.starts_with("x.ply:8: vertex has 3 properties, the line has more values"),
            "{e}"
        );
        let empty = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement nothing 1000000000000000000\nend_header\n";
        let e = read_ply(empty.as_bytes(), "n.ply").unwrap_err().to_string();
        assert!(
            e.contains("element nothing declares 1000000000000000000 records and no property"),
            "{e}"
        );
        // binary faces declared and absent
        let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 100\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
        for v in [1.0f32, 2.0, 3.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let e = read_ply(&b[..], "b.ply").unwrap_err().to_string();
        assert!(e.contains("binary face 1 of 100: file ends early"), "{e}");
        b.push(3);
        for i in [0i32, 0, 0] {
            b.extend_from_slice(&i.to_le_bytes());
        }
        let e = read_ply(&b[..], "b.ply").unwrap_err().to_string();
        assert!(e.contains("binary face 2 of 100: file ends early"), "{e}");
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
