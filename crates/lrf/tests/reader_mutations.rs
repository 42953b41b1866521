//! Issue 14, "nothing silent": each text and binary reader of this crate (scan CSV, XYZ,
//! labelled points, PLY) gets valid files mutated the ways real files go wrong — a line
//! duplicated, data appended, the file cut short, a UTF-8 byte-order mark in front, a
//! number made huge — 1,000 cases each. Every mutation is either refused with an error
//! naming the file, or read with the result the mutated text legally means:
//!
//! * a byte-order mark or a trailing comment: the same result as the clean file;
//! * a duplicated line of XYZ, a format without counts: that line read twice, nothing
//!   shifted (a scan CSV refuses a scan that repeats the previous one, labelled points
//!   refuse the repeated id; PLY, whose header counts the vertices, refuses the extra line);
//! * a cut of a format without counts: a prefix of the clean result whose last item may be
//!   cut short (PLY refuses any cut);
//! * a huge number (1e300) or a non-number: refused; in a scan's range, masked as no
//!   return and counted (issue 39).
//!
//! The mutations, applying them and the checks every reader shares are
//! `pingcal_testkit::mutations` (pingcal-ba's readers use the same harness).

use pingcal_lrf::scan::{ScanLine, ScanReader};
use pingcal_lrf::xyz::{read_labelled, read_xyz, LabelledPoint};
use pingcal_testkit::mutations::{apply, mutation, prefix_ok, refused_well, Mutation, Numbers};
use proptest::prelude::*;

/// The lines appended to every file: a comment (legal), and a pair, a word, a field that
/// is not a number and a line of NaNs that a reader might take for data.
const APPENDED: [&str; 5] = [
    "# a comment\n",
    "1 2\n",
    "abc\n",
    "1,x,3\n",
    "nan nan nan nan\n",
];

/// The number fields of the lines `data_line` accepts, split at any of `separators`.
fn fields(data_line: fn(&str) -> bool, separators: &[char]) -> Numbers<'_> {
    Numbers::Fields {
        data_line,
        separators,
        first: 0,
    }
}

/// The check shared by all readers: a refusal names the file; an acceptance is what the
/// mutated text legally means (see the module doc). `counted`: the format's header counts
/// its items (then a duplicated line and a cut are refused).
fn judge<T: PartialEq + std::fmt::Debug + Clone>(
    file: &str,
    clean: &[T],
    m: &Mutation,
    got: Result<Vec<T>, String>,
    duplicated: impl Fn(usize) -> Option<Vec<T>>,
) -> std::result::Result<(), TestCaseError> {
    match got {
        Err(e) => refused_well(file, m, &e)?,
        Ok(v) => match m {
            Mutation::Bom => prop_assert_eq!(&v[..], clean),
            Mutation::Huge(_) => prop_assert!(false, "a 1e300 was accepted"),
            Mutation::Append(_) => {
                prop_assert_eq!(&v[..], clean, "appended data changed the result")
            }
            Mutation::Duplicate(k) => match duplicated(*k) {
                Some(want) => prop_assert_eq!(v, want),
                None => prop_assert!(false, "a duplicated line was accepted"),
            },
            Mutation::Cut(_) => prefix_ok(&v, clean)?,
        },
    }
    Ok(())
}

const SCAN: &str = "# pingcal-scan v1\n# angle_min_deg=-119.53125\n# angle_increment_deg=0.3515625\n# range_unit=mm\nstamp_s,servo_deg,r0,r1,r2\n0.000,-45.056,1532,1530,0\n0.100,-44.9,1531,7,1529\n0.200,-44.8,1500,1501,1502\n";

fn read_scan(text: &str) -> Result<Vec<ScanLine>, String> {
    read_scan_masked(text).map(|(v, _)| v)
}

/// The scans and how many ranges were masked for being beyond any range finder.
fn read_scan_masked(text: &str) -> Result<(Vec<ScanLine>, usize), String> {
    let mut r = ScanReader::new(text.as_bytes(), "s.csv").map_err(|e| e.to_string())?;
    let v = r
        .by_ref()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    Ok((v, r.masked().count))
}

/// Scans compared without their line numbers (a duplicated line moves the later ones).
fn scan_values(v: Vec<ScanLine>) -> Vec<(f64, f64, Vec<f64>)> {
    v.into_iter()
        .map(|s| (s.stamp_s, s.servo_deg, s.ranges_mm))
        .collect()
}

const XYZ: &str = "# cloud\n1 2 3\n4,5,6, 255 0 0\n7\t8\t9\n-10 11.5 12\n";

const LABELLED: &str = "B1 1 2 3\nB2, 4, 5, 6, 0.5, 0.5, 1\nB3 7 8 9\n";

const PLY: &str = "ply\nformat ascii 1.0\ncomment hi\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n7 8 9\n";

