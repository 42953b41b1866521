//! Issue 39's fuzz harness: valid inputs of every reader, mutated the ways real files go
//! wrong, each case run with a time limit; it counts per reader the cases, the panics, the
//! hangs (a case over [`LIMIT`]) and the silent acceptances — a mutated input read without
//! an error or a note (a masked range) into another result than the clean input's, where
//! the mutation can have no legal meaning:
//!
//! - a number made absurd (1e308, −1e308, 1e300, NaN, inf);
//! - junk appended (`%%junk%%`): no format has it as data or comment;
//! - a line duplicated, or removed, or the file cut short, in a format that counts its items
//!   or is complete in itself (see [`Strict`]): PLY, PCD, BAL, JSON, an image;
//! - a UTF-8 byte-order mark in front of a text file (read as the clean file, or refused).
//!
//! Other mutations — a byte flipped, inserted or removed, a binary field set to 0 or to its
//! largest value, a number made large but possible (999,999, 1e6, −1, 1e-300) — are judged
//! for panics and hangs only. A scan is also made into a cloud and its balls searched, so
//! that a value that blows up the search's time is a hang.
//!
//! The short form (in CI: `cargo test --release -p pingcal --test cli cli_safety::fuzz`) runs
//! [`SHORT_CASES`] cases per reader; `PINGCAL_FUZZ_CASES=3000` runs that many (minutes), and
//! `PINGCAL_FUZZ_SEED` another sequence. The table is printed with `--nocapture`.

use pingcal_ba::io::dbat;
use pingcal_ba::io::measurements::Measurements;
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::scan::{ScanHeader, ScanReader};
use rand::Rng;
use std::sync::mpsc;
use std::time::Duration;

/// Cases per reader of the short form.
pub const SHORT_CASES: usize = 40;

/// A case that takes longer is a hang.
pub const LIMIT: Duration = Duration::from_secs(5);

/// What a reader made of an input: refused (the message) or read.
type Outcome = Result<Read, String>;

/// An input read: a digest to compare with the clean input's, and whether the reader said
/// something about it (ranges masked, warnings).
#[derive(Clone, Debug, PartialEq)]
struct Read {
    digest: String,
    noted: bool,
}

impl Read {
    fn of(digest: impl std::fmt::Debug) -> Outcome {
        Ok(Read {
            digest: format!("{digest:?}"),
            noted: false,
        })
    }
}

/// Which mutations an accepted input must have read as the clean one.
#[derive(Clone, Copy)]
struct Strict {
    /// A line duplicated (a data line repeated is refused by the format).
    dup: bool,
    /// A line removed, or the file cut short (the format counts its items or is complete).
    cut: bool,
}

/// One reader under test.
struct Reader {
    name: &'static str,
    seed: Vec<u8>,
    /// Text: the text mutations apply, and junk appended must be refused (binary formats
    /// whose header counts their data, PLY and PCD, refuse it too; an image or a bag may
    /// carry bytes after its end).
    text: bool,
    strict: Strict,
    /// Leading columns of a line that are ids (text: any token, 1e308 included, is legal).
    ids: usize,
    /// A NaN coordinate is legal (PCD: no return, the point dropped).
    nan_legal: bool,
    read: fn(&[u8]) -> Outcome,
}

const FILE: &str = "fuzz-input";

fn text(b: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(b).map_err(|_| format!("{FILE}: not UTF-8"))
}

fn scan(b: &[u8]) -> Outcome {
    let mut r = ScanReader::new(b, FILE).map_err(|e| e.to_string())?;
    let header = r.header();
    let lines = r
        .by_ref()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    let cloud = Cloud::from_scans(
        &header,
        lines.iter().cloned().map(Ok),
        &MountModel::default(),
    )
    .map_err(|e| e.to_string())?;
    // the search whose time one value could blow up
    let found = find_balls(&cloud, &FinderOptions::default());
    let digest: Vec<(f64, f64, &Vec<f64>)> = lines
        .iter()
        .map(|l| (l.stamp_s, l.servo_deg, &l.ranges_mm))
        .collect();
    Ok(Read {
        digest: format!("{header:?} {digest:?} {}", found.balls.len()),
        noted: r.masked().count > 0,
    })
}

