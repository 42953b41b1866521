//! The PCD reader against fixtures written by an independent writer (pypcd4, see
//! `data/pcd/make_fixtures.py`): ascii, binary and binary_compressed of one organized 5 × 4
//! cloud with two NaN points and fields to skip give exactly the points of `cloud.xyz`
//! (mm; the PCD files are metres). Then the fixtures truncated, corrupted, and random
//! headers: always `Ok` or `Err`, never a panic.

use pingcal_lrf::pcd::read_pcd;
use proptest::prelude::*;
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/pcd")
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(dir().join(name)).unwrap()
}

const KINDS: [&str; 3] = [
    "cloud_ascii.pcd",
    "cloud_binary.pcd",
    "cloud_binary_compressed.pcd",
];

#[test]
fn the_three_fixtures_give_the_points_of_cloud_xyz() {
    let truth = pingcal_lrf::xyz::read_xyz_file(&dir().join("cloud.xyz")).unwrap();
    assert_eq!(truth.len(), 18);
    for k in KINDS {
        let c = read_pcd(&fixture(k), k).unwrap();
        assert_eq!(c.len(), truth.len(), "{k}");
        let worst = c
            .points
            .iter()
            .zip(&truth.points)
            .map(|(p, t)| (p * 1000.0 - t).amax())
            .fold(0.0, f64::max);
        println!("{k}: max difference {worst:e} mm");
        assert!(worst < 1e-9, "{k}: {worst}");
    }
}

#[test]
fn a_cut_fixture_is_refused_naming_the_file() {
    for k in KINDS {
        let b = fixture(k);
        let e = read_pcd(&b[..b.len() - 3], k).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{k}:")), "{e}");
    }
}

fn header() -> impl Strategy<Value = String> {
    let key = prop_oneof![
        Just("VERSION"),
        Just("FIELDS"),
        Just("SIZE"),
        Just("TYPE"),
        Just("COUNT"),
        Just("WIDTH"),
        Just("HEIGHT"),
        Just("POINTS"),
        Just("VIEWPOINT"),
    ];
    let val = prop_oneof![
        Just("x y z".to_string()),
        Just("4 4 4".to_string()),
        Just("8 8 8 2".to_string()),
        Just("F F F".to_string()),
        Just("F F F U".to_string()),
        Just("1 1 1".to_string()),
        Just("1 1 1 3".to_string()),
        Just("0 0 0 1 0 0 0".to_string()),
        (0u64..u64::MAX).prop_map(|n| n.to_string()),
        (0u64..40).prop_map(|n| n.to_string()),
        "[a-z0-9. ]{0,12}",
    ];
    let data = prop_oneof![Just("ascii"), Just("binary"), Just("binary_compressed")];
    (
        proptest::collection::vec((key, val), 0..10),
        data,
        proptest::collection::vec(any::<u8>(), 0..300),
    )
        .prop_map(|(lines, data, body)| {
            let mut s = String::new();
            for (k, v) in lines {
                s += &format!("{k} {v}\n");
            }
            s += &format!("DATA {data}\n");
            s + &String::from_utf8_lossy(&body)
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    #[test]
    fn cut_or_corrupted_fixtures_never_panic(
        k in 0usize..3,
        cut in any::<usize>(),
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
    ) {
        let mut b = fixture(KINDS[k]);
        for (at, v) in flips {
            let n = b.len();
            b[at % n] = v;
        }
        let keep = cut % (b.len() + 1);
        let _ = read_pcd(&b[..keep], KINDS[k]);
    }

    #[test]
    fn random_headers_never_panic(text in header()) {
        let _ = read_pcd(text.as_bytes(), "r.pcd");
    }
}
