//! Arbitrary bytes never make the scan, PLY, XYZ or labelled-point readers panic: they
//! return data or an error.

use pingcal_lrf::ply::read_ply;
use pingcal_lrf::scan::ScanReader;
use pingcal_lrf::xyz::{read_labelled, read_xyz};
use proptest::prelude::*;

fn scan_all(b: &[u8]) {
    if let Ok(r) = ScanReader::new(b, "f") {
        for s in r {
            if s.is_err() {
                break;
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes(b in proptest::collection::vec(any::<u8>(), 0..400)) {
        scan_all(&b);
        let _ = read_ply(&b[..], "f");
        let _ = read_xyz(&b[..], "f");
        let _ = read_labelled(&b[..], "f");
    }

    #[test]
    fn plausible_scan_text(lines in proptest::collection::vec("[-0-9.,a-z# =_]{0,40}", 0..8)) {
        let text = format!("# pingcal-scan v1\n# angle_min_deg=-1\n# angle_increment_deg=0.5\n{}", lines.join("\n"));
        scan_all(text.as_bytes());
    }

    #[test]
    fn plausible_ply(body in proptest::collection::vec(any::<u8>(), 0..200), n in 0usize..1_000_000_000, ascii in any::<bool>()) {
        let fmt = if ascii { "ascii" } else { "binary_little_endian" };
        let mut b = format!("ply\nformat {fmt} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty double z\nend_header\n").into_bytes();
        b.extend(body);
        let _ = read_ply(&b[..], "f");
    }
}
