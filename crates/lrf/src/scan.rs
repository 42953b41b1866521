//! The `pingcal-scan` CSV format (docs/lrf.md): one 2D scan per line, with the servo angle.
//!
//! ```text
//! # pingcal-scan v1
//! # angle_min_deg=-119.53125
//! # angle_increment_deg=0.3515625
//! # range_unit=mm
//! stamp_s,servo_deg,r0,r1,r2,...
//! 0.000,-45.056,1532,1530,0,...
//! ```
//!
//! [`ScanReader`] streams the file line by line through a [`BufRead`], so a log of
//! millions of beams never has to fit in memory as one string. Ranges under 20 mm (the URG
//! error codes, and 0) mean "no return" and are stored as `0.0`.
//!
//! A range above [`MAX_RANGE_MM`] (1 km; the URG-04LX reaches 5.6 m, long-range 2D
//! scanners some 100 m) is beyond any range finder: it is masked as no return and counted
//! ([`ScanReader::masked`]), and the caller warns with the count and the first line. One
//! such glitch in a long log leaves the other ranges of the sweep usable; masking it keeps
//! it out of the cloud (an infinite PLY vertex) and out of the plane and ball search, and
//! the warning keeps it from passing unseen. Ranges beyond the sensor's own maximum (a
//! project's `[lrf] max_range_mm`) are masked likewise by the caller
//! ([`ScanLine::mask_beyond`]). A non-number, an infinite or a negative range is refused,
//! naming the file and line, as is a time stamp beyond ±1e12 s or a servo angle beyond
//! ±1e6°. A UTF-8 byte-order mark at the start is skipped.
//!
//! **Beam geometry.** `angle_min_deg` must lie within ±360° and the beams must span at
//! most one turn (`|angle_increment_deg| · (beams − 1) ≤ 360°`): a header beyond that (an
//! increment of 1e308, or of 360° per beam) describes no scanner, and the file is refused
//! naming the header line, before any point is made.
//!
//! **Time stamps.** Scans must come in time order: a `stamp_s` earlier than the previous
//! scan's is refused, naming both lines (the file was concatenated or sorted by something
//! else). Equal stamps are legal (a logger without a clock may write 0 throughout), but a
//! line that repeats the previous one exactly — stamp, servo angle and every range — is
//! refused as a duplicated record: a range finder's noise never gives the same hundreds of
//! ranges twice. Beyond this order the stamps are not used: a stop-and-go sweep gives
//! each line its servo angle.
//!
//! [`ScanWriter`] is the one writer of the format (the simulator writes through it too):
//! time stamps with 3 decimals, servo angles with 6, ranges in whole mm.
//!
//! **Version 2: continuous sweeps.** A servo that turns while the LRF scans gives each
//! beam its own servo angle. `# pingcal-scan v2` files have a third column,
//! `servo_end_deg`: the servo angle at the scan's last beam, `servo_deg` being the one at
//! its first beam, and beam i of n at β = servo_deg + (servo_end_deg − servo_deg) · i/(n−1)
//! ([`ScanLine::servo_deg_at`]). Everything else is as in v1, which is read unchanged (one
//! servo angle for the whole scan: stop-and-go). A file naming another version is refused.
//!
//! ```text
//! # pingcal-scan v2
//! # angle_min_deg=-119.53125
//! # angle_increment_deg=0.3515625
//! # range_unit=mm
//! stamp_s,servo_deg,servo_end_deg,r0,r1,r2,...
//! 0.000,-45.056,-44.956,1532,1530,0,...
//! ```
//!
//! **Version 3: intensities.** A scanner that reports an intensity per beam (most ROS
//! drivers fill `LaserScan.intensities`) keeps it: `# pingcal-scan v3` is v2 with, after
//! the n ranges, n intensity columns `i0,...,i(n-1)` in the scanner's own unit (the shortest
//! decimal of its `float32`). The version changes so that an older pingcal refuses the file
//! instead of reading the intensities as ranges. A v3 file without intensity columns is
//! read as v2. v1 and v2 files are read unchanged.
//!
//! **Beam timing.** The optional header key `# time_increment_s=` (written from a bag's
//! `LaserScan.time_increment`, and by the simulator for a continuous sweep) gives the time
//! between two beams of a scan: beam i was measured at `stamp_s + i · time_increment_s`.
//! Earlier readers ignore the key. (In v4 it may be negative: the beams were measured
//! from the last to the first, as some drivers publish them.)
//!
//! **Version 4: one file for a recording whose beam geometry changes.** Some drivers
//! (RPLIDAR, YDLIDAR) publish a different beam count, first angle or step from scan to
//! scan. `# pingcal-scan v4` is v3 (a `servo_end_deg` column; intensities optional) in
//! which a line `# geometry angle_min_deg=A angle_increment_deg=D beams=N` (and optionally
//! `time_increment_s=T`) may stand before any scan: the scans after it, until the next such
//! line, have that geometry and N ranges each, optionally followed by N intensities. The
//! first geometry is the header's, as in v3. v1, v2 and v3 files are read unchanged (in
//! them a `# geometry` line is a comment, as before); an older pingcal refuses a v4 file
//! instead of reading its scans with the wrong angles. Each scan read from a later
//! geometry carries it ([`ScanLine::geometry`]).
//!
//! ```text
//! # pingcal-scan v4
//! # angle_min_deg=-180
//! # angle_increment_deg=1
//! # range_unit=mm
//! stamp_s,servo_deg,servo_end_deg,r0,r1,...,r359
//! 0.000,-18.000000,-17.900000,1532,1530,...
//! # geometry angle_min_deg=-179.5 angle_increment_deg=0.99 beams=362
//! 0.100,-17.900000,-17.800000,1533,1529,...
//! ```
//!
//! **Units the data contradict.** A reader that read every scan can tell
//! ([`ScanReader::unit_slip`]) a servo column in radians (every angle within ±2π and a
//! sweep of more than π: a sweep of a few degrees calibrates nothing) and ranges in metres
//! in a file that says millimetres (every range under 20 mm, none a return): the callers
//! refuse the file naming the likely unit.
//!
//! **A file cut short.** A file whose last line has no line break was cut (a copy or a
//! recording stopped mid-way, possibly in the middle of a number): it is refused, naming
//! the file and the line, not read as far as it goes.
//! ```text
//! # pingcal-scan v3
//! # angle_min_deg=-119.53125
//! # angle_increment_deg=0.3515625
//! # range_unit=mm
//! # time_increment_s=0.00009765625
//! stamp_s,servo_deg,servo_end_deg,r0,r1,r2,...,i0,i1,i2,...
//! 0.000,-45.056,-44.956,1532,1530,0,...,812,790,0,...
//! ```

use crate::error::{LrfError, Result};
use std::io::{BufRead, Write};

/// Ranges under this many millimetres are URG error codes: no return.
pub const MIN_VALID_RANGE_MM: f64 = 20.0;

/// Ranges above this many millimetres (1 km) are beyond any 2D range finder: masked as no
/// return and counted ([`ScanReader::masked`]).
pub const MAX_RANGE_MM: f64 = 1e6;

/// The beams of a scan span at most this many degrees (one turn).
pub const MAX_SPAN_DEG: f64 = 360.0;

/// A servo angle beyond ± this many degrees is refused (a corrupt line).
pub const MAX_SERVO_DEG: f64 = 1e6;

/// A time stamp beyond ± this many seconds is refused (a corrupt line).
pub const MAX_STAMP_S: f64 = 1e12;

/// Whether `n_beams` beams `increment_deg` apart from `angle_min_deg` are a scan a
/// `pingcal-scan` file can hold: the first within ±[`MAX_SPAN_DEG`], all within one turn
/// (what the readers check, for the writers that check before writing).
pub fn geometry_ok(angle_min_deg: f64, increment_deg: f64, n_beams: usize) -> bool {
    angle_min_deg.abs() <= MAX_SPAN_DEG
        && increment_deg != 0.0
        && increment_deg.abs() * n_beams.saturating_sub(1) as f64 <= MAX_SPAN_DEG
}

/// The header of a scan file: the beam geometry shared by all lines.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScanHeader {
    /// Angle α of beam 0, degrees.
    pub angle_min_deg: f64,
    /// Angle step between beams, degrees.
    pub angle_increment_deg: f64,
    /// Millimetres per range unit of the file (1 for `mm`, 10 for `cm`, 1000 for `m`).
    pub mm_per_unit: f64,
    /// Time between two beams of a scan, seconds (`# time_increment_s=`), when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_increment_s: Option<f64>,
}