fn cloud_points(c: pingcal_lrf::Cloud) -> Vec<[f64; 3]> {
    c.points.iter().map(|p| [p.x, p.y, p.z]).collect()
}

fn ply(b: &[u8]) -> Outcome {
    let c = pingcal_lrf::ply::read_ply(b, FILE).map_err(|e| e.to_string())?;
    Read::of(cloud_points(c))
}

fn pcd(b: &[u8]) -> Outcome {
    let c = pingcal_lrf::pcd::read_pcd(b, FILE).map_err(|e| e.to_string())?;
    Read::of(cloud_points(c))
}

fn xyz(b: &[u8]) -> Outcome {
    let c = pingcal_lrf::xyz::read_xyz(b, FILE).map_err(|e| e.to_string())?;
    Read::of(cloud_points(c))
}

fn labelled(b: &[u8]) -> Outcome {
    let v = pingcal_lrf::xyz::read_labelled(b, FILE).map_err(|e| e.to_string())?;
    Read::of(v)
}

fn bal(b: &[u8]) -> Outcome {
    let p = pingcal_ba::bal::parse_bal(b, FILE).map_err(|e| e.to_string())?;
    Read::of(p)
}

fn measurements(b: &[u8]) -> Outcome {
    let mut m = Measurements::parse(text(b)?, FILE).map_err(|e| e.to_string())?;
    let built = m.to_problem().map_err(|e| format!("{FILE}: {e}"))?;
    // the format line is optional: without it, the same measurements
    m.format = None;
    Ok(Read {
        digest: format!("{m:?}"),
        noted: !built.warnings.is_empty(),
    })
}

fn markpts(b: &[u8]) -> Outcome {
    Read::of(dbat::parse_markpts(text(b)?, FILE).map_err(|e| e.to_string())?)
}

fn control(b: &[u8]) -> Outcome {
    let c = dbat::parse_control(text(b)?, FILE).map_err(|e| e.to_string())?;
    // the line numbers left out: a comment line repeated moves them, legally
    let v: Vec<_> = c
        .iter()
        .map(|c| (&c.id, &c.label, c.xyz, c.sigma))
        .collect();
    Read::of(v)
}

fn dbat_camera(b: &[u8]) -> Outcome {
    Read::of(dbat::parse_camera(text(b)?, FILE).map_err(|e| e.to_string())?)
}

fn project(b: &[u8]) -> Outcome {
    let p = pingcal_project::ProjectFile::parse(text(b)?, FILE).map_err(|e| e.to_string())?;
    // what `pingcal calibrate` checks up front beyond the files it names (the mount too)
    p.validate(FILE).map_err(|e| e.to_string())?;
    Read::of(p)
}

fn image(b: &[u8]) -> Outcome {
    let g = pingcal_targets::decode_image(b, FILE).map_err(|e| e.to_string())?;
    let sum: f64 = g.data.iter().map(|&v| f64::from(v)).sum();
    Read::of((g.width, g.height, sum))
}