fn points(c: pingcal_lrf::Cloud) -> Vec<[f64; 3]> {
    c.points.iter().map(|p| [p.x, p.y, p.z]).collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn scan_csv(m in mutation(APPENDED)) {
        let text = apply(SCAN, &m, &fields(|l| !l.starts_with('#') && !l.starts_with("stamp"), &[',']));
        let clean = scan_values(read_scan(SCAN).unwrap());
        // a range of 1e300 is masked as no return and counted (issue 39), never silently:
        // the scans read are the clean ones with that range 0, and the count is 1
        if let (Mutation::Huge(_), Ok((v, masked))) = (&m, read_scan_masked(&text)) {
            prop_assert_eq!(masked, 1, "a 1e300 range was read without being counted");
            let got = scan_values(v);
            let differ: Vec<(usize, usize)> = (0..clean.len())
                .flat_map(|i| (0..clean[i].2.len()).map(move |j| (i, j)))
                .filter(|&(i, j)| got[i].2[j] != clean[i].2[j])
                .collect();
            prop_assert!(differ.len() <= 1 && differ.iter().all(|&(i, j)| got[i].2[j] == 0.0), "{:?}", got);
            return Ok(());
        }
        let got = read_scan(&text).map(scan_values);
        let dup = |k: usize| {
            let lines: Vec<&str> = SCAN.lines().collect();
            let k = k % lines.len();
            // A repeated scan is refused (a duplicated record); a repeated header, comment
            // or column line changes nothing.
            (k < 5).then(|| clean.clone())
        };
        judge("s.csv", &clean, &m, got, dup)?;
    }

    #[test]
    fn xyz_clouds(m in mutation(APPENDED)) {
        let text = apply(XYZ, &m, &fields(|l| !l.starts_with('#'), &[' ', ',', '\t']));
        let clean = points(read_xyz(XYZ.as_bytes(), "a.xyz").unwrap());
        let got = read_xyz(text.as_bytes(), "a.xyz").map(points).map_err(|e| e.to_string());
        let dup = |k: usize| {
            let lines: Vec<&str> = XYZ.lines().collect();
            let k = k % lines.len();
            let mut v = clean.clone();
            if k >= 1 {
                v.insert(k - 1, clean[k - 1]);
            }
            Some(v)
        };
        // A cut inside a line's extra columns or a huge colour value is legal.
        let m = match &m {
            Mutation::Huge(_) if text.lines().filter(|l| l.contains("1e300")).any(|l| {
                l.split([' ', ',', '\t']).filter(|t| !t.is_empty()).position(|t| t == "1e300") > Some(2)
            }) => return Ok(()),
            m => m.clone(),
        };
        judge("a.xyz", &clean, &m, got, dup)?;
    }

    #[test]
    fn labelled_points(m in mutation(APPENDED)) {
        let text = apply(LABELLED, &m, &fields(|_| true, &[' ', ',']));
        let clean = read_labelled(LABELLED.as_bytes(), "p.txt").unwrap();
        let got: Result<Vec<LabelledPoint>, String> =
            read_labelled(text.as_bytes(), "p.txt").map_err(|e| e.to_string());
        judge("p.txt", &clean, &m, got, |_| None)?;
    }

    #[test]
    fn ascii_ply(m in mutation(APPENDED)) {
        let text = apply(PLY, &m, &fields(|l| l.starts_with(|c: char| c.is_ascii_digit()), &[' ']));
        let clean = points(pingcal_lrf::ply::read_ply(PLY.as_bytes(), "a.ply").unwrap());
        let got = pingcal_lrf::ply::read_ply(text.as_bytes(), "a.ply")
            .map(points)
            .map_err(|e| e.to_string());
        let dup = |k: usize| {
            // A repeated comment or format line changes nothing; anything else is refused.
            let lines: Vec<&str> = PLY.lines().collect();
            let l = lines[k % lines.len()];
            (l.starts_with("comment") || l.starts_with("format")).then(|| clean.clone())
        };
        // Only a cut of the trailing newline leaves the file whole.
        if let (Mutation::Cut(k), Ok(v)) = (&m, &got) {
            prop_assert!(k % PLY.len() == PLY.len() - 1 && v == &clean, "a cut PLY was accepted");
            return Ok(());
        }
        judge("a.ply", &clean, &m, got, dup)?;
    }

    #[test]
    fn binary_ply(cut in 0usize..200, extra in proptest::collection::vec(any::<u8>(), 1..8), bom: bool) {
        let pts = vec![
            pingcal_lrf::nalgebra::Vector3::new(1.5, -2.0, 1000.25),
            pingcal_lrf::nalgebra::Vector3::new(0.0, 3.0, -4.0),
        ];
        let mut bytes = Vec::new();
        pingcal_lrf::ply::write_ply(&mut bytes, &pts, &[[1, 2, 3], [4, 5, 6]], &[]).unwrap();
        let read = |b: &[u8]| pingcal_lrf::ply::read_ply(b, "b.ply").map(points).map_err(|e| e.to_string());
        let clean = read(&bytes).unwrap();
        let at = cut % bytes.len();
        let e = read(&bytes[..at]).unwrap_err();
        prop_assert!(e.starts_with("b.ply"), "{}", e);
        let mut longer = bytes.clone();
        longer.extend_from_slice(&extra);
        let e = read(&longer).unwrap_err();
        prop_assert!(e.starts_with("b.ply") && e.contains("trailing data"), "{}", e);
        if bom {
            let mut b = "\u{feff}".as_bytes().to_vec();
            b.extend_from_slice(&bytes);
            prop_assert_eq!(read(&b).unwrap(), clean);
        }
    }
}