impl ScanHeader {
    /// The Hokuyo URG-04LX geometry: 682 beams from −119.53125° in 0.3515625° steps, mm.
    pub const URG_04LX: ScanHeader = ScanHeader {
        angle_min_deg: -119.53125,
        angle_increment_deg: 0.3515625,
        mm_per_unit: 1.0,
        time_increment_s: None,
    };

    /// Beam angle α of beam `i`, in degrees.
    pub fn beam_angle_deg(&self, i: usize) -> f64 {
        self.angle_min_deg + i as f64 * self.angle_increment_deg
    }
}

/// One 2D scan: the servo angle and one range per beam.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanLine {
    /// 1-based line number in the file (0 when not read from a file).
    pub line: usize,
    /// Time stamp, seconds.
    pub stamp_s: f64,
    /// Servo angle β, degrees (at the first beam when `servo_end_deg` is given).
    pub servo_deg: f64,
    /// Servo angle at the last beam, degrees, for a scan taken while the servo turned
    /// (`pingcal-scan` v2); `None`: the servo stood at `servo_deg` for the whole scan.
    pub servo_end_deg: Option<f64>,
    /// Ranges in mm; `0.0` where the beam had no return.
    pub ranges_mm: Vec<f64>,
    /// One intensity per beam in the scanner's unit (`pingcal-scan` v3), or empty when the
    /// scanner gave none.
    pub intensities: Vec<f32>,
    /// The scan's own beam geometry when it is not the file's (`pingcal-scan` v4, a
    /// `# geometry` line); `None`: the file's header.
    pub geometry: Option<ScanHeader>,
}

impl ScanLine {
    /// The beam geometry of this scan: its own ([`ScanLine::geometry`]) or the file's.
    pub fn geometry_or(&self, file: &ScanHeader) -> ScanHeader {
        self.geometry.unwrap_or(*file)
    }

    /// The servo angle of beam `i`, degrees: linear in the beam index from `servo_deg` at
    /// the first beam to `servo_end_deg` at the last.
    pub fn servo_deg_at(&self, i: usize) -> f64 {
        match self.servo_end_deg {
            Some(end) if self.ranges_mm.len() > 1 && end != self.servo_deg => {
                let f = i as f64 / (self.ranges_mm.len() - 1) as f64;
                self.servo_deg + f * (end - self.servo_deg)
            }
            _ => self.servo_deg,
        }
    }

    /// True when the servo turned during the scan.
    pub fn is_sweep(&self) -> bool {
        self.servo_end_deg.is_some_and(|e| e != self.servo_deg)
    }

    /// Masks (sets to no return) every range beyond `max_range_mm`, the sensor's maximum;
    /// how many were masked.
    pub fn mask_beyond(&mut self, max_range_mm: f64) -> usize {
        let mut n = 0;
        for r in &mut self.ranges_mm {
            if *r > max_range_mm {
                *r = 0.0;
                n += 1;
            }
        }
        n
    }
}

/// Ranges masked while reading or building a cloud: how many, and the first file line that
/// had one (0 when not read from a file).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Masked {
    /// Ranges masked.
    pub count: usize,
    /// The first line with one.
    pub first_line: Option<usize>,
}

impl Masked {
    /// Counts `n` ranges masked on `line`.
    pub fn add(&mut self, n: usize, line: usize) {
        if n > 0 {
            self.count += n;
            self.first_line.get_or_insert(line);
        }
    }

    /// "N range(s) … (first on line L)", for a warning: `what` says beyond what.
    pub fn describe(&self, what: &str) -> String {
        format!(
            "{} range{} {what} masked as no return{}",
            self.count,
            if self.count == 1 { "" } else { "s" },
            match self.first_line {
                Some(l) if l > 0 => format!(" (first on line {l})"),
                _ => String::new(),
            }
        )
    }
}

/// Masks the ranges of `lines` beyond `max_range_mm` ([`ScanLine::mask_beyond`]).
pub fn mask_lines_beyond(lines: &mut [ScanLine], max_range_mm: f64) -> Masked {
    let mut m = Masked::default();
    for l in lines {
        let n = l.mask_beyond(max_range_mm);
        m.add(n, l.line);
    }
    m
}

/// A streaming reader of a `pingcal-scan` CSV file.
///
/// The header (the `#` lines and the column line) is read by [`ScanReader::new`]; the
/// scans are then yielded one at a time by the iterator.
pub struct ScanReader<R: BufRead> {
    input: R,
    file: String,
    header: ScanHeader,
    n_beams: Option<usize>,
    /// `pingcal-scan` v2: a `servo_end_deg` column.
    sweep: bool,
    /// `pingcal-scan` v3 with intensity columns.
    intensities: bool,
    line_no: usize,
    pending: Option<(usize, String)>,
    buf: Vec<u8>,
    failed: bool,
    /// The previous scan's line number and stamp (time order), and its text in `previous_text`
    /// (duplicated records; one buffer reused for every line).
    previous: Option<(usize, f64)>,
    previous_text: String,
    /// Ranges beyond [`MAX_RANGE_MM`] masked so far.
    masked: Masked,
    /// `pingcal-scan` v4: `# geometry` lines may change the geometry between scans.
    sections: bool,
    /// The geometry of the scans now being read, once a `# geometry` line set it.
    geometry: Option<ScanHeader>,
    /// What the scans read so far show of their units ([`ScanReader::unit_slip`]).
    units: UnitEvidence,
}

/// What the scans of a file show of their units: the servo angles' extremes, the largest
/// range (mm, before ranges under 20 mm are read as no return) and the ranges of 20 mm or
/// more.
#[derive(Debug, Clone, Copy, Default)]
struct UnitEvidence {
    servo: Option<(f64, f64)>,
    scans: usize,
    largest_mm: f64,
    returns: usize,
}

impl UnitEvidence {
    fn servo(&mut self, deg: f64) {
        let (lo, hi) = self.servo.unwrap_or((deg, deg));
        self.servo = Some((lo.min(deg), hi.max(deg)));
    }
}

/// A rotating LRF's scans whose servo angles all lie within this (degrees) did not turn:
/// a scanner bolted to the head ([`ServoSpan::kind_slip`]).
pub const STANDING_SERVO_DEG: f64 = 0.5;

/// A fixed LRF's servo column is ignored, but one that spans more than this (degrees) is a
/// rotating LRF's sweep ([`ServoSpan::kind_slip`]).
pub const TURNING_SERVO_DEG: f64 = 1.0;

/// The servo angles a scan file's scans went through: the smallest and largest (degrees,
/// each scan's first and last beam) over how many scans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoSpan {
    /// The smallest servo angle (degrees).
    pub lo: f64,
    /// The largest (degrees).
    pub hi: f64,
    /// Scans read.
    pub scans: usize,
}

impl ServoSpan {
    /// Why these scans are not of the LRF kind the project says (`fixed`: a scanner bolted
    /// to the head, else one turned by a servo): a rotating LRF's scans that never turned,
    /// or a fixed LRF's that did; None when they agree.
    pub fn kind_slip(&self, fixed: bool) -> Option<String> {
        let span = self.hi - self.lo;
        if fixed && span > TURNING_SERVO_DEG {
            return Some(format!(
                "the servo angles span {span:.1}°: a rotating LRF's sweep, not a fixed scanner's scans ([lrf] kind = \"rotating\", the default)"
            ));
        }
        (!fixed && self.scans > 1 && span < STANDING_SERVO_DEG).then(|| {
            format!(
                "the servo angle of all {} scans is within {span:.2}° of {:.2}°: a scanner that did not turn; a 2D LRF bolted to the head is [lrf] kind = \"fixed\", its scans listed with their stations",
                self.scans, self.lo
            )
        })
    }
}

/// Servo angles all within this many units of 0, over a sweep of more than
/// [`RADIANS_SPAN`], are likely radians (2π and a little).
pub const RADIANS_BOUND: f64 = 6.3;
/// The sweep (largest minus smallest servo angle) above which angles within
/// [`RADIANS_BOUND`] are likely radians: π (a sweep of 3.1° in degrees calibrates
/// nothing).
pub const RADIANS_SPAN: f64 = 3.1;

fn read_line<R: BufRead>(
    input: &mut R,
    buf: &mut Vec<u8>,
    file: &str,
    line_no: usize,
) -> Result<Option<String>> {
    buf.clear();
    let n = input
        .read_until(b'\n', buf)
        .map_err(|e| LrfError::io(file, e))?;
    if n == 0 {
        return Ok(None);
    }
    if !buf.ends_with(b"\n") && !buf.iter().all(u8::is_ascii_whitespace) {
        return Err(LrfError::cut_short(file, line_no));
    }
    let s =
        std::str::from_utf8(buf).map_err(|_| LrfError::parse(file, line_no, "not UTF-8 text"))?;
    let s = LrfError::without_bom(line_no, s);
    Ok(Some(s.trim_end_matches(['\n', '\r']).to_string()))
}

