//! Issue 14, "nothing silent": each reader of this crate (BAL, the measurement JSON with
//! its checks, DBAT's mark-point, control and camera files) gets valid files mutated the ways real
//! files go wrong — a line duplicated, data appended, the file cut short, a UTF-8
//! byte-order mark in front, a number made huge — 1,000 cases each. Every mutation is
//! either refused with an error naming the file, or read with the result the mutated text
//! legally means:
//!
//! * a byte-order mark, a trailing comment or blank: the same result as the clean file;
//! * a duplicated line: refused (a point measured twice, an id given twice, a BAL value
//!   shifted), except a comment and, in the JSON, a distance (measured twice: a legal
//!   repeated measurement, read as two distances);
//! * a cut: refused where the format is closed (JSON, BAL, DBAT's camera XML); in DBAT's line files, which
//!   have no counts, a prefix of the clean result whose last record may be cut short;
//! * a huge number (1e300): refused.
//!
//! The mutations, applying them and the checks every reader shares are
//! `pingcal_testkit::mutations` (pingcal-lrf's readers use the same harness).

use pingcal_ba::bal::{parse_bal, write_bal};
use pingcal_ba::io::dbat::{parse_camera, parse_control, parse_markpts, DbatControl};
use pingcal_ba::io::measurements::Measurements;
use pingcal_testkit::mutations::{
    apply, duplicated_line, mutation, prefix_ok, refused_well, whole_after_cut, Mutation, Numbers,
};
use proptest::prelude::*;

/// The lines appended to every file: blank lines (legal), and a pair, a word, a closing
/// brace and a lone number that a reader might take for data.
const APPENDED: [&str; 5] = ["\n \n", "1 2\n", "abc\n", "}\n", "7\n"];

/// The numbers of DBAT's line files: the fields after the two ids, in the lines that are
/// not comments.
const DBAT_VALUES: Numbers = Numbers::Fields {
    data_line: |l| !l.starts_with('#'),
    separators: &[','],
    first: 2,
};

const BAL: &str = "2 2 3\n0 0 1.0 2.0\n1 0 -1.0 0.5\n1 1 3.0 -2.0\n\
    0.1\n0.2\n0.3\n1\n2\n3\n500\n0.01\n0.001\n\
    0\n0\n0\n0\n0\n-5\n600\n0\n0\n\
    1 2 -10\n0.5 0.5 -12\n";

fn bal(text: &str) -> Result<String, String> {
    let p = parse_bal(text.as_bytes(), "f.bal").map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    write_bal(&p, &mut out).unwrap();
    Ok(String::from_utf8(out).unwrap())
}

const JSON: &str = r#"{
  "format": "pingcal-measurements v1",
  "cameras": [
    {"name": "left", "model": "photogrammetric", "width": 1280, "height": 720, "pixel_size_mm": 0.00375, "intrinsics": {"c": 2.45, "xp": 0.0, "K1": 0.0}, "calibrate": ["c", "xp"]}
  ],
  "images": [
    {"name": "main", "camera": "left", "pose": {"centre": [0, 0, 0], "omega_phi_kappa_deg": [0, 0, 0]}, "fixed": true},
    {"name": "st02", "camera": "left"}
  ],
  "image_points": [
    {"image": "main", "point": "17", "x": 640.25, "y": 355.5, "sigma_px": 0.05},
    {"image": "main", "point": "18", "x": 600.25, "y": 305.5, "sigma_px": 0.05},
    {"image": "st02", "point": "17", "x": 512.0, "y": 300.75, "sigma_px": 0.05},
    {"image": "st02", "point": "18", "x": 502.0, "y": 310.75, "sigma_px": 0.05}
  ],
  "distances": [
    {"a": "17", "b": "18", "mm": 1000.12, "sigma_mm": 0.05},
    {"a": "18", "b": "19", "mm": 500.5, "sigma_mm": 0.05}
  ],
  "control_points": [
    {"id": "17", "xyz": [0, 2000, 0], "fixed": true},
    {"id": "18", "xyz": [1000, 2000, 0], "sigma_mm": [0.1, 0.1, 0.1]},
    {"id": "19", "xyz": [0, 2500, 300]}
  ]
}
"#;

/// The file as `pingcal ba` takes it: parsed and checked, errors naming the file.
fn measurements(text: &str) -> Result<Measurements, String> {
    let m = Measurements::parse(text, "m.json").map_err(|e| e.to_string())?;
    m.to_problem()
        .map_err(|e| e.in_file("m.json").to_string())?;
    Ok(m)
}

const MARKS: &str = "# Mark points\n 1, 2, 1429.1871, 1456.4278, 0.1\n 1, 1001, 10.5, 20.5, 0.1\n 2, 2, 100, 200, 0.2\n 2, 1001, 110, 210, 0.2\n";

