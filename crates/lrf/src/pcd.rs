//! PCD clouds (the Point Cloud Library's format, v0.7; v0.5/v0.6 headers too): `DATA ascii`,
//! `binary` and `binary_compressed` (LZF, [`crate::lzf`]).
//!
//! The header is a list of `KEY values` lines (`#` starts a comment): `VERSION`, `FIELDS`
//! (`COLUMNS` in v0.5), `SIZE`, `TYPE`, `COUNT` (default 1 each), `WIDTH`, `HEIGHT`
//! (default 1), `VIEWPOINT`, `POINTS` (default `WIDTH × HEIGHT`), and last `DATA`. The
//! fields `x`, `y`, `z` are found by name and must be `F` of size 4 or 8; any other field,
//! of any type and `COUNT`, is skipped. Binary data is little-endian, one record after the
//! other; `binary_compressed` data is `u32` compressed size, `u32` uncompressed size, then
//! the LZF stream, which decompresses to the fields one after the other (all points' first
//! field, then all points' second field, …), as PCL writes it.
//!
//! A point with a NaN coordinate is dropped: organized clouds (`HEIGHT > 1`) hold NaN where
//! the sensor had no return. An infinite coordinate, or one beyond ±1e7 in the file's unit,
//! is refused naming the record. A `VIEWPOINT` other than the identity
//! (`0 0 0 1 0 0 0`) is refused: PCL does not apply it to the points either, and the
//! along-ray sphere fit would need it as the rays' origin, so rather than guess, the file
//! must hold the points in the sensor's frame.
//!
//! Every count of the header is checked against the file's size before anything is
//! allocated; the values are returned in the file's unit (PCD files are usually metres:
//! [`crate::cloud_file`] converts).

use crate::cloud::Cloud;
use crate::error::{LrfError, Result};
use nalgebra::Vector3;

/// Largest absolute coordinate accepted, in the file's unit.
pub const MAX_COORDINATE: f64 = 1e7;

#[derive(Clone, Copy, PartialEq, Debug)]
enum Data {
    Ascii,
    Binary,
    Compressed,
}

#[derive(Debug)]
struct Field {
    name: String,
    size: usize,
    kind: char,
    count: usize,
}

/// What the header's lines said, before they are checked against each other; SIZE, TYPE
/// and COUNT keep their line number for the messages.
#[derive(Default)]
struct HeaderLines {
    names: Option<Vec<String>>,
    sizes: Option<(usize, Vec<usize>)>,
    types: Option<(usize, Vec<char>)>,
    counts: Option<(usize, Vec<usize>)>,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
}

/// The checked header: the fields, where `x`, `y`, `z` are, the record's layout, the number
/// of points, the encoding and where its data start.
struct Header {
    fields: Vec<Field>,
    xyz: [usize; 3],
    /// Byte offset of each field in a record.
    offsets: Vec<usize>,
    /// Bytes per record.
    stride: usize,
    /// Numbers per record (an ASCII line's length).
    tokens: usize,
    n: usize,
    data: Data,
    data_line: usize,
    /// Byte offset of the data, after the `DATA` line.
    body_start: usize,
}

/// Reads a PCD cloud held in memory; values are in the file's unit.
pub fn read_pcd(bytes: &[u8], file: &str) -> Result<Cloud> {
    if bytes.is_empty() {
        return Err(LrfError::Empty {
            file: file.into(),
            msg: "empty file (expected a PCD header)".into(),
        });
    }
    let h = parse_header(bytes, file)?;
    let body = &bytes[h.body_start..];
    let mut out = Points {
        file,
        pts: Vec::new(),
    };
    match h.data {
        Data::Ascii => decode_ascii(body, &h, file, &mut out)?,
        Data::Binary => decode_binary(body, &h, file, &mut out)?,
        Data::Compressed => decode_compressed(body, &h, file, &mut out)?,
    }
    Ok(Cloud::from_points(out.pts))
}