/// The column line's beams and whether it has intensity columns: `stamp_s,servo_deg`, then
/// `servo_end_deg` when `sweep` (v2, v3), the ranges `r0..`, and in v3 (`v3`) optionally as
/// many intensities `i0..`.
fn column_line(cols: &[&str], sweep: bool, v3: bool) -> std::result::Result<(usize, bool), String> {
    let fixed = if sweep { 3 } else { 2 };
    let ok = cols.len() > fixed && cols[1] == "servo_deg" && (cols[2] == "servo_end_deg") == sweep;
    if !ok {
        return Err(if sweep {
            "a v2 column line: expected `stamp_s,servo_deg,servo_end_deg,r0,r1,...`".into()
        } else {
            "column line: expected `stamp_s,servo_deg,r0,r1,...` (a servo_end_deg column needs `# pingcal-scan v2`)".into()
        });
    }
    let beams = &cols[fixed..];
    let Some(first_i) = beams.iter().position(|c| *c == "i0") else {
        return Ok((beams.len(), false));
    };
    if !v3 {
        return Err("intensity columns (i0, ...) need `# pingcal-scan v3`".into());
    }
    if first_i * 2 != beams.len() {
        return Err(format!(
            "a v3 column line with {first_i} ranges and {} intensities: expected as many of each",
            beams.len() - first_i
        ));
    }
    Ok((first_i, true))
}

fn parse_intensities(file: &str, line: usize, fields: &[&str]) -> Result<Vec<f32>> {
    fields
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let t = f.trim();
            match t.parse::<f32>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => Err(LrfError::parse(
                    file,
                    line,
                    format!("intensity i{i}: expected a number, found {t:?}"),
                )),
            }
        })
        .collect()
}

/// `v` as written for a message: plainly, or in e-notation when it is huge or tiny.
pub fn short(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

fn parse_f64(file: &str, line: usize, what: &str, s: &str) -> Result<f64> {
    let t = s.trim();
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(LrfError::parse(
            file,
            line,
            format!("{what}: expected a number, found {t:?}"),
        )),
    }
}

/// What the header's lines said so far.
struct HeaderSoFar {
    angle_min: Option<f64>,
    increment: Option<f64>,
    mm_per_unit: f64,
    n_beams: Option<usize>,
    version: Option<u32>,
    sweep: bool,
    intensities: bool,
    time_increment_s: Option<f64>,
    /// The line of the column line (`stamp_s,…`), 0 before it.
    columns_line: usize,
}

impl HeaderSoFar {
    fn new() -> Self {
        HeaderSoFar {
            angle_min: None,
            increment: None,
            mm_per_unit: 1.0,
            n_beams: None,
            version: None,
            sweep: false,
            intensities: false,
            time_increment_s: None,
            columns_line: 0,
        }
    }

    /// A `# …` line: the version line, a `key=value` line, or a comment.
    fn comment(&mut self, rest: &str, line_no: usize, file: &str) -> Result<()> {
        if let Some(v) = rest.strip_prefix("pingcal-scan v") {
            self.version = Some(match v.trim() {
                "1" => 1,
                "2" => 2,
                "3" => 3,
                "4" => 4,
                v => {
                    return Err(LrfError::parse(
                        file,
                        line_no,
                        format!("pingcal-scan version {v:?}: this pingcal reads v1, v2, v3 and v4"),
                    ))
                }
            });
            return Ok(());
        }
        if let Some((k, v)) = rest.split_once('=') {
            self.key_value(k.trim(), v.trim(), line_no, file)?;
        }
        Ok(())
    }

    /// A `# key=value` line of the header; unknown keys are ignored.
    fn key_value(&mut self, k: &str, v: &str, line_no: usize, file: &str) -> Result<()> {
        match k {
            "angle_min_deg" => {
                let a = parse_f64(file, line_no, k, v)?;
                if !(a.abs() <= MAX_SPAN_DEG) {
                    return Err(LrfError::parse(
                        file,
                        line_no,
                        format!(
                            "angle_min_deg = {}: expected an angle within ±{MAX_SPAN_DEG}°",
                            short(a)
                        ),
                    ));
                }
                self.angle_min = Some(a)
            }
            "angle_increment_deg" => {
                let inc = parse_f64(file, line_no, k, v)?;
                if inc == 0.0 {
                    return Err(LrfError::parse(
                        file,
                        line_no,
                        "angle_increment_deg must not be 0",
                    ));
                }
                self.increment = Some(inc)
            }
            "time_increment_s" => {
                let ti = parse_f64(file, line_no, k, v)?;
                // v4 may time the beams from the last to the first
                if ti < 0.0 && self.version != Some(4) {
                    return Err(LrfError::parse(
                        file,
                        line_no,
                        format!("time_increment_s: {ti} is negative"),
                    ));
                }
                self.time_increment_s = Some(ti)
            }
            "range_unit" => {
                self.mm_per_unit = match v {
                    "mm" => 1.0,
                    "cm" => 10.0,
                    "m" => 1000.0,
                    _ => {
                        return Err(LrfError::parse(
                            file,
                            line_no,
                            format!("range_unit: expected mm, cm or m, found {v:?}"),
                        ))
                    }
                }
            }
            _ => {} // unknown keys are ignored (docs/lrf.md)
        }
        Ok(())
    }

    /// The column line `stamp_s,…`: the number of beams, sweeps and intensities.
    fn columns(&mut self, t: &str, line_no: usize, file: &str) -> Result<()> {
        let cols: Vec<&str> = t.split(',').map(str::trim).collect();
        self.sweep = self.version.is_some_and(|v| v >= 2);
        let (n, with_i) = column_line(&cols, self.sweep, self.version.is_some_and(|v| v >= 3))
            .map_err(|e| LrfError::parse(file, line_no, e))?;
        self.n_beams = Some(n);
        self.intensities = with_i;
        self.columns_line = line_no;
        Ok(())
    }
}

/// Refuses `n_beams` beams `increment_deg` apart that span more than a turn.
fn check_span(file: &str, increment_deg: f64, n_beams: usize, line_no: usize) -> Result<()> {
    let span = increment_deg.abs() * n_beams.saturating_sub(1) as f64;
    if !(span <= MAX_SPAN_DEG) {
        return Err(LrfError::parse(
            file,
            line_no,
            format!(
                "angle_increment_deg = {} over {n_beams} beams spans {}°: the beams of a scan span at most {MAX_SPAN_DEG}° (a wrong header?)",
                short(increment_deg),
                short(span)
            ),
        ));
    }
    Ok(())
}

/// [`ScanReader::unit_slip`] of what the scans showed, in a file of `mm_per_unit`.
fn unit_slip(u: &UnitEvidence, mm_per_unit: f64) -> Option<String> {
    if let Some((lo, hi)) = u.servo {
        if lo >= -RADIANS_BOUND && hi <= RADIANS_BOUND && hi - lo > RADIANS_SPAN {
            return Some(format!(
                "the servo angles span {lo:.2}…{hi:.2}: radians? the scan file's column is degrees (servo_deg); convert them (× 180/π)"
            ));
        }
    }
    if u.returns == 0 && u.largest_mm > 0.0 {
        let unit = if mm_per_unit == 1.0 {
            "mm"
        } else if mm_per_unit == 10.0 {
            "cm"
        } else {
            "m"
        };
        let largest = u.largest_mm / mm_per_unit;
        return Some(format!(
            "every range is under {MIN_VALID_RANGE_MM} mm, the largest {}: metres? the file says range_unit={unit}; write # range_unit=m or the ranges in mm",
            short(largest)
        ));
    }
    None
}