const CONTROL: &str = "# Id,label,X,Y,Z,sxyz\n1001,CP1,0,1,0\n1002,CP2,1,1,0,0.001\n1003,CP3,1,2,0,0.001,0.001,0.002\n";

/// DBAT's camera XML as its `camcaldemo` gives the camera (sensor width `auto`); every line
/// is different, so that a duplicated line is an element given twice or broken XML.
const CAMERA: &str = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<document dbat_camera_version=\"1.0\">\n  <cameras>\n    <camera>\n      <id>1</id>\n      <name>Olympus Camedia C4040Z</name>\n      <unit>mm</unit>\n      <sensor>auto,5.43764</sensor>\n      <image>2272,1704</image>\n      <aspect>1</aspect>\n      <focal>7.5</focal>\n    </camera>\n  </cameras>\n</document>\n";

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn bal_files(m in mutation(APPENDED)) {
        let text = apply(BAL, &m, &Numbers::Tokens);
        let clean = bal(BAL).unwrap();
        match bal(&text) {
            Err(e) => refused_well("f.bal", &m, &e)?,
            Ok(got) => {
                let blank = m.appends_blank();
                // A cut inside the last value leaves a shorter number: the one cut BAL
                // cannot tell.
                let last_value = matches!(m, Mutation::Cut(k) if k % BAL.len() > BAL.len() - 4);
                prop_assert!(
                    matches!(m, Mutation::Bom) || blank || last_value || whole_after_cut(BAL, &m),
                    "accepted: {:?}", m
                );
                if !last_value {
                    prop_assert_eq!(got, clean);
                }
            }
        }
    }

    #[test]
    fn measurement_json(m in mutation(APPENDED)) {
        let text = apply(JSON, &m, &Numbers::Tokens);
        let clean = measurements(JSON).unwrap();
        match measurements(&text) {
            Err(e) => refused_well("m.json", &m, &e)?,
            Ok(got) => {
                let line = duplicated_line(JSON, &m);
                let blank = m.appends_blank();
                if line.contains("\"mm\":") {
                    // A distance measured twice: read as two.
                    prop_assert_eq!(got.distances.len(), clean.distances.len() + 1);
                } else {
                    prop_assert!(
                        matches!(m, Mutation::Bom) || blank || whole_after_cut(JSON, &m),
                        "accepted: {:?}", m
                    );
                    prop_assert_eq!(got, clean);
                }
            }
        }
    }

    #[test]
    fn dbat_mark_points(m in mutation(APPENDED)) {
        let text = apply(MARKS, &m, &DBAT_VALUES);
        let clean = parse_markpts(MARKS, "markpts.txt").unwrap();
        match parse_markpts(&text, "markpts.txt") {
            Err(e) => refused_well("markpts.txt", &m, &e.to_string())?,
            Ok(got) => match m {
                Mutation::Cut(_) => prefix_ok(&got, &clean)?,
                _ => {
                    let comment = duplicated_line(MARKS, &m).starts_with('#');
                    let blank = m.appends_blank();
                    prop_assert!(matches!(m, Mutation::Bom) || comment || blank, "accepted: {:?}", m);
                    prop_assert_eq!(got, clean);
                }
            },
        }
    }

    #[test]
    fn dbat_control_points(m in mutation(APPENDED)) {
        let text = apply(CONTROL, &m, &DBAT_VALUES);
        let clean = parse_control(CONTROL, "control.txt").unwrap();
        match parse_control(&text, "control.txt") {
            Err(e) => refused_well("control.txt", &m, &e.to_string())?,
            Ok(got) => match m {
                Mutation::Cut(_) => prefix_ok(&got, &clean)?,
                _ => {
                    let comment = duplicated_line(CONTROL, &m).starts_with('#');
                    let blank = m.appends_blank();
                    prop_assert!(matches!(m, Mutation::Bom) || comment || blank, "accepted: {:?}", m);
                    // a duplicated comment moves the lines after it: the values must not move
                    let values = |v: Vec<DbatControl>| -> Vec<DbatControl> {
                        v.into_iter().map(|c| DbatControl { line: 0, ..c }).collect()
                    };
                    prop_assert_eq!(values(got), values(clean));
                }
            },
        }
    }

    #[test]
    fn dbat_camera_files(m in mutation(APPENDED)) {
        let text = apply(CAMERA, &m, &Numbers::Tokens);
        let clean = parse_camera(CAMERA, "camera.xml").unwrap();
        match parse_camera(&text, "camera.xml") {
            Err(e) => {
                let e = e.to_string();
                refused_well("camera.xml", &m, &e)?;
                prop_assert!(!e.contains('\n'), "not one line: {}", e);
            }
            Ok(got) => {
                let blank = m.appends_blank();
                prop_assert!(
                    matches!(m, Mutation::Bom) || blank || whole_after_cut(CAMERA, &m),
                    "accepted: {:?}", m
                );
                prop_assert_eq!(got, clean);
            }
        }
    }
}