/// Reads the header up to its `DATA` line and checks it: fields, coordinates, record
/// layout, point count.
fn parse_header(bytes: &[u8], file: &str) -> Result<Header> {
    let (lines, data, data_line, body_start) = read_header_lines(bytes, file)?;
    let (fields, tl, cl) = lines.fields(data_line, file)?;
    let xyz = [
        coordinate(&fields, "x", data_line, tl, cl, file)?,
        coordinate(&fields, "y", data_line, tl, cl, file)?,
        coordinate(&fields, "z", data_line, tl, cl, file)?,
    ];
    let (offsets, stride, tokens) = record_layout(&fields, cl, file)?;
    let n = lines.point_count(data_line, file)?;
    Ok(Header {
        fields,
        xyz,
        offsets,
        stride,
        tokens,
        n,
        data,
        data_line,
        body_start,
    })
}

/// The header's lines up to `DATA`: what they said, the encoding, the `DATA` line's number
/// and the byte offset after it.
fn read_header_lines(bytes: &[u8], file: &str) -> Result<(HeaderLines, Data, usize, usize)> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut lines = HeaderLines::default();
    loop {
        if pos >= bytes.len() {
            return Err(LrfError::parse(
                file,
                line_no.max(1),
                "end of file inside the PCD header (expected a `DATA ascii|binary|binary_compressed` line)",
            ));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |k| pos + k);
        line_no += 1;
        let raw = &bytes[pos..end];
        pos = (end + 1).min(bytes.len());
        let s = std::str::from_utf8(raw)
            .map_err(|_| LrfError::parse(file, line_no, "header line is not text"))?;
        let s = LrfError::without_bom(line_no, s);
        let s = s.split('#').next().unwrap_or("").trim();
        let w: Vec<&str> = s.split_whitespace().collect();
        let Some(&key) = w.first() else { continue };
        if let Some(data) = lines.keyword(key, &w[1..], line_no, file)? {
            return Ok((lines, data, line_no, pos));
        }
    }
}