impl<R: BufRead> ScanReader<R> {
    /// Reads the header. `file` is the name used in error messages.
    pub fn new(mut input: R, file: &str) -> Result<Self> {
        let mut buf = Vec::new();
        let mut line_no = 0;
        let mut h = HeaderSoFar::new();
        let mut pending = None;
        loop {
            line_no += 1;
            let Some(line) = read_line(&mut input, &mut buf, file, line_no)? else {
                break;
            };
            let t = line.trim();
            if t.is_empty() {
                continue;
            }
            if let Some(rest) = t.strip_prefix('#') {
                h.comment(rest.trim(), line_no, file)?;
                continue;
            }
            if t.starts_with("stamp_s") {
                h.columns(t, line_no, file)?;
                continue;
            }
            if h.version.is_some_and(|v| v >= 2) && h.n_beams.is_none() {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    "a v2 file needs its column line `stamp_s,servo_deg,servo_end_deg,r0,...` before the scans",
                ));
            }
            pending = Some((line_no, line));
            break;
        }
        let HeaderSoFar {
            angle_min,
            increment,
            mm_per_unit,
            n_beams,
            version,
            sweep,
            intensities,
            time_increment_s,
            columns_line,
        } = h;
        let missing = |key: &str| LrfError::Empty {
            file: file.to_string(),
            msg: format!("header has no `# {key}=` line"),
        };
        if angle_min.is_none() && increment.is_none() && pending.is_none() && n_beams.is_none() {
            return Err(LrfError::Empty {
                file: file.to_string(),
                msg: "empty file: no header and no scans".into(),
            });
        }
        let angle_min_deg = angle_min.ok_or_else(|| missing("angle_min_deg"))?;
        let angle_increment_deg = increment.ok_or_else(|| missing("angle_increment_deg"))?;
        let reader = ScanReader {
            input,
            file: file.to_string(),
            header: ScanHeader {
                angle_min_deg,
                angle_increment_deg,
                mm_per_unit,
                time_increment_s,
            },
            n_beams,
            sweep,
            intensities,
            line_no,
            pending,
            buf,
            failed: false,
            previous: None,
            previous_text: String::new(),
            masked: Masked::default(),
            sections: version == Some(4),
            geometry: None,
            units: UnitEvidence::default(),
        };
        if let Some(n) = n_beams {
            reader.check_span(n, columns_line)?;
        }
        Ok(reader)
    }

    /// The beam geometry.
    pub fn header(&self) -> ScanHeader {
        self.header
    }

    /// Number of beams per scan, once known (column line or first scan).
    pub fn n_beams(&self) -> Option<usize> {
        self.n_beams
    }

    /// The ranges beyond [`MAX_RANGE_MM`] masked in the scans read so far.
    pub fn masked(&self) -> Masked {
        self.masked
    }

    /// Refuses beams that span more than a turn, once their number is known.
    fn check_span(&self, n_beams: usize, line_no: usize) -> Result<()> {
        check_span(
            &self.file,
            self.header.angle_increment_deg,
            n_beams,
            line_no,
        )
    }

    /// The unit the scans read so far likely have where the file says another (module
    /// doc): the servo column in radians, or the ranges in metres; `None` when the data
    /// agree with the file. Meaningful once every scan has been read.
    pub fn unit_slip(&self) -> Option<String> {
        unit_slip(&self.units, self.header.mm_per_unit)
    }

    /// The servo angles the scans read so far went through; None before any.
    pub fn servo_span(&self) -> Option<ServoSpan> {
        (self.units.servo).map(|(lo, hi)| ServoSpan {
            lo,
            hi,
            scans: self.units.scans,
        })
    }

    /// A v4 `# geometry …` line: the geometry of the scans after it.
    fn geometry_line(&mut self, rest: &str, line_no: usize) -> Result<()> {
        let file = self.file.as_str();
        let mut h = HeaderSoFar::new();
        h.version = Some(4);
        let mut beams = None;
        for word in rest.split_whitespace() {
            let Some((k, v)) = word.split_once('=') else {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!("a geometry line: expected key=value words, found {word:?}"),
                ));
            };
            match k {
                "beams" => match v.parse::<usize>() {
                    Ok(n) if n > 0 => beams = Some(n),
                    _ => {
                        return Err(LrfError::parse(
                            file,
                            line_no,
                            format!("beams: expected a whole number above 0, found {v:?}"),
                        ))
                    }
                },
                "angle_min_deg" | "angle_increment_deg" | "time_increment_s" => {
                    h.key_value(k, v, line_no, file)?
                }
                _ => {
                    return Err(LrfError::parse(
                        file,
                        line_no,
                        format!("a geometry line: unknown key {k:?} (expected angle_min_deg, angle_increment_deg, beams, time_increment_s)"),
                    ))
                }
            }
        }
        let (Some(angle_min_deg), Some(angle_increment_deg), Some(n)) =
            (h.angle_min, h.increment, beams)
        else {
            return Err(LrfError::parse(
                file,
                line_no,
                "a geometry line needs angle_min_deg=, angle_increment_deg= and beams=",
            ));
        };
        check_span(file, angle_increment_deg, n, line_no)?;
        self.geometry = Some(ScanHeader {
            angle_min_deg,
            angle_increment_deg,
            mm_per_unit: self.header.mm_per_unit,
            time_increment_s: h.time_increment_s,
        });
        self.n_beams = Some(n);
        Ok(())
    }

    fn parse_scan(&mut self, line_no: usize, line: &str) -> Result<ScanLine> {
        let file = self.file.as_str();
        let mut fields = line.split(',');
        let stamp_s = parse_f64(file, line_no, "stamp_s", fields.next().unwrap_or(""))?;
        let servo_deg = parse_f64(
            file,
            line_no,
            "servo_deg",
            fields.next().ok_or_else(|| {
                LrfError::parse(file, line_no, "expected `stamp_s,servo_deg,r0,...`")
            })?,
        )?;
        let servo_end_deg = if self.sweep {
            let f = fields.next().ok_or_else(|| {
                LrfError::parse(
                    file,
                    line_no,
                    "expected `stamp_s,servo_deg,servo_end_deg,r0,...`",
                )
            })?;
            Some(parse_f64(file, line_no, "servo_end_deg", f)?)
        } else {
            None
        };
        let end = servo_end_deg.unwrap_or(servo_deg);
        for (what, v, max) in [
            ("stamp_s", stamp_s, MAX_STAMP_S),
            ("servo_deg", servo_deg, MAX_SERVO_DEG),
            ("servo_end_deg", end, MAX_SERVO_DEG),
        ] {
            if v.abs() > max {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!("{what}: {v:e} is beyond ±{max:e}: a corrupt line?"),
                ));
            }
        }
        let mut ranges_mm = Vec::with_capacity(self.n_beams.unwrap_or(0));
        let mut masked = 0;
        let rest: Vec<&str> = fields.collect();
        let (range_fields, intensities) = self.ranges_and_intensities(&rest, line_no)?;
        for (i, f) in range_fields.iter().enumerate() {
            let v = parse_f64(file, line_no, &format!("range r{i}"), f)?;
            if v < 0.0 {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!("range r{i}: negative value {v}"),
                ));
            }
            let mm = v * self.header.mm_per_unit;
            if mm > MAX_RANGE_MM {
                masked += 1;
                ranges_mm.push(0.0);
                continue;
            }
            self.units.largest_mm = self.units.largest_mm.max(mm);
            self.units.returns += usize::from(mm >= MIN_VALID_RANGE_MM);
            ranges_mm.push(if mm < MIN_VALID_RANGE_MM { 0.0 } else { mm });
        }
        if ranges_mm.is_empty() {
            return Err(LrfError::parse(
                file,
                line_no,
                "no ranges after stamp_s,servo_deg",
            ));
        }
        match self.n_beams {
            Some(n) if n != ranges_mm.len() => {
                return Err(LrfError::parse(
                    file,
                    line_no,
                    format!("expected {n} ranges, found {}", ranges_mm.len()),
                ))
            }
            None => {
                self.check_span(ranges_mm.len(), line_no)?;
                self.n_beams = Some(ranges_mm.len())
            }
            _ => {}
        }
        self.masked.add(masked, line_no);
        self.units.servo(servo_deg);
        self.units.servo(end);
        self.units.scans += 1;
        Ok(ScanLine {
            line: line_no,
            stamp_s,
            servo_deg,
            servo_end_deg,
            ranges_mm,
            intensities,
            geometry: self.geometry,
        })
    }

    /// A scan line's values after its servo columns: the ranges' fields and the
    /// intensities (v3 with intensity columns: n of each; v4: n ranges, and n intensities or
    /// none).
    fn ranges_and_intensities<'t>(
        &self,
        rest: &'t [&'t str],
        line_no: usize,
    ) -> Result<(&'t [&'t str], Vec<f32>)> {
        let file = self.file.as_str();
        let n = self.n_beams.unwrap_or(0);
        let with_i = if self.sections {
            n > 0 && rest.len() != n
        } else {
            self.intensities
        };
        if !with_i {
            return Ok((rest, Vec::new()));
        }
        if rest.len() != 2 * n {
            let expected = if self.sections {
                format!("{n} ranges, or {n} ranges and {n} intensities")
            } else {
                format!("{n} ranges and {n} intensities")
            };
            return Err(LrfError::parse(
                file,
                line_no,
                format!("expected {expected}, found {} values", rest.len()),
            ));
        }
        let intensities = parse_intensities(file, line_no, &rest[n..])?;
        Ok((&rest[..n], intensities))
    }

    /// Refuses a scan earlier than the previous one, or an exact repeat of it (module doc).
    fn check_order(&mut self, scan: &ScanLine, text: &str) -> Result<()> {
        if let Some((k, stamp)) = &self.previous {
            if scan.stamp_s < *stamp {
                return Err(LrfError::parse(
                    &self.file,
                    scan.line,
                    format!(
                        "stamp_s {} is earlier than line {k}'s {stamp}: scans must be in time order",
                        scan.stamp_s
                    ),
                ));
            }
            if text == self.previous_text {
                return Err(LrfError::parse(
                    &self.file,
                    scan.line,
                    format!("repeats line {k} exactly (stamp, servo angle and every range): a duplicated record?"),
                ));
            }
        }
        self.previous = Some((scan.line, scan.stamp_s));
        self.previous_text.clear();
        self.previous_text.push_str(text);
        Ok(())
    }

    fn next_scan(&mut self) -> Result<Option<ScanLine>> {
        loop {
            let (line_no, line) = match self.pending.take() {
                Some(p) => p,
                None => {
                    self.line_no += 1;
                    match read_line(&mut self.input, &mut self.buf, &self.file, self.line_no)? {
                        Some(l) => (self.line_no, l),
                        None => return Ok(None),
                    }
                }
            };
            let t = line.trim();
            if self.sections {
                if let Some(rest) = t.strip_prefix("# geometry ") {
                    self.geometry_line(rest, line_no)?;
                    continue;
                }
            }
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let scan = self.parse_scan(line_no, t)?;
            self.check_order(&scan, t)?;
            return Ok(Some(scan));
        }
    }
}

