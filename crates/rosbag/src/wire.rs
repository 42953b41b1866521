//! The two wire formats of ROS messages, behind one cursor: ROS 1 serialization
//! (little endian, packed, `u32` lengths) and CDR (XCDR1 as ROS 2 writes it: a 4-byte
//! encapsulation header giving the byte order, every primitive aligned to its size relative
//! to the end of that header, strings with a `u32` length that counts a terminating NUL).

/// How a message's bytes are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// ROS 1 serialization.
    Ros1,
    /// CDR with its encapsulation header (ROS 2).
    Cdr,
}

/// A cursor over one message's bytes; every read is bounds-checked and a failure says
/// what was being read and where.
#[derive(Debug)]
pub struct Wire<'a> {
    data: &'a [u8],
    pos: usize,
    /// Start of the aligned body (after the CDR encapsulation header; 0 for ROS 1).
    origin: usize,
    big_endian: bool,
    cdr: bool,
}

/// Why a message could not be decoded: the field and the byte offset.
pub type WireError = String;

impl<'a> Wire<'a> {
    /// A cursor over `data`, reading its CDR encapsulation header if `encoding` is CDR.
    pub fn new(data: &'a [u8], encoding: Encoding) -> Result<Self, WireError> {
        let mut w = Wire {
            data,
            pos: 0,
            origin: 0,
            big_endian: false,
            cdr: encoding == Encoding::Cdr,
        };
        if w.cdr {
            let head = w.take(4, "the CDR encapsulation header")?;
            w.big_endian = match (head[0], head[1]) {
                (0, 0) => true,
                (0, 1) => false,
                (a, b) => {
                    return Err(format!(
                        "CDR encapsulation {a:#04x} {b:#04x} is neither CDR_BE nor CDR_LE"
                    ))
                }
            };
            w.origin = 4;
        }
        Ok(w)
    }

    fn align(&mut self, n: usize) {
        if self.cdr {
            let rel = self.pos - self.origin;
            self.pos += (n - rel % n) % n;
        }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], WireError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        match end {
            Some(end) => {
                let s = &self.data[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(format!(
                "{what}: needs {n} bytes at offset {}, the message has {}",
                self.pos,
                self.data.len()
            )),
        }
    }

    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N], WireError> {
        self.align(N);
        let s = self.take(N, what)?;
        let mut b = [0u8; N];
        b.copy_from_slice(s);
        if self.big_endian {
            b.reverse();
        }
        Ok(b)
    }

    /// A `uint16`.
    pub fn u16(&mut self, what: &str) -> Result<u16, WireError> {
        self.bytes::<2>(what).map(u16::from_le_bytes)
    }

    /// A `uint32`.
    pub fn u32(&mut self, what: &str) -> Result<u32, WireError> {
        self.bytes::<4>(what).map(u32::from_le_bytes)
    }

    /// An `int32`.
    pub fn i32(&mut self, what: &str) -> Result<i32, WireError> {
        self.bytes::<4>(what).map(i32::from_le_bytes)
    }

    /// A `float32`.
    pub fn f32(&mut self, what: &str) -> Result<f32, WireError> {
        self.bytes::<4>(what).map(f32::from_le_bytes)
    }

    /// A `float64`.
    pub fn f64(&mut self, what: &str) -> Result<f64, WireError> {
        self.bytes::<8>(what).map(f64::from_le_bytes)
    }

    /// A sequence length, refused when its elements of `elem_size` bytes could not fit in
    /// the rest of the message (a corrupt length never allocates).
    pub fn len(&mut self, what: &str, elem_size: usize) -> Result<usize, WireError> {
        let n = self.u32(what)? as usize;
        let left = self.data.len() - self.pos;
        if n.saturating_mul(elem_size.max(1)) > left {
            return Err(format!(
                "{what}: {n} elements of {elem_size} bytes at offset {} do not fit in the {left} bytes left",
                self.pos
            ));
        }
        Ok(n)
    }

    /// A `string` (UTF-8; CDR's terminating NUL dropped).
    pub fn string(&mut self, what: &str) -> Result<String, WireError> {
        let n = self.len(what, 1)?;
        let mut s = self.take(n, what)?;
        if self.cdr {
            match s.split_last() {
                Some((0, rest)) => s = rest,
                _ => return Err(format!("{what}: CDR string without its terminating NUL")),
            }
        }
        String::from_utf8(s.to_vec()).map_err(|_| format!("{what}: not UTF-8"))
    }