impl HeaderLines {
    /// Records one `KEY values` line; the encoding when it is the closing `DATA` line.
    fn keyword(
        &mut self,
        key: &str,
        args: &[&str],
        line_no: usize,
        file: &str,
    ) -> Result<Option<Data>> {
        let bad = |what: &str| LrfError::parse(file, line_no, format!("{key}: expected {what}"));
        let uints = |what: &str| -> Result<Vec<usize>> {
            let v: Option<Vec<usize>> = args.iter().map(|a| a.parse().ok()).collect();
            match v {
                Some(v) if !v.is_empty() => Ok(v),
                _ => Err(bad(what)),
            }
        };
        let one = |what: &str| -> Result<usize> {
            match uints(what)?.as_slice() {
                [n] => Ok(*n),
                _ => Err(bad(what)),
            }
        };
        match key.to_ascii_uppercase().as_str() {
            "VERSION" => {
                let v = args.first().map(|v| v.trim_start_matches('.'));
                if !matches!(v, Some("0.5" | "5" | "0.6" | "6" | "0.7" | "7")) {
                    return Err(bad("0.5, 0.6 or 0.7"));
                }
            }
            "FIELDS" | "COLUMNS" => {
                if args.is_empty() {
                    return Err(bad("field names"));
                }
                self.names = Some(args.iter().map(|a| a.to_string()).collect());
            }
            "SIZE" => self.sizes = Some((line_no, uints("sizes in bytes (1, 2, 4 or 8)")?)),
            "TYPE" => {
                let v: Option<Vec<char>> = args
                    .iter()
                    .map(|a| match *a {
                        "F" | "f" => Some('F'),
                        "I" | "i" => Some('I'),
                        "U" | "u" => Some('U'),
                        _ => None,
                    })
                    .collect();
                match v {
                    Some(v) if !v.is_empty() => self.types = Some((line_no, v)),
                    _ => return Err(bad("types F, I or U")),
                }
            }
            "COUNT" => self.counts = Some((line_no, uints("counts (positive integers)")?)),
            "WIDTH" => self.width = Some(one("one integer")?),
            "HEIGHT" => self.height = Some(one("one integer")?),
            "POINTS" => self.points = Some(one("one integer")?),
            "VIEWPOINT" => check_viewpoint(args, line_no, file, bad)?,
            "DATA" => {
                return match args.first().map(|a| a.to_ascii_lowercase()).as_deref() {
                    Some("ascii") => Ok(Some(Data::Ascii)),
                    Some("binary") => Ok(Some(Data::Binary)),
                    Some("binary_compressed") => Ok(Some(Data::Compressed)),
                    _ => Err(bad("ascii, binary or binary_compressed")),
                };
            }
            _ => {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!("unknown header keyword {key:?} (expected VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS or DATA)"),
                ))
            }
        }
        Ok(None)
    }

    /// The fields of FIELDS, SIZE, TYPE and COUNT (default 1 each), checked against each
    /// other; with the line numbers of TYPE and COUNT for later messages.
    fn fields(&self, data_line: usize, file: &str) -> Result<(Vec<Field>, usize, usize)> {
        let hdr = |line: usize, msg: String| LrfError::parse(file, line, msg);
        let names = self
            .names
            .clone()
            .ok_or_else(|| hdr(data_line, "header has no FIELDS line".into()))?;
        let nf = names.len();
        let (sl, sizes) = self
            .sizes
            .clone()
            .ok_or_else(|| hdr(data_line, "header has no SIZE line".into()))?;
        let (tl, types) = self
            .types
            .clone()
            .ok_or_else(|| hdr(data_line, "header has no TYPE line".into()))?;
        let (cl, counts) = self.counts.clone().unwrap_or((data_line, vec![1; nf]));
        for (line, what, n) in [
            (sl, "SIZE", sizes.len()),
            (tl, "TYPE", types.len()),
            (cl, "COUNT", counts.len()),
        ] {
            if n != nf {
                return Err(hdr(
                    line,
                    format!("{what}: expected {nf} values (one per field), found {n}"),
                ));
            }
        }
        let mut fields = Vec::with_capacity(nf);
        for k in 0..nf {
            let (size, kind, count) = (sizes[k], types[k], counts[k]);
            let ok = match kind {
                'F' => matches!(size, 4 | 8),
                _ => matches!(size, 1 | 2 | 4 | 8),
            };
            if !ok {
                return Err(hdr(
                    sl,
                    format!(
                        "SIZE: field {:?} of TYPE {kind} has size {size} (expected 1, 2, 4 or 8; 4 or 8 for F)",
                        names[k]
                    ),
                ));
            }
            if count == 0 {
                return Err(hdr(cl, format!("COUNT: field {:?} has count 0", names[k])));
            }
            fields.push(Field {
                name: names[k].clone(),
                size,
                kind,
                count,
            });
        }
        Ok((fields, tl, cl))
    }

    /// POINTS, or WIDTH × HEIGHT (HEIGHT default 1), checked against each other.
    fn point_count(&self, data_line: usize, file: &str) -> Result<usize> {
        let hdr = |msg: String| LrfError::parse(file, data_line, msg);
        Ok(match (self.points, self.width, self.height) {
            (Some(p), w, h) => {
                let w = w.unwrap_or(p);
                let h = h.unwrap_or(1);
                if w.checked_mul(h) != Some(p) {
                    return Err(hdr(format!("POINTS {p} is not WIDTH × HEIGHT = {w} × {h}")));
                }
                p
            }
            (None, Some(w), h) => w
                .checked_mul(h.unwrap_or(1))
                .ok_or_else(|| hdr("WIDTH × HEIGHT overflows".into()))?,
            (None, None, _) => return Err(hdr("header has no POINTS nor WIDTH line".into())),
        })
    }
}