impl<R: BufRead> Iterator for ScanReader<R> {
    type Item = Result<ScanLine>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        match self.next_scan() {
            Ok(Some(s)) => Some(Ok(s)),
            Ok(None) => None,
            Err(e) => {
                self.failed = true;
                Some(Err(e))
            }
        }
    }
}

/// Opens a scan file for streaming.
pub fn open_scan_file(
    path: &std::path::Path,
) -> Result<ScanReader<std::io::BufReader<std::fs::File>>> {
    let name = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| LrfError::io(&name, e))?;
    ScanReader::new(std::io::BufReader::with_capacity(1 << 16, f), &name)
}

/// The refusal of a scan file whose data contradict its units ([`ScanReader::unit_slip`]),
/// once `reader` has read every scan.
pub fn check_units<R: BufRead>(reader: &ScanReader<R>) -> Result<()> {
    match reader.unit_slip() {
        Some(slip) => Err(LrfError::Invalid(format!("{}: {slip}", reader.file))),
        None => Ok(()),
    }
}

/// Reads the scan file `path` through, as a project's scan files are checked when it is
/// loaded (before any image is read): the first malformed line, or data that contradict
/// the file's units ([`ScanReader::unit_slip`]), refused; else the servo angles its scans
/// went through (for [`ServoSpan::kind_slip`]).
pub fn check_scan_file(path: &std::path::Path) -> Result<Option<ServoSpan>> {
    let mut reader = open_scan_file(path)?;
    for line in reader.by_ref() {
        line?;
    }
    check_units(&reader)?;
    Ok(reader.servo_span())
}

/// A streaming writer of the `pingcal-scan` format: the header (with optional extra
/// `# key=value` lines) when created, then one scan per [`ScanWriter::write_scan`] (v1, or
/// v2 made by [`ScanWriter::new_v2`]). Time stamps are written with 3 decimals, servo
/// angles with 6 (the simulator's encoder steps of 0.088° need more than 3), ranges
/// rounded to whole mm as the URG reports them, no return as 0.
pub struct ScanWriter<W: Write> {
    out: W,
    sweep: bool,
    /// v3: intensity columns after the ranges.
    intensities: Option<usize>,
    /// The geometry and beam count of the scans now written ([`ScanWriter::write_line_in`]).
    section: (ScanHeader, usize),
    /// A `# geometry` line, or a scan whose intensities the column line does not have, was
    /// written: the file is v4 ([`ScanWriter::needs_v4`]).
    amended: bool,
}

/// The byte offset of the version digit in every `pingcal-scan` file this writer starts
/// (`# pingcal-scan v` is 16 bytes): a writer of a seekable file that learns late that it
/// needs v4 ([`ScanWriter::needs_v4`]) puts `4` there, the rest of the file being the same.
pub const VERSION_DIGIT_OFFSET: u64 = 16;

impl<W: Write> ScanWriter<W> {
    /// Writes a v1 header: the beam geometry of `header`, ranges in mm, the `extra` lines
    /// (each written as `# line`, e.g. `sensor=...`) and the column line of `n_beams` ranges.
    pub fn new(
        out: W,
        header: &ScanHeader,
        n_beams: usize,
        extra: &[&str],
    ) -> std::io::Result<Self> {
        Self::with_version(out, header, n_beams, extra, 1)
    }

    /// Writes a v2 header (a `servo_end_deg` column: continuous sweeps), otherwise as
    /// [`ScanWriter::new`].
    pub fn new_v2(
        out: W,
        header: &ScanHeader,
        n_beams: usize,
        extra: &[&str],
    ) -> std::io::Result<Self> {
        Self::with_version(out, header, n_beams, extra, 2)
    }

    /// Writes a v3 header (v2 with `n_beams` intensity columns after the ranges); every scan
    /// written must then carry its intensities.
    pub fn new_v3(
        out: W,
        header: &ScanHeader,
        n_beams: usize,
        extra: &[&str],
    ) -> std::io::Result<Self> {
        Self::with_version(out, header, n_beams, extra, 3)
    }

    fn with_version(
        mut out: W,
        header: &ScanHeader,
        n_beams: usize,
        extra: &[&str],
        version: u8,
    ) -> std::io::Result<Self> {
        writeln!(out, "# pingcal-scan v{version}")?;
        writeln!(out, "# angle_min_deg={}", header.angle_min_deg)?;
        writeln!(out, "# angle_increment_deg={}", header.angle_increment_deg)?;
        writeln!(out, "# range_unit=mm")?;
        if let Some(ti) = header.time_increment_s {
            writeln!(out, "# time_increment_s={ti}")?;
        }
        for line in extra {
            writeln!(out, "# {line}")?;
        }
        write!(out, "stamp_s,servo_deg")?;
        let sweep = version >= 2;
        if sweep {
            write!(out, ",servo_end_deg")?;
        }
        for i in 0..n_beams {
            write!(out, ",r{i}")?;
        }
        if version == 3 {
            for i in 0..n_beams {
                write!(out, ",i{i}")?;
            }
        }
        writeln!(out)?;
        Ok(ScanWriter {
            out,
            sweep,
            intensities: (version == 3).then_some(n_beams),
            section: (*header, n_beams),
            // beams timed from the last to the first: v4 only
            amended: header.time_increment_s.is_some_and(|t| t < 0.0),
        })
    }

