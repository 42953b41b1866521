//! LZF decompression (the liblzf format of PCD's `binary_compressed` data), bounded: the
//! output never grows past the size the caller expects, and malformed input is an error,
//! never a panic.

/// Decompresses `input` into exactly `expected` bytes, or says why it cannot.
///
/// Each token starts with a control byte `c`: below 32 it is a run of `c + 1` literal
/// bytes; otherwise a back-reference of `(c >> 5) + 2` bytes (7 meaning a length byte
/// follows and is added) at distance `((c & 31) << 8 | next) + 1` behind the output's end.
pub fn decompress(input: &[u8], expected: usize) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(expected);
    let mut i = 0;
    while i < input.len() {
        let c = input[i] as usize;
        i += 1;
        if c < 32 {
            let run = input
                .get(i..i + c + 1)
                .ok_or("LZF literal run past the end of the data")?;
            push(&mut out, run, expected)?;
            i += c + 1;
            continue;
        }
        let mut len = c >> 5;
        if len == 7 {
            len += *input.get(i).ok_or("LZF length past the end of the data")? as usize;
            i += 1;
        }
        let low = *input.get(i).ok_or("LZF offset past the end of the data")? as usize;
        i += 1;
        let dist = ((c & 31) << 8 | low) + 1;
        let start = out
            .len()
            .checked_sub(dist)
            .ok_or("LZF back-reference before the start of the data")?;
        if out.len() + len + 2 > expected {
            return Err(overflow(expected));
        }
        for k in 0..len + 2 {
            let b = out[start + k];
            out.push(b);
        }
    }
    if out.len() != expected {
        return Err(format!(
            "LZF data gives {} bytes, the header says {expected}",
            out.len()
        ));
    }
    Ok(out)
}

fn push(out: &mut Vec<u8>, run: &[u8], expected: usize) -> Result<(), String> {
    if out.len() + run.len() > expected {
        return Err(overflow(expected));
    }
    out.extend_from_slice(run);
    Ok(())
}

fn overflow(expected: usize) -> String {
    format!("LZF data gives more than the {expected} bytes the header says")
}

/// The most bytes `n` compressed bytes can give: a 3-byte back-reference gives at most
/// 264 bytes, so no more than 88 per input byte.
pub const MAX_RATIO: usize = 88;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A plain LZF compressor for the tests (greedy, longest match in the 8 KiB window).
    pub(crate) fn compress(data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut lit: Vec<u8> = Vec::new();
        let flush = |out: &mut Vec<u8>, lit: &mut Vec<u8>| {
            for chunk in lit.chunks(32) {
                out.push(chunk.len() as u8 - 1);
                out.extend_from_slice(chunk);
            }
            lit.clear();
        };
        let mut i = 0;
        while i < data.len() {
            let (mut best, mut dist) = (0, 0);
            for d in 1..=i.min(8192) {
                let mut l = 0;
                while l < 264 && i + l < data.len() && data[i + l] == data[i - d + l] {
                    l += 1;
                }
                if l > best {
                    (best, dist) = (l, d);
                }
            }
            if best < 3 {
                lit.push(data[i]);
                i += 1;
                continue;
            }
            flush(&mut out, &mut lit);
            let (len, off) = (best - 2, dist - 1);
            if len < 7 {
                out.push(((len << 5) | (off >> 8)) as u8);
            } else {
                out.push(((7 << 5) | (off >> 8)) as u8);
                out.push((len - 7) as u8);
            }
            out.push((off & 255) as u8);
            i += best;
        }
        flush(&mut out, &mut lit);
        out
    }

    #[test]
    fn a_hand_checked_stream() {
        // literal "abc", then 7 bytes from distance 3 ("abcabca"), then literal "Z"
        let s = [2, b'a', b'b', b'c', 5 << 5, 2, 0, b'Z'];
        assert_eq!(decompress(&s, 11).unwrap(), b"abcabcabcaZ");
        assert!(decompress(&s, 10).unwrap_err().contains("more than"));
        assert!(decompress(&s, 12).unwrap_err().contains("gives 11 bytes"));
        assert!(decompress(&[1 << 5, 0], 3)
            .unwrap_err()
            .contains("before the start"));
        assert!(decompress(&[4, b'a'], 5)
            .unwrap_err()
            .contains("past the end"));
    }

    proptest! {
        #[test]
        fn round_trip(data in proptest::collection::vec(0u8..4, 0..2000)) {
            let c = compress(&data);
            prop_assert_eq!(decompress(&c, data.len()).unwrap(), data.clone());
            prop_assert!(data.len() <= c.len() * MAX_RATIO);
        }

        #[test]
        fn any_bytes_never_panic_nor_overgrow(
            data in proptest::collection::vec(any::<u8>(), 0..300),
            expected in 0usize..5000,
        ) {
            if let Ok(v) = decompress(&data, expected) {
                prop_assert_eq!(v.len(), expected);
            }
        }
    }
}