/// Refuses a `VIEWPOINT` other than the identity (see the module's doc).
fn check_viewpoint(
    args: &[&str],
    line_no: usize,
    file: &str,
    bad: impl Fn(&str) -> LrfError,
) -> Result<()> {
    let v: Option<Vec<f64>> = args.iter().map(|a| a.parse().ok()).collect();
    let Some(v) = v.filter(|v| v.len() == 7) else {
        return Err(bad("seven numbers tx ty tz qw qx qy qz"));
    };
    let identity = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    if v.iter().zip(identity).any(|(a, b)| (a - b).abs() > 1e-12) {
        return Err(LrfError::parse(
            file,
            line_no,
            format!(
                "VIEWPOINT {}: only the identity `0 0 0 1 0 0 0` is supported (pingcal does not move the points; write them in the sensor's frame)",
                args.join(" ")
            ),
        ));
    }
    Ok(())
}

/// The index of coordinate field `name`: present, one number per point, a float.
fn coordinate(
    fields: &[Field],
    name: &str,
    data_line: usize,
    tl: usize,
    cl: usize,
    file: &str,
) -> Result<usize> {
    let hdr = |line: usize, msg: String| LrfError::parse(file, line, msg);
    let i = fields.iter().position(|f| f.name == name).ok_or_else(|| {
        let names: Vec<&str> = fields.iter().map(|f| f.name.as_str()).collect();
        hdr(
            data_line,
            format!("no field {name:?} among FIELDS {}", names.join(" ")),
        )
    })?;
    if fields[i].count != 1 {
        return Err(hdr(
            cl,
            format!(
                "COUNT: field {name:?} has count {}: a coordinate is one number per point",
                fields[i].count
            ),
        ));
    }
    if fields[i].kind != 'F' {
        return Err(hdr(
            tl,
            format!(
                "TYPE: field {name:?} must be F (4 or 8 bytes), found {}",
                fields[i].kind
            ),
        ));
    }
    Ok(i)
}

/// The byte offset of each field in a record, the record size and the numbers per record,
/// checked for overflow.
fn record_layout(fields: &[Field], cl: usize, file: &str) -> Result<(Vec<usize>, usize, usize)> {
    let hdr = |msg: &str| LrfError::parse(file, cl, msg);
    let mut offsets = Vec::with_capacity(fields.len());
    let mut stride: usize = 0;
    let mut tokens: usize = 0;
    for f in fields {
        offsets.push(stride);
        stride = f
            .size
            .checked_mul(f.count)
            .and_then(|b| stride.checked_add(b))
            .ok_or_else(|| hdr("COUNT: the record size overflows"))?;
        tokens = tokens
            .checked_add(f.count)
            .ok_or_else(|| hdr("COUNT: too many values per point"))?;
    }
    Ok((offsets, stride, tokens))
}

impl Header {
    /// The error for data shorter than the header's `n` points of `stride` bytes (`need`).
    fn too_short(&self, body: &[u8], need: &str, file: &str) -> LrfError {
        LrfError::parse(
            file,
            self.data_line,
            format!(
                "the header says {} points of {} bytes ({need}), the file holds {} bytes after the header",
                self.n,
                self.stride,
                body.len()
            ),
        )
    }
}

/// The points read so far.
struct Points<'a> {
    file: &'a str,
    pts: Vec<Vector3<f64>>,
}

impl Points<'_> {
    /// Keeps point `p` of record (or line) `rec`: dropped when a coordinate is NaN, refused
    /// beyond [`MAX_COORDINATE`].
    fn push(&mut self, rec: usize, p: [f64; 3]) -> Result<()> {
        if p.iter().any(|v| v.is_nan()) {
            return Ok(());
        }
        if let Some(v) = p.iter().find(|v| v.abs() > MAX_COORDINATE) {
            return Err(LrfError::parse(
                self.file,
                rec,
                format!("coordinate {v:e} is beyond ±{MAX_COORDINATE:e} (or not finite)"),
            ));
        }
        self.pts.push(Vector3::new(p[0], p[1], p[2]));
        Ok(())
    }
}

