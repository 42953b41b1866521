//! The generated ring-code tables against the AICON tables shipped with the real panel data.

use pingcal_targets::aicon::CodeTable;

const DATA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/data/aicon-panel"
);

#[test]
fn generated_tables_equal_the_aicon_files() {
    for bits in [12u32, 14] {
        let path = format!("{DATA}/aicon-{bits}bit-codes.txt");
        let Ok(text) = std::fs::read_to_string(&path) else {
            println!("SKIP: {path} not found");
            continue;
        };
        let table = CodeTable::generate(bits).unwrap();
        let mut n = 0;
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            let f: Vec<u32> = line
                .split_whitespace()
                .map(|s| s.parse().unwrap())
                .collect();
            assert_eq!(table.code(f[0]), Some(f[1]), "{bits} bit, target {}", f[0]);
            assert_eq!(table.id(f[1]), Some(f[0]));
            n += 1;
        }
        assert_eq!(n, table.codes.len(), "{bits} bit table size");
    }
}