    /// A `uint8`.
    pub fn u8(&mut self, what: &str) -> Result<u8, WireError> {
        self.bytes::<1>(what).map(|b| b[0])
    }

    /// A `uint8[]`, borrowed from the message.
    pub fn u8_seq(&mut self, what: &str) -> Result<&'a [u8], WireError> {
        let n = self.len(what, 1)?;
        self.take(n, what)
    }

    /// A `float32[]` (read as one slice: a scan's ranges are most of a bag).
    pub fn f32_seq(&mut self, what: &str) -> Result<Vec<f32>, WireError> {
        let n = self.len(what, 4)?;
        if n == 0 {
            return Ok(Vec::new());
        }
        self.align(4);
        let raw = self.take(n * 4, what)?;
        let big = self.big_endian;
        Ok(raw
            .chunks_exact(4)
            .map(|b| {
                let b = [b[0], b[1], b[2], b[3]];
                if big {
                    f32::from_be_bytes(b)
                } else {
                    f32::from_le_bytes(b)
                }
            })
            .collect())
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, what: &str) -> Result<Vec<f64>, WireError> {
        let n = self.len(what, 8)?;
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// A `string[]`.
    pub fn string_seq(&mut self, what: &str) -> Result<Vec<String>, WireError> {
        let n = self.len(what, 4)?;
        (0..n).map(|_| self.string(what)).collect()
    }

    /// A time stamp (`time` in ROS 1, `builtin_interfaces/Time` in ROS 2), nanoseconds.
    pub fn time_ns(&mut self, what: &str) -> Result<i64, WireError> {
        let sec = if self.cdr {
            i64::from(self.i32(what)?)
        } else {
            i64::from(self.u32(what)?)
        };
        let nsec = i64::from(self.u32(what)?);
        Ok(sec * 1_000_000_000 + nsec)
    }

    /// A `std_msgs/Header`: its stamp (ns) and frame id (the ROS 1 `seq` skipped).
    pub fn header(&mut self) -> Result<(i64, String), WireError> {
        if !self.cdr {
            self.u32("header.seq")?;
        }
        let stamp = self.time_ns("header.stamp")?;
        let frame = self.string("header.frame_id")?;
        Ok((stamp, frame))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_relative_to_the_body_in_both_byte_orders() {
        // u16 7, then (padding to 8) f64 1.5: body offsets 0..2, pad 2..8, 8..16.
        let mut le = vec![0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0];
        le.extend_from_slice(&1.5f64.to_le_bytes());
        let mut w = Wire::new(&le, Encoding::Cdr).unwrap();
        assert_eq!(w.u16("a").unwrap(), 7);
        assert_eq!(w.f64("b").unwrap(), 1.5);
        let mut be = vec![0, 0, 0, 0, 0, 7, 0, 0, 0, 0, 0, 0];
        be.extend_from_slice(&1.5f64.to_be_bytes());
        let mut w = Wire::new(&be, Encoding::Cdr).unwrap();
        assert_eq!(w.u16("a").unwrap(), 7);
        assert_eq!(w.f64("b").unwrap(), 1.5);
    }

    #[test]
    fn ros1_is_packed_and_cdr_strings_carry_a_nul() {
        let mut b = vec![7, 0];
        b.extend_from_slice(&2.5f64.to_le_bytes());
        let mut w = Wire::new(&b, Encoding::Ros1).unwrap();
        assert_eq!(w.u16("a").unwrap(), 7);
        assert_eq!(w.f64("b").unwrap(), 2.5);
        let b = [0, 1, 0, 0, 3, 0, 0, 0, b'a', b'b', 0];
        let mut w = Wire::new(&b, Encoding::Cdr).unwrap();
        assert_eq!(w.string("s").unwrap(), "ab");
    }

    #[test]
    fn a_huge_length_is_refused_without_allocating() {
        let b = [0xff, 0xff, 0xff, 0x7f, 1, 2];
        let mut w = Wire::new(&b, Encoding::Ros1).unwrap();
        let e = w.f32_seq("ranges").unwrap_err();
        assert!(e.starts_with("ranges: 2147483647 elements"), "{e}");
    }
}