/// `DATA ascii`: one line of `tokens` numbers per point; blank lines and comments skipped.
fn decode_ascii(body: &[u8], h: &Header, file: &str, out: &mut Points) -> Result<()> {
    let (n, tokens, data_line) = (h.n, h.tokens, h.data_line);
    // Each point takes at least one line of `tokens` numbers: 2·tokens bytes.
    if n > 0 && n > body.len() / tokens.max(1) / 2 + 1 {
        return Err(LrfError::parse(
            file,
            data_line,
            format!(
                "the header says {n} points, the file holds only {} bytes after the header",
                body.len()
            ),
        ));
    }
    let mut rec = 0;
    let mut l = data_line;
    // a last line without a line break was cut short (in the middle of a number?)
    if let Some(tail) = body.rsplit(|&b| b == b'\n').next() {
        if !tail.iter().all(u8::is_ascii_whitespace) {
            let lines = body.iter().filter(|&&b| b == b'\n').count();
            return Err(LrfError::cut_short(file, data_line + lines + 1));
        }
    }
    for line in body.split(|&b| b == b'\n') {
        l += 1;
        let s =
            std::str::from_utf8(line).map_err(|_| LrfError::parse(file, l, "not UTF-8 text"))?;
        let s = s.split('#').next().unwrap_or("").trim();
        if s.is_empty() {
            continue;
        }
        if rec == n {
            return Err(LrfError::parse(
                file,
                l,
                format!("more data lines than the header's {n} points"),
            ));
        }
        let w: Vec<&str> = s.split_whitespace().collect();
        if w.len() != tokens {
            return Err(LrfError::parse(
                file,
                l,
                format!("expected {tokens} values, found {}", w.len()),
            ));
        }
        let mut p = [0.0; 3];
        for (j, &fi) in h.xyz.iter().enumerate() {
            let t: usize = h.fields[..fi].iter().map(|f| f.count).sum();
            p[j] = w[t].parse::<f64>().map_err(|_| {
                LrfError::parse(
                    file,
                    l,
                    format!("{}: expected a number, found {:?}", h.fields[fi].name, w[t]),
                )
            })?;
        }
        out.push(l, p)?;
        rec += 1;
    }
    if rec != n {
        return Err(LrfError::parse(
            file,
            l,
            format!("file ends after {rec} of {n} points"),
        ));
    }
    Ok(())
}

/// `DATA binary`: `n` little-endian records of `stride` bytes, nothing after.
fn decode_binary(body: &[u8], h: &Header, file: &str, out: &mut Points) -> Result<()> {
    let (n, stride) = (h.n, h.stride);
    let total = n
        .checked_mul(stride)
        .ok_or_else(|| h.too_short(body, "more than memory can hold", file))?;
    if body.len() < total {
        return Err(h.too_short(body, &format!("{total} bytes"), file));
    }
    if body.len() > total {
        return Err(LrfError::parse(
            file,
            h.data_line,
            format!(
                "{} bytes after the {n} points of the header",
                body.len() - total
            ),
        ));
    }
    for rec in 0..n {
        let r = &body[rec * stride..(rec + 1) * stride];
        let mut p = [0.0; 3];
        for (j, &fi) in h.xyz.iter().enumerate() {
            p[j] = float(&r[h.offsets[fi]..], h.fields[fi].size);
        }
        out.push(rec + 1, p)?;
    }
    Ok(())
}