    /// Writes one scan of beam geometry `geometry` (a v2 or v3 writer): when its geometry
    /// or beam count differs from the scans before it, a `# geometry` line first; its
    /// intensities when it has one per beam. The file is then v4 ([`ScanWriter::needs_v4`])
    /// when a geometry line was written or a scan's intensities differ from the column line.
    pub fn write_line_in(&mut self, geometry: &ScanHeader, s: &ScanLine) -> std::io::Result<()> {
        if !self.sweep {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "scans of several geometries need a pingcal-scan v2 or v3 writer",
            ));
        }
        let n = s.ranges_mm.len();
        if (*geometry, n) != self.section {
            write!(
                self.out,
                "# geometry angle_min_deg={} angle_increment_deg={} beams={n}",
                geometry.angle_min_deg, geometry.angle_increment_deg
            )?;
            if let Some(ti) = geometry.time_increment_s {
                write!(self.out, " time_increment_s={ti}")?;
            }
            writeln!(self.out)?;
            self.section = (*geometry, n);
            self.amended = true;
        }
        let with_i = s.intensities.len() == n;
        if with_i != self.intensities.is_some() {
            self.amended = true;
        }
        let end = s.servo_end_deg.unwrap_or(s.servo_deg);
        write!(self.out, "{:.3},{:.6},{end:.6}", s.stamp_s, s.servo_deg)?;
        self.write_ranges(s.ranges_mm.iter().copied())?;
        if with_i {
            self.write_intensities(&s.intensities)?;
        }
        writeln!(self.out)
    }

    /// True when the scans written need `# pingcal-scan v4` ([`ScanWriter::write_line_in`]).
    pub fn needs_v4(&self) -> bool {
        self.amended
    }

    fn write_intensities(&mut self, intensities: &[f32]) -> std::io::Result<()> {
        for v in intensities {
            // non-finite intensities are not written (the reader refuses them): 0
            let v = if v.is_finite() { *v } else { 0.0 };
            write!(self.out, ",{v}")?;
        }
        Ok(())
    }

    /// Writes one scan taken with the servo at `servo_deg`: its time stamp (s), servo
    /// angle (degrees) and ranges (mm, 0 for no return).
    pub fn write_scan<I>(
        &mut self,
        stamp_s: f64,
        servo_deg: f64,
        ranges_mm: I,
    ) -> std::io::Result<()>
    where
        I: IntoIterator,
        I::Item: Into<f64>,
    {
        self.write_sweep_scan(stamp_s, servo_deg, servo_deg, ranges_mm)
    }

    /// Writes one scan with the servo at `servo_deg` at its first beam and `servo_end_deg`
    /// at its last; a v1 writer refuses a scan whose two angles differ.
    pub fn write_sweep_scan<I>(
        &mut self,
        stamp_s: f64,
        servo_deg: f64,
        servo_end_deg: f64,
        ranges_mm: I,
    ) -> std::io::Result<()>
    where
        I: IntoIterator,
        I::Item: Into<f64>,
    {
        write!(self.out, "{stamp_s:.3},{servo_deg:.6}")?;
        if self.sweep {
            write!(self.out, ",{servo_end_deg:.6}")?;
        } else if servo_end_deg != servo_deg {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a scan taken while the servo turned needs a pingcal-scan v2 writer",
            ));
        }
        // whole millimetres through itoa: formatting through `write!` was most of the time
        // of `pingcal scans` on a 1 GB bag (bench/rosbag)
        if self.intensities.is_some() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "a pingcal-scan v3 writer needs each scan's intensities (write_line)",
            ));
        }
        self.write_ranges(ranges_mm)?;
        writeln!(self.out)
    }

    fn write_ranges<I>(&mut self, ranges_mm: I) -> std::io::Result<()>
    where
        I: IntoIterator,
        I::Item: Into<f64>,
    {
        let mut digits = itoa::Buffer::new();
        for r in ranges_mm {
            self.out.write_all(b",")?;
            self.out
                .write_all(digits.format(r.into().round() as i64).as_bytes())?;
        }
        Ok(())
    }

    /// Writes one scan line (its `servo_end_deg`, when given, needs a v2 writer; a v3
    /// writer writes its intensities, which must be one per beam).
    pub fn write_line(&mut self, s: &ScanLine) -> std::io::Result<()> {
        let end = s.servo_end_deg.unwrap_or(s.servo_deg);
        let Some(n) = self.intensities else {
            return self.write_sweep_scan(s.stamp_s, s.servo_deg, end, s.ranges_mm.iter().copied());
        };
        if s.intensities.len() != n || s.ranges_mm.len() != n {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "a pingcal-scan v3 line needs {n} ranges and {n} intensities, not {} and {}",
                    s.ranges_mm.len(),
                    s.intensities.len()
                ),
            ));
        }
        write!(self.out, "{:.3},{:.6},{end:.6}", s.stamp_s, s.servo_deg)?;
        self.write_ranges(s.ranges_mm.iter().copied())?;
        self.write_intensities(&s.intensities)?;
        writeln!(self.out)
    }

    /// The underlying writer (flushed).
    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Writes scans through [`ScanWriter`], without extra header lines: v1, v2 when a scan
