//! AICON / Schneider ring codes (SPEC.md "Coded targets").
//!
//! The table rule (checked against the official 12- and 14-bit tables in
//! `shared/data/aicon-panel/`, see the tests): N-bit values with an even number of set
//! bits, at least one pair of opposite sectors (bit i and bit i + N/2) both set, equal to
//! their smallest cyclic rotation, and not all ones. Target number k is the k-th such value
//! (1-based) in increasing order.
//!
//! This module implements the rule itself because `pingcal_targets::aicon` did not exist
//! when the simulator was written; it is meant to be merged with it.
//!
//! Sector convention used by the renderer: with the target's in-plane axes (t1, t2) (t1 × t2
//! along the target normal, towards the viewer), sector k covers the angles
//! `[ψ + k·360°/N, ψ + (k+1)·360°/N)` measured from t1 towards t2, ψ a random rotation of
//! the printed target, and sector k is retro-reflective iff bit k of the code value is set.

/// Rotates an N-bit value left by one (cyclically).
fn rotl(v: u32, n: u32) -> u32 {
    ((v << 1) | (v >> (n - 1))) & ((1 << n) - 1)
}

/// The smallest cyclic rotation of an N-bit value.
pub fn min_rotation(v: u32, n: u32) -> u32 {
    let mut best = v;
    let mut x = v;
    for _ in 1..n {
        x = rotl(x, n);
        best = best.min(x);
    }
    best
}

/// Whether `v` is a valid N-bit AICON code value (see the module doc).
pub fn is_code(v: u32, n: u32) -> bool {
    let all = (1u32 << n) - 1;
    if v == 0 || v == all || v.count_ones() % 2 != 0 {
        return false;
    }
    let half = n / 2;
    let opposite = (0..half).any(|i| v & (1 << i) != 0 && v & (1 << (i + half)) != 0);
    opposite && min_rotation(v, n) == v
}

/// The N-bit code table in target-number order: element k−1 is the code of target k.
pub fn code_table(n: u32) -> Vec<u32> {
    assert!(
        (4..=24).contains(&n) && n % 2 == 0,
        "ring bits must be even, 4..=24"
    );
    (1..(1u32 << n)).filter(|&v| is_code(v, n)).collect()
}

/// The code value of target number `number` (1-based), if the table has it.
pub fn code_of(number: u32, n: u32) -> Option<u32> {
    let t = code_table(n);
    t.get((number as usize).checked_sub(1)?).copied()
}

/// The target number of a ring pattern read at any rotation, if it is a code.
pub fn number_of(pattern: u32, n: u32) -> Option<u32> {
    let v = min_rotation(pattern, n);
    let t = code_table(n);
    t.binary_search(&v).ok().map(|i| i as u32 + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_sizes_are_the_aicon_ones() {
        assert_eq!(code_table(12).len(), 147);
        assert_eq!(code_table(14).len(), 516);
    }

    #[test]
    fn tables_match_the_official_files_when_present() {
        for n in [12u32, 14] {
            let path = format!(
                "{}/../../../shared/data/aicon-panel/aicon-{n}bit-codes.txt",
                env!("CARGO_MANIFEST_DIR")
            );
            let Ok(text) = std::fs::read_to_string(&path) else {
                eprintln!("skipping: {path} not found");
                continue;
            };
            let table = code_table(n);
            let mut count = 0;
            for line in text.lines().filter(|l| !l.trim().is_empty()) {
                let mut it = line.split_whitespace();
                let k: usize = it.next().unwrap().parse().unwrap();
                let v: u32 = it.next().unwrap().parse().unwrap();
                assert_eq!(table[k - 1], v, "{n}-bit target {k}");
                count += 1;
            }
            assert_eq!(count, table.len());
        }
    }

    #[test]
    fn any_rotation_reads_back_the_number() {
        let n = 14;
        for k in [1u32, 2, 100, 516] {
            let mut v = code_of(k, n).unwrap();
            for _ in 0..n {
                assert_eq!(number_of(v, n), Some(k));
                v = rotl(v, n);
            }
        }
    }
}