fn bag(b: &[u8]) -> Outcome {
    // the reader maps a file: each case writes its bytes to one
    let path = std::env::temp_dir().join(format!(
        "pingcal-{FILE}-{}-{:?}.bag",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::write(&path, b).map_err(|e| e.to_string())?;
    let r = (|| {
        let bag = pingcal_rosbag::Bag::open(&path).map_err(|e| e.to_string())?;
        let topics = bag.topics().map_err(|e| e.to_string())?;
        let names: Vec<&str> = topics.iter().map(|t| t.name.as_str()).collect();
        let mut n = 0usize;
        bag.for_each(&names, &mut |m| {
            n += m.data.len();
            Ok(())
        })
        .map_err(|e| e.to_string())?;
        Read::of((topics, n))
    })();
    let _ = std::fs::remove_file(&path);
    r
}

/// The valid inputs the mutations start from, all made here (no file of ../shared needed).
fn readers() -> Vec<Reader> {
    let strict = Strict {
        dup: true,
        cut: true,
    };
    let loose = Strict {
        dup: false,
        cut: false,
    };
    let mut v = vec![
        Reader {
            name: "scan CSV",
            seed: scan_seed(),
            text: true,
            // a repeated scan is refused; fewer scans, or a cut, are legal
            strict: Strict {
                dup: true,
                cut: false,
            },
            read: scan,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "PLY ascii",
            seed: "ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n1 2 3 9\n4 5 6 9\n7 8 9 9\n10 11 12 9\n3 0 1 2\n".into(),
            text: true,
            strict,
            read: ply,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "PLY binary",
            seed: ply_binary_seed(),
            text: false,
            strict,
            read: ply,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "PCD ascii",
            seed: "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n1 2 3 0\n4 5 6 0\n7 8 9 0\n10 11 12 0\n".into(),
            text: true,
            strict,
            read: pcd,
            ids: 0,
            nan_legal: true,
        },
        Reader {
            name: "PCD binary",
            seed: pcd_binary_seed(),
            text: false,
            strict,
            read: pcd,
            ids: 0,
            nan_legal: true,
        },
        Reader {
            name: "XYZ",
            seed: "# cloud\n1 2 3\n4,5,6, 255 0 0\n7\t8\t9\n-10 11.5 12\n".into(),
            text: true,
            strict: loose,
            read: xyz,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "register points",
            seed: "# id x y z sx sy sz\nB1 1 2 3\nB2, 4, 5, 6, 0.5, 0.5, 1\nB3 7 8 9\nB4 -1 0 2.5\n".into(),
            text: true,
            strict: Strict {
                dup: true,
                cut: false,
            },
            read: labelled,
            ids: 1,
            nan_legal: false,
        },
        Reader {
            name: "BAL",
            seed: bal_seed(),
            text: true,
            strict,
            read: bal,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "measurement JSON",
            seed: measurement_seed(),
            text: true,
            strict,
            read: measurements,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "DBAT mark points",
            seed: MARKS.into(),
            text: true,
            strict: Strict {
                dup: true,
                cut: false,
            },
            read: markpts,
            ids: 2,
            nan_legal: false,
        },
        Reader {
            name: "DBAT control",
            seed: "# Id,label,X,Y,Z\n1001,CP1,0,1,0\n1002,CP2,1,1,0\n1003,CP3,0,0,0\n1004,CP4,1,0,0,0.001,0.002,0.003\n".into(),
            text: true,
            strict: Strict {
                dup: true,
                cut: false,
            },
            read: control,
            ids: 1,
            nan_legal: false,
        },
        Reader {
            name: "DBAT camera",
            seed: "<document dbat_camera_version=\"1.0\">\n<cameras>\n<camera>\n<name>cam</name>\n<sensor>auto,4.8</sensor>\n<image>1600,1200</image>\n<focal>8.5</focal>\n</camera>\n</cameras>\n</document>\n".into(),
            text: true,
            strict: loose,
            read: dbat_camera,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "project.toml",
            seed: readme_project().into_bytes(),
            text: true,
            strict: Strict {
                dup: true,
                cut: false,
            },
            read: project,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "PNG",
            seed: png_seed(),
            text: false,
            strict,
            read: image,
            ids: 0,
            nan_legal: false,
        },
        Reader {
            name: "TIFF",
            seed: tiff_seed(),
            text: false,
            strict,
            read: image,
            ids: 0,
            nan_legal: false,
        },
    ];
    let bag =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../rosbag/tests/data/ros1.bag");
    if let Ok(seed) = std::fs::read(&bag) {
        v.push(Reader {
            name: "ROS 1 bag",
            seed,
            text: false,
            strict: loose,
            read: bag_read,
            ids: 0,
            nan_legal: false,
        });
    }
    v
}

fn bag_read(b: &[u8]) -> Outcome {
    bag(b)
}

const MARKS: &str = "# Mark points\n# image id, point id, x, y, sxy\n1, 1, 100.5, 200.5, 0.1\n1, 2, 300, 220, 0.1\n1, 3, 500.25, 410, 0.1\n2, 1, 120, 205, 0.1\n2, 2, 310, 230, 0.1\n2, 3, 520, 400, 0.2\n";

/// The documented example project file (it was the README's): docs/project.md's first
/// ```toml block.
fn readme_project() -> String {
    let doc = include_str!("../../docs/project.md");
    let start = doc.find("```toml").expect("a toml block") + "```toml".len();
    let end = doc[start..].find("```").expect("the block's end") + start;
    doc[start..end].trim_start().to_string()
}

fn scan_seed() -> Vec<u8> {
    let mut rng = pingcal_geometry::consensus::rng(5);
    let scene = pingcal_lrf::simulate::room_corner_scene(3, &mut rng);
    let lrf = pingcal_lrf::simulate::SimulatedLrf::default();
    let scans = scene.half_sweep(24, &lrf, &mut rng);
    let mut out = Vec::new();
    pingcal_lrf::scan::write_scans(&mut out, &ScanHeader::URG_04LX, &scans).unwrap();
    out
}

fn ply_binary_seed() -> Vec<u8> {
    let pts: Vec<pingcal_lrf::nalgebra::Vector3<f64>> = (0..6)
        .map(|i| pingcal_lrf::nalgebra::Vector3::new(i as f64, -2.0 * i as f64, 1000.0))
        .collect();
    let mut out = Vec::new();
    pingcal_lrf::ply::write_ply(&mut out, &pts, &[[1, 2, 3]; 6], &["fuzz".into()]).unwrap();
    out
}

fn pcd_binary_seed() -> Vec<u8> {
    let mut b = b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\nHEIGHT 1\nPOINTS 5\nDATA binary\n".to_vec();
    for i in 0..15 {
        b.extend_from_slice(&(i as f32 * 0.25).to_le_bytes());
    }
    b
}

fn bal_seed() -> Vec<u8> {
    let s = pingcal_ba::synthetic::SyntheticBal {
        cameras: 4,
        points: 12,
        obs_per_point: 3,
        seed: 2,
        ..Default::default()
    }
    .generate()
    .unwrap();
    let mut out = Vec::new();
    pingcal_ba::bal::write_bal(&s.problem, &mut out).unwrap();
    out
}

fn measurement_seed() -> Vec<u8> {
    let marks = dbat::parse_markpts(MARKS, "m").unwrap();
    let ctrl = dbat::parse_control("1,a,0,0,0\n2,b,1,0,0\n3,c,0,1,0\n", "c").unwrap();
    let m = dbat::to_measurements(&marks, &ctrl, &dbat::DbatCamera::c4040z(), 1000.0);
    m.to_json().into_bytes()
}

fn png_seed() -> Vec<u8> {
    let (w, h) = (48u32, 32u32);
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, w, h);
    e.set_color(png::ColorType::Grayscale);
    e.set_depth(png::BitDepth::Eight);
    let mut wr = e.write_header().unwrap();
    let data: Vec<u8> = (0..w * h).map(|k| ((k * 7) % 251) as u8).collect();
    wr.write_image_data(&data).unwrap();
    drop(wr);
    out
}

fn tiff_seed() -> Vec<u8> {
    crate::common::grey_tiff(40, 30, 8 + 2 + 12 * 9 + 4, 253)
}

/// One way an input goes wrong.
#[derive(Clone, Debug)]
enum Mutation {
    Bom,
    DuplicateLine(usize),
    DeleteLine(usize),
    Cut(usize),
    AppendJunk,
    /// The k-th number of the text replaced by an absurd value (judged) …
    Absurd(usize, &'static str),
    /// … or by a large but possible one (time only).
    Extreme(usize, &'static str),
    FlipByte(usize, u8),
    InsertByte(usize, u8),
    DeleteByte(usize),
    /// Bytes k..k+4 (within the first 256) set to all 0 or all 0xFF.
    Field(usize, u8),
}

const ABSURD: [&str; 5] = ["1e308", "-1e308", "1e300", "nan", "inf"];
const EXTREME: [&str; 5] = ["999999", "1000000", "-1", "1e-300", "0"];

fn mutation(rng: &mut impl Rng, text: bool) -> Mutation {
    let k = rng.random_range(0..usize::MAX / 2);
    let byte = rng.random_range(1..=255u8);
    let pick = if text {
        rng.random_range(0..10)
    } else {
        rng.random_range(5..10)
    };
    match pick {
        0 => Mutation::Bom,
        1 => Mutation::DuplicateLine(k),
        2 => Mutation::DeleteLine(k),
        3 => Mutation::Absurd(k, ABSURD[k % ABSURD.len()]),
        4 => Mutation::Extreme(k, EXTREME[k % EXTREME.len()]),
        5 => Mutation::Cut(k),
        6 => Mutation::AppendJunk,
        7 => Mutation::FlipByte(k, byte),
        8 => match rng.random_range(0..2) {
            0 => Mutation::InsertByte(k, byte),
            _ => Mutation::DeleteByte(k),
        },
        _ => Mutation::Field(k % 256, if byte % 2 == 0 { 0 } else { 0xFF }),
    }
}

/// Byte ranges of the number tokens of `s`.
fn numbers(s: &str, ids: usize) -> Vec<std::ops::Range<usize>> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts =
            b[i].is_ascii_digit() || (b[i] == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        let after_word = i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_');
        if starts && !after_word {
            let j = (i + 1..b.len())
                .find(|&j| {
                    !(b[j].is_ascii_digit() || matches!(b[j], b'.' | b'e' | b'E' | b'-' | b'+'))
                })
                .unwrap_or(b.len());
            let line = s[..i].rfind('\n').map_or(0, |l| l + 1);
            let quoted = s[line..i].matches('"').count() % 2 == 1;
            let column = s[line..i]
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|t| !t.is_empty())
                .count();
            if column >= ids
                && !quoted
                && (j == b.len() || !(b[j].is_ascii_alphabetic() || b[j] == b'_'))
            {
                out.push(i..j);
            }
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

/// `seed` mutated by `m`; `None` where the mutation does not apply (no number to replace).
fn apply(seed: &[u8], m: &Mutation, ids: usize) -> Option<Vec<u8>> {
    let n = seed.len();
    let lines = || -> Vec<&[u8]> { seed.split_inclusive(|&b| b == b'\n').collect() };
    Some(match m {
        Mutation::Bom => [&[0xEF, 0xBB, 0xBF][..], seed].concat(),
        Mutation::DuplicateLine(k) | Mutation::DeleteLine(k) => {
            let l = lines();
            let k = k % l.len();
            let mut v: Vec<&[u8]> = l.clone();
            if matches!(m, Mutation::DeleteLine(_)) {
                v.remove(k);
            } else {
                v.insert(k, l[k]);
            }
            v.concat()
        }
        Mutation::Cut(k) => seed[..k % n].to_vec(),
        Mutation::AppendJunk => [seed, b"%%junk%%\n"].concat(),
        Mutation::Absurd(k, v) | Mutation::Extreme(k, v) => {
            let s = std::str::from_utf8(seed).ok()?;
            let spots = numbers(s, ids);
            if spots.is_empty() {
                return None;
            }
            let r = spots[k % spots.len()].clone();
            [&seed[..r.start], v.as_bytes(), &seed[r.end..]].concat()
        }
        Mutation::FlipByte(k, x) => {
            let mut v = seed.to_vec();
            v[k % n] ^= x;
            v
        }
        Mutation::InsertByte(k, x) => {
            let mut v = seed.to_vec();
            v.insert(k % (n + 1), *x);
            v
        }
        Mutation::DeleteByte(k) => {
            let mut v = seed.to_vec();
            v.remove(k % n);
            v
        }
        Mutation::Field(k, x) => {
            let mut v = seed.to_vec();
            let at = k % n.min(256);
            for b in v.iter_mut().skip(at).take(4) {
                *b = *x;
            }
            v
        }
    })
}

/// The first line (text) or byte offset (binary) where `input` differs from `seed`.
fn first_change(seed: &[u8], input: &[u8]) -> String {
    let at = seed
        .iter()
        .zip(input)
        .position(|(a, b)| a != b)
        .unwrap_or(seed.len().min(input.len()));
    match (std::str::from_utf8(seed), std::str::from_utf8(input)) {
        (Ok(_), Ok(t)) => {
            let line = t[..at.min(t.len())].matches('\n').count();
            format!(
                "line {}: {:?}",
                line + 1,
                t.lines()
                    .nth(line)
                    .unwrap_or("")
                    .chars()
                    .take(80)
                    .collect::<String>()
            )
        }
        _ => format!("byte {at}"),
    }
}

/// How one case ended.
enum Verdict {
    Fine,
    Panic(String),
    Hang,
    Silent(String),
    Unnamed(String),
}

/// Runs `read` on `input` in a thread of its own, at most [`LIMIT`].
fn run(read: fn(&[u8]) -> Outcome, input: Vec<u8>) -> Result<Outcome, Verdict> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(|| read(&input));
        let _ = tx.send(r);
    });
    match rx.recv_timeout(LIMIT) {
        Ok(Ok(o)) => Ok(o),
        Ok(Err(p)) => Err(Verdict::Panic(
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default(),
        )),
        Err(_) => Err(Verdict::Hang),
    }
}

/// The verdict on a case (see the module doc).
fn judge(r: &Reader, clean: &Read, m: &Mutation, got: Outcome) -> Verdict {
    let read = match got {
        Err(e) if !e.contains(FILE) => return Verdict::Unnamed(e),
        Err(_) => return Verdict::Fine,
        Ok(read) => read,
    };
    let same = read.digest == clean.digest;
    let must_be_same = match m {
        Mutation::Bom => r.text,
        Mutation::AppendJunk if r.text || r.name.starts_with("P") && !r.name.starts_with("PNG") => {
            return Verdict::Silent("junk appended was read without a word".into())
        }
        Mutation::Absurd(_, v) => !(read.noted || r.nan_legal && *v == "nan"),
        Mutation::DuplicateLine(_) => r.strict.dup,
        Mutation::DeleteLine(_) => r.strict.cut,
        // a cut inside the last line may leave a shorter last number, which no count shows
        Mutation::Cut(k) => {
            let at = k % r.seed.len();
            let last = r.seed[..r.seed.len() - 1]
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |l| l + 1);
            r.strict.cut && !(r.text && at > last)
        }
        _ => false,
    };
    if must_be_same && !same {
        Verdict::Silent(format!(
            "read into another result than the clean input's ({m:?})"
        ))
    } else {
        Verdict::Fine
    }
}