/// `DATA binary_compressed`: the two sizes, then LZF data that decompress to the fields one
/// after the other.
fn decode_compressed(body: &[u8], h: &Header, file: &str, out: &mut Points) -> Result<()> {
    let (n, stride, data_line) = (h.n, h.stride, h.data_line);
    let total = n
        .checked_mul(stride)
        .ok_or_else(|| h.too_short(body, "more than memory can hold", file))?;
    let (Some(cs), Some(us)) = (u32_at(body, 0), u32_at(body, 4)) else {
        return Err(LrfError::parse(
            file,
            data_line,
            "binary_compressed data lacks its two sizes",
        ));
    };
    let (cs, us) = (cs as usize, us as usize);
    if us != total {
        return Err(LrfError::parse(
            file,
            data_line,
            format!("uncompressed size {us} bytes, the header's {n} points of {stride} bytes make {total}"),
        ));
    }
    if cs != body.len() - 8 {
        return Err(LrfError::parse(
            file,
            data_line,
            format!(
                "compressed size {cs} bytes, the file holds {} after the header",
                body.len() - 8
            ),
        ));
    }
    if total > cs.saturating_mul(crate::lzf::MAX_RATIO) {
        return Err(h.too_short(
            body,
            &format!("{total} bytes, more than {cs} compressed bytes can hold"),
            file,
        ));
    }
    let raw = crate::lzf::decompress(&body[8..], total)
        .map_err(|e| LrfError::parse(file, data_line, e))?;
    for rec in 0..n {
        let mut p = [0.0; 3];
        for (j, &fi) in h.xyz.iter().enumerate() {
            let f = &h.fields[fi];
            let at = h.offsets[fi] * n + rec * f.size * f.count;
            p[j] = float(&raw[at..], f.size);
        }
        out.push(rec + 1, p)?;
    }
    Ok(())
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at + 4)?;
    Some(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// A little-endian float of `size` 4 or 8 at the start of `b` (the caller checked the length).
fn float(b: &[u8], size: usize) -> f64 {
    if size == 4 {
        f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64
    } else {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[..8]);
        f64::from_le_bytes(a)
    }
}

/// Reads a PCD file from disk; values are in the file's unit.
pub fn read_pcd_file(path: &std::path::Path) -> Result<Cloud> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| LrfError::io(&name, e))?;
    let c = read_pcd(&bytes, &name)?;
    if c.is_empty() {
        return Err(LrfError::Empty {
            file: name,
            msg: "no points (every point NaN, or none)".into(),
        });
    }
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";

    #[test]
    fn ascii_with_count_and_nan() {
        let t = "# c\nVERSION .7\nFIELDS x y z n\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 3\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3 0 0 0\nnan nan nan 1 1 1\n";
        let c = read_pcd(t.as_bytes(), "a.pcd").unwrap();
        assert_eq!(c.points, vec![Vector3::new(1.0, 2.0, 3.0)]);
    }

    #[test]
    fn a_coordinate_with_a_count_is_refused() {
        let t = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 2\nWIDTH 1\nDATA ascii\n1 2 3 4\n";
        let e = read_pcd(t.as_bytes(), "z.pcd").unwrap_err().to_string();
        assert_eq!(
            e,
            "z.pcd:5: COUNT: field \"z\" has count 2: a coordinate is one number per point"
        );
    }

    #[test]
    fn header_errors_name_the_line() {
        let e = read_pcd(
            format!("{HEAD}WIDTH 1000000000000\nDATA binary\n").as_bytes(),
            "a.pcd",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("a.pcd:7: the header says 1000000000000 points"),
            "{e}"
        );
        let e = read_pcd(
            format!("{HEAD}WIDTH 1\nVIEWPOINT 1 0 0 1 0 0 0\nDATA ascii\n1 2 3\n").as_bytes(),
            "a.pcd",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("a.pcd:7: VIEWPOINT 1 0 0 1 0 0 0: only the identity"),
            "{e}"
        );
        let e = read_pcd("VERSION 0.7\nFIELDS x y z\nSIZE 4 4\n".as_bytes(), "a.pcd")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("a.pcd:3: end of file inside the PCD header"),
            "{e}"
        );
        let e = read_pcd(
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n".as_bytes(),
            "a.pcd",
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "a.pcd:3: SIZE: expected 3 values (one per field), found 2"
        );
        let e = read_pcd(
            format!("{HEAD}WIDTH 2\nDATA ascii\n1 2 3\n").as_bytes(),
            "a.pcd",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("file ends after 1 of 2 points"), "{e}");
    }
}