/// has a `servo_end_deg`, v3 when the first has intensities.
pub fn write_scans<W: Write>(w: W, header: &ScanHeader, scans: &[ScanLine]) -> std::io::Result<()> {
    let n = scans.first().map_or(0, |s| s.ranges_mm.len());
    let mut out = if scans.first().is_some_and(|s| !s.intensities.is_empty()) {
        ScanWriter::new_v3(w, header, n, &[])?
    } else if scans.iter().any(|s| s.servo_end_deg.is_some()) {
        ScanWriter::new_v2(w, header, n, &[])?
    } else {
        ScanWriter::new(w, header, n, &[])?
    };
    for s in scans {
        out.write_line(s)?;
    }
    out.finish().map(drop)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_all(text: &str) -> Result<(ScanHeader, Vec<ScanLine>)> {
        let r = ScanReader::new(text.as_bytes(), "t.csv")?;
        let h = r.header();
        let v: Result<Vec<_>> = r.collect();
        Ok((h, v?))
    }

    const GOOD: &str = "# pingcal-scan v1\n# angle_min_deg=-119.53125\n# angle_increment_deg=0.3515625\n# range_unit=mm\n# sensor=URG-04LX\nstamp_s,servo_deg,r0,r1,r2\n0.000,-45.056,1532,1530,0\n0.100,-44.9,1531,7,1529\n";

    /// A rotating LRF's scans that never turned, and a fixed LRF's that did, are named; a
    /// sweep, a fixed LRF's standing servo, and one scan are not.
    #[test]
    fn a_servo_that_never_turned_or_did_is_named_against_the_kind() {
        let standing = ServoSpan {
            lo: 0.0,
            hi: 0.0,
            scans: 5,
        };
        assert!(standing.kind_slip(false).unwrap().contains("did not turn"));
        assert_eq!(standing.kind_slip(true), None);
        let sweep = ServoSpan {
            lo: -180.0,
            hi: 179.9,
            scans: 4096,
        };
        assert!(sweep.kind_slip(true).unwrap().contains("span 359.9°"));
        assert_eq!(sweep.kind_slip(false), None);
        let one = ServoSpan {
            lo: 3.0,
            hi: 3.0,
            scans: 1,
        };
        assert_eq!(one.kind_slip(false), None);
    }

    #[test]
    fn reads_header_and_lines() {
        let (h, v) = read_all(GOOD).unwrap();
        assert_eq!(h.angle_min_deg, -119.53125);
        assert_eq!(h.angle_increment_deg, 0.3515625);
        assert_eq!(v.len(), 2);
        assert_eq!(v[0].line, 7);
        assert_eq!(v[0].ranges_mm, vec![1532.0, 1530.0, 0.0]);
        // 7 is a URG error code: no return
        assert_eq!(v[1].ranges_mm, vec![1531.0, 0.0, 1529.0]);
        assert_eq!(v[1].servo_deg, -44.9);
    }

    #[test]
    fn scans_out_of_time_order_or_repeated_are_refused_naming_both_lines() {
        let t = GOOD.replace("0.100,-44.9", "-0.100,-44.9");
        let e = read_all(&t).unwrap_err().to_string();
        assert_eq!(
            e,
            "t.csv:8: stamp_s -0.1 is earlier than line 7's 0: scans must be in time order"
        );
        let t = format!("{GOOD}0.100,-44.9,1531,7,1529\n");
        let e = read_all(&t).unwrap_err().to_string();
        assert!(e.starts_with("t.csv:9: repeats line 8 exactly"), "{e}");
        // equal stamps are legal (no clock), and so is the same servo angle with new ranges
        let t = format!(
            "{}0.000,-44.9,1530,7,1529\n",
            GOOD.replace("0.100,", "0.000,")
        );
        assert_eq!(read_all(&t).unwrap().1.len(), 3);
    }

    #[test]
    fn a_byte_order_mark_is_skipped() {
        let (h, v) = read_all(&format!("\u{feff}{GOOD}")).unwrap();
        assert_eq!(h.angle_min_deg, -119.53125);
        assert_eq!(v.len(), 2);
    }

    #[test]
    fn range_unit_metres() {
        let t = GOOD
            .replace("range_unit=mm", "range_unit=m")
            .replace("1532,1530,0", "1.532,1.5,0.01")
            .replace("1531,7,1529", "1.531,0.007,1.529");
        let (_, v) = read_all(&t).unwrap();
        assert_eq!(v[0].ranges_mm, vec![1532.0, 1500.0, 0.0]);
    }

    #[test]
    fn wrong_count_names_line() {
        let t = GOOD.replace("1531,7,1529", "1531,7");
        let e = read_all(&t).unwrap_err().to_string();
        assert_eq!(e, "t.csv:8: expected 3 ranges, found 2");
    }

    #[test]
    fn non_numeric_names_line_and_field() {
        let t = GOOD.replace("1531,7", "1531,abc");
        let e = read_all(&t).unwrap_err().to_string();
        assert_eq!(e, "t.csv:8: range r1: expected a number, found \"abc\"");
        let t = GOOD.replace("-44.9", "x");
        let e = read_all(&t).unwrap_err().to_string();
        assert!(e.starts_with("t.csv:8: servo_deg"), "{e}");
    }

    #[test]
    fn ranges_beyond_any_sensor_are_masked_and_counted_with_the_line() {
        let t = GOOD.replace("1531,7,1529", "1531,1e300,1529");
        let mut r = ScanReader::new(t.as_bytes(), "t.csv").unwrap();
        let v = r.by_ref().collect::<Result<Vec<_>>>().unwrap();
        assert_eq!(v[1].ranges_mm, vec![1531.0, 0.0, 1529.0]);
        assert_eq!(
            r.masked(),
            Masked {
                count: 1,
                first_line: Some(8)
            }
        );
        assert_eq!(
            r.masked().describe("beyond 1e6 mm"),
            "1 range beyond 1e6 mm masked as no return (first on line 8)"
        );
        let t = GOOD.replace("1531,7,1529", "1531,inf,1529");
        let e = read_all(&t).unwrap_err().to_string();
        assert!(e.starts_with("t.csv:8: range r1: expected a number"), "{e}");
        // 1 km exactly is still a range.
        let t = GOOD.replace("1531,7,1529", "1531,1000000,1529");
        assert_eq!(read_all(&t).unwrap().1[1].ranges_mm[1], 1e6);
        // the sensor's own maximum, by the caller
        let (_, mut v) = read_all(GOOD).unwrap();
        let m = mask_lines_beyond(&mut v, 1530.0);
        assert_eq!((m.count, m.first_line), (2, Some(7)));
        assert_eq!(v[0].ranges_mm, vec![0.0, 1530.0, 0.0]);
    }

    #[test]
    fn beams_spanning_more_than_a_turn_are_refused_at_the_header() {
        for (inc, line) in [("1e308", 6), ("360", 6), ("0.6", 6)] {
            let t = GOOD.replace("0.3515625", inc);
            // three beams: 1e308 and 360 span more than a turn, 0.6 does not
            match read_all(&t) {
                Ok(_) => assert_eq!(inc, "0.6"),
                Err(e) => {
                    let e = e.to_string();
                    assert!(
                        e.starts_with(&format!("t.csv:{line}: angle_increment_deg = "))
                            && e.contains("at most 360°"),
                        "{e}"
                    );
                }
            }
        }
        let t = GOOD.replace("-119.53125", "1e308");
        let e = read_all(&t).unwrap_err().to_string();
        assert!(
            e.contains("angle_min_deg = 1e308: expected an angle within ±360°"),
            "{e}"
        );
    }

    #[test]
    fn the_bad_inputs_with_huge_ranges_are_masked() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/bad-inputs");
        for (name, line) in [
            ("cloud_range_1e300_writes_inf_into_ply.csv", 6),
            ("scan_csv_slow_11477156d6.csv", 12),
        ] {
            let path = dir.join(name);
            if !path.exists() {
                println!("skipped: {} is absent", path.display());
                continue;
            }
            let mut r = open_scan_file(&path).unwrap();
            let v = r.by_ref().collect::<Result<Vec<_>>>().unwrap();
            assert!(v
                .iter()
                .flat_map(|l| &l.ranges_mm)
                .all(|&x| x <= MAX_RANGE_MM));
            assert_eq!(r.masked().first_line, Some(line), "{name}");
        }
    }

    #[test]
    fn empty_file_and_missing_increment() {
        let e = read_all("").unwrap_err().to_string();
        assert!(e.contains("empty file"), "{e}");
        let t = GOOD.replace("# angle_increment_deg=0.3515625\n", "");
        let e = read_all(&t).unwrap_err().to_string();
        assert_eq!(e, "t.csv: header has no `# angle_increment_deg=` line");
    }

    #[test]
    fn write_then_read_round_trip() {
        let scans = vec![
            ScanLine {
                line: 0,
                stamp_s: 0.0,
                servo_deg: 1.5,
                servo_end_deg: None,
                ranges_mm: vec![1000.0, 0.0, 2500.0],
                intensities: vec![],
                geometry: None,
            },
            ScanLine {
                line: 0,
                stamp_s: 0.1,
                servo_deg: 1.6,
                servo_end_deg: None,
                ranges_mm: vec![1001.0, 30.0, 0.0],
                intensities: vec![],
                geometry: None,
            },
        ];
        let mut out = Vec::new();
        write_scans(&mut out, &ScanHeader::URG_04LX, &scans).unwrap();
        let (h, v) = read_all(std::str::from_utf8(&out).unwrap()).unwrap();
        assert_eq!(h, ScanHeader::URG_04LX);
        assert_eq!(v.len(), 2);
        for (a, b) in scans.iter().zip(&v) {
            assert_eq!(a.ranges_mm, b.ranges_mm);
            assert_eq!(a.servo_deg, b.servo_deg);
        }
    }

    #[test]
    fn writer_puts_extra_lines_in_the_header_and_six_servo_decimals() {
        let mut out =
            ScanWriter::new(Vec::new(), &ScanHeader::URG_04LX, 2, &["sensor=test"]).unwrap();
        out.write_scan(0.1, -179.912109375, [1532u32, 0]).unwrap();
        out.write_scan(0.2, 0.087890625, [1531.4f64, 1529.6])
            .unwrap();
        let text = String::from_utf8(out.finish().unwrap()).unwrap();
        assert_eq!(
            text,
            "# pingcal-scan v1\n# angle_min_deg=-119.53125\n# angle_increment_deg=0.3515625\n\
             # range_unit=mm\n# sensor=test\nstamp_s,servo_deg,r0,r1\n\
             0.100,-179.912109,1532,0\n0.200,0.087891,1531,1530\n"
        );
        let (h, v) = read_all(&text).unwrap();
        assert_eq!(h, ScanHeader::URG_04LX);
        assert_eq!(v[0].ranges_mm, vec![1532.0, 0.0]);
    }

    #[test]
    fn v2_gives_each_beam_its_servo_angle_and_round_trips() {
        let scans = vec![ScanLine {
            line: 0,
            stamp_s: 0.1,
            servo_deg: 10.0,
            servo_end_deg: Some(12.0),
            ranges_mm: vec![1000.0, 0.0, 2500.0],
            intensities: vec![],
            geometry: None,
        }];
        let mut out = Vec::new();
        write_scans(&mut out, &ScanHeader::URG_04LX, &scans).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("# pingcal-scan v2\n"), "{text}");
        assert!(text.contains(
            "stamp_s,servo_deg,servo_end_deg,r0,r1,r2\n0.100,10.000000,12.000000,1000,0,2500\n"
        ));
        let (_, v) = read_all(&text).unwrap();
        assert_eq!(v[0].servo_end_deg, Some(12.0));
        assert_eq!(
            (0..3).map(|i| v[0].servo_deg_at(i)).collect::<Vec<_>>(),
            vec![10.0, 11.0, 12.0]
        );
        // v1 lines stand still
        let (_, v) = read_all(GOOD).unwrap();
        assert_eq!((v[0].servo_end_deg, v[0].servo_deg_at(2)), (None, -45.056));
    }

    #[test]
    fn v2_needs_its_column_and_other_versions_are_refused() {
        let v2 = GOOD.replace("v1", "v2");
        let e = read_all(&v2).unwrap_err().to_string();
        assert!(
            e.starts_with("t.csv:6: a v2 column line: expected `stamp_s,servo_deg,servo_end_deg"),
            "{e}"
        );
        let e = read_all(&GOOD.replace("v1", "v5")).unwrap_err().to_string();
        assert_eq!(
            e,
            "t.csv:1: pingcal-scan version \"5\": this pingcal reads v1, v2, v3 and v4"
        );
        let t = GOOD.replace("servo_deg,r0", "servo_deg,servo_end_deg,r0");
        let e = read_all(&t).unwrap_err().to_string();
        assert!(e.contains("needs `# pingcal-scan v2`"), "{e}");
        let mut w = ScanWriter::new(Vec::new(), &ScanHeader::URG_04LX, 1, &[]).unwrap();
        assert!(w.write_sweep_scan(0.0, 1.0, 2.0, [1000.0]).is_err());
    }

    #[test]
    fn v3_keeps_intensities_and_the_beam_time_and_round_trips() {
        let header = ScanHeader {
            time_increment_s: Some(0.1 / 1024.0),
            ..ScanHeader::URG_04LX
        };
        let scans = vec![ScanLine {
            line: 0,
            stamp_s: 0.1,
            servo_deg: 10.0,
            servo_end_deg: Some(10.0),
            ranges_mm: vec![1000.0, 0.0, 2500.0],
            intensities: vec![812.0, 0.0, 47.25],
            geometry: None,
        }];
        let mut out = Vec::new();
        write_scans(&mut out, &header, &scans).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("# pingcal-scan v3\n"), "{text}");
        assert!(
            text.contains("# time_increment_s=0.00009765625\n"),
            "{text}"
        );
        assert!(
            text.contains("stamp_s,servo_deg,servo_end_deg,r0,r1,r2,i0,i1,i2\n0.100,10.000000,10.000000,1000,0,2500,812,0,47.25\n"),
            "{text}"
        );
        let (h, v) = read_all(&text).unwrap();
        assert_eq!(h, header);
        assert_eq!(v[0].ranges_mm, scans[0].ranges_mm);
        assert_eq!(v[0].intensities, scans[0].intensities);
        // a v3 file without intensity columns reads as v2; v1 and v2 have none
        let (_, v) = read_all(&text.replace(",i0,i1,i2", "").replace(",812,0,47.25", "")).unwrap();
        assert!(v[0].intensities.is_empty());
        let (_, v) = read_all(GOOD).unwrap();
        assert!(v[0].intensities.is_empty());
        // intensity columns need v3, as many as the ranges, and numbers
        let e = read_all(&text.replace("v3", "v2")).unwrap_err().to_string();
        assert!(
            e.contains("intensity columns (i0, ...) need `# pingcal-scan v3`"),
            "{e}"
        );
        let e = read_all(&text.replace(",i2", "")).unwrap_err().to_string();
        assert!(e.contains("with 3 ranges and 2 intensities"), "{e}");
        let e = read_all(&text.replace(",47.25", ",x"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("intensity i2: expected a number, found \"x\""),
            "{e}"
        );
        let e = read_all(&text.replace(",47.25", ""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("expected 3 ranges and 3 intensities, found 5 values"),
            "{e}"
        );
        let e = read_all(&text.replace("time_increment_s=0.0", "time_increment_s=-0.0"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("time_increment_s: -0.00009765625 is negative"),
            "{e}"
        );
        // a v3 writer needs the intensities
        let mut w = ScanWriter::new_v3(Vec::new(), &header, 3, &[]).unwrap();
        assert!(w.write_scan(0.0, 1.0, [1000.0, 0.0, 1.0]).is_err());
    }

    /// v4: one file for scans of several geometries (and with or without intensities),
    /// written by `write_line_in` and read back scan by scan with its own geometry.
    #[test]
    fn v4_holds_scans_of_several_geometries_and_round_trips() {
        let a = ScanHeader {
            angle_min_deg: -10.0,
            angle_increment_deg: 10.0,
            mm_per_unit: 1.0,
            time_increment_s: Some(0.001),
        };
        let b = ScanHeader {
            angle_min_deg: -5.0,
            angle_increment_deg: 5.0,
            time_increment_s: Some(-0.002),
            ..a
        };
        let line = |k: usize, n: usize, with_i: bool| ScanLine {
            line: 0,
            stamp_s: 0.1 * k as f64,
            servo_deg: k as f64,
            servo_end_deg: Some(k as f64 + 0.5),
            ranges_mm: (0..n).map(|i| (1000 + 10 * k + i) as f64).collect(),
            intensities: if with_i { vec![7.0; n] } else { vec![] },
            geometry: None,
        };
        let scans = [
            (a, line(0, 3, false)),
            (a, line(1, 3, false)),
            (b, line(2, 4, true)),
            (a, line(3, 3, false)),
        ];
        let mut w = ScanWriter::new_v2(Vec::new(), &a, 3, &[]).unwrap();
        for (g, l) in &scans[..2] {
            w.write_line_in(g, l).unwrap();
        }
        assert!(!w.needs_v4(), "one geometry so far: still v2");
        for (g, l) in &scans[2..] {
            w.write_line_in(g, l).unwrap();
        }
        assert!(w.needs_v4());
        let mut text = String::from_utf8(w.finish().unwrap()).unwrap();
        text.replace_range(
            VERSION_DIGIT_OFFSET as usize..VERSION_DIGIT_OFFSET as usize + 1,
            "4",
        );
        assert!(text.starts_with("# pingcal-scan v4\n"), "{text}");
        assert!(
            text.contains("# geometry angle_min_deg=-5 angle_increment_deg=5 beams=4 time_increment_s=-0.002\n"),
            "{text}"
        );
        let (h, v) = read_all(&text).unwrap();
        assert_eq!(h, a);
        assert_eq!(v.len(), 4);
        for ((g, want), got) in scans.iter().zip(&v) {
            assert_eq!(got.geometry_or(&h), *g);
            assert_eq!(
                (&got.ranges_mm, &got.intensities),
                (&want.ranges_mm, &want.intensities)
            );
            assert_eq!(got.servo_end_deg, want.servo_end_deg);
        }
        // the same text under v3 is refused (the geometry line is a comment there, and the
        // counts differ), as an older pingcal refuses v4
        let e = read_all(&text.replacen("v4", "v3", 1))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("expected 3 ranges and 3 intensities") || e.contains("expected 3 ranges"),
            "{e}"
        );
        // a geometry line must be whole and describe a scan
        for (bad, want) in [
            (
                "beams=4 angle_min_deg=-5",
                "needs angle_min_deg=, angle_increment_deg= and beams=",
            ),
            (
                "angle_min_deg=-5 angle_increment_deg=200 beams=4",
                "spans 600°",
            ),
            (
                "angle_min_deg=-5 angle_increment_deg=5 beams=0",
                "beams: expected a whole number above 0",
            ),
            (
                "angle_min_deg=-5 angle_increment_deg=5 beams=4 colour=red",
                "unknown key \"colour\"",
            ),
        ] {
            let t = text.replace(
                "angle_min_deg=-5 angle_increment_deg=5 beams=4 time_increment_s=-0.002",
                bad,
            );
            let e = read_all(&t).unwrap_err().to_string();
            assert!(e.starts_with("t.csv:9: ") && e.contains(want), "{bad}: {e}");
        }
        // a scan of the wrong count in a section
        let t = text.replace("1020,1021,1022,1023,", "1020,1021,1022,");
        let e = read_all(&t).unwrap_err().to_string();
        assert!(
            e.contains("expected 4 ranges, or 4 ranges and 4 intensities, found 7 values"),
            "{e}"
        );
    }

    #[test]
    fn a_servo_column_in_radians_or_ranges_in_metres_are_told() {
        let slip = |text: &str| {
            let mut r = ScanReader::new(text.as_bytes(), "t.csv").unwrap();
            for l in r.by_ref() {
                l.unwrap();
            }
            r.unit_slip()
        };
        assert_eq!(slip(GOOD), None);
        let radians = GOOD
            .replace("-45.056", "-3.1416")
            .replace("-44.9", "3.1416");
        let e = slip(&radians).unwrap();
        assert!(
            e.starts_with("the servo angles span -3.14…3.14: radians?"),
            "{e}"
        );
        // a nod of a few degrees is degrees still when it spans less than π
        assert_eq!(
            slip(&GOOD.replace("-45.056", "-1.5").replace("-44.9", "1.5")),
            None
        );
        let metres = GOOD
            .replace("1532,1530,0", "1.532,1.53,0")
            .replace("1531,7,1529", "5.6,0.007,1.529");
        let e = slip(&metres).unwrap();
        assert_eq!(
            e,
            "every range is under 20 mm, the largest 5.6: metres? the file says range_unit=mm; write # range_unit=m or the ranges in mm"
        );
        // the file's check names it
        let mut r = ScanReader::new(metres.as_bytes(), "t.csv").unwrap();
        for l in r.by_ref() {
            l.unwrap();
        }
        assert!(check_units(&r)
            .unwrap_err()
            .to_string()
            .starts_with("t.csv: every range"));
    }

    #[test]
    fn a_last_line_without_a_line_break_is_refused_naming_it() {
        let cut = &GOOD[..GOOD.len() - 3];
        let e = read_all(cut).unwrap_err().to_string();
        assert!(
            e.starts_with("t.csv:8: the last line does not end with a line break"),
            "{e}"
        );
        // trailing blanks without a line break are no data
        assert_eq!(read_all(&format!("{GOOD}  ")).unwrap().1.len(), 2);
    }
}