/// The counts of one reader.
#[derive(Default, Debug)]
pub struct Tally {
    pub cases: usize,
    pub panics: usize,
    pub hangs: usize,
    pub silent: usize,
    pub unnamed: usize,
    pub refused: usize,
    pub examples: Vec<String>,
}

/// Runs `cases` mutations of every reader from `seed`: the tally of each, by name.
pub fn fuzz(cases: usize, seed: u64) -> Vec<(&'static str, Tally)> {
    let mut out = Vec::new();
    for (ri, r) in readers().into_iter().enumerate() {
        let clean = match (r.read)(&r.seed) {
            Ok(c) => c,
            Err(e) => panic!("{}: the clean input is refused: {e}", r.name),
        };
        let mut rng = pingcal_geometry::consensus::rng_stream(seed, ri as u64);
        let mut t = Tally::default();
        while t.cases < cases {
            let m = mutation(&mut rng, r.text);
            let Some(input) = apply(&r.seed, &m, r.ids) else {
                continue;
            };
            t.cases += 1;
            let changed = first_change(&r.seed, &input);
            let v = match run(r.read, input) {
                Ok(got) => {
                    if got.is_err() {
                        t.refused += 1;
                    }
                    judge(&r, &clean, &m, got)
                }
                Err(v) => v,
            };
            let note = |what: &str, detail: &str| {
                format!("{}: {what} on {m:?}: {detail} [{changed}]", r.name)
            };
            match v {
                Verdict::Fine => {}
                Verdict::Panic(p) => {
                    t.panics += 1;
                    t.examples.push(note("panic", &p));
                }
                Verdict::Hang => {
                    t.hangs += 1;
                    t.examples.push(note("hang", &format!("over {LIMIT:?}")));
                }
                Verdict::Silent(why) => {
                    t.silent += 1;
                    t.examples.push(note("silent", &why));
                }
                Verdict::Unnamed(e) => {
                    t.unnamed += 1;
                    t.examples.push(note("error not naming the file", &e));
                }
            }
        }
        out.push((r.name, t));
    }
    out
}

/// The table of a run, one line per reader.
pub fn table(tallies: &[(&str, Tally)]) -> String {
    let mut s = format!(
        "{:<18} {:>6} {:>7} {:>6} {:>7} {:>8} {:>8}\n",
        "reader", "cases", "panics", "hangs", "silent", "unnamed", "refused"
    );
    for (name, t) in tallies {
        s += &format!(
            "{name:<18} {:>6} {:>7} {:>6} {:>7} {:>8} {:>8}\n",
            t.cases, t.panics, t.hangs, t.silent, t.unnamed, t.refused
        );
    }
    s
}
