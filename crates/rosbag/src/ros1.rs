//! ROS 1 bags, format 2.0: a stream of records (`header_len`, header fields
//! `name=value`, `data_len`, data), messages inside chunks that are stored uncompressed,
//! bz2 or lz4 (LZ4 frames). The chunks are read in file order, one decompressed at a time
//! into one reused buffer; the index records are skipped, so unindexed (unclosed) bags
//! read too.

use crate::error::{Result, RosbagError};
use crate::msgs::normalize_type;
use crate::wire::Encoding;
use crate::RawMessage;
use std::collections::HashMap;
use std::io::Read;

/// The first 13 bytes of a ROS 1 bag.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

const OP_MSG_DATA: u8 = 0x02;
const OP_CHUNK: u8 = 0x05;
const OP_CONNECTION: u8 = 0x07;

/// Chunks claiming more than this many uncompressed bytes (1 GiB) are refused as corrupt.
const MAX_CHUNK: usize = 1 << 30;

/// One record: its header fields and data, and where it started.
struct Record<'a> {
    at: usize,
    header: &'a [u8],
    data: &'a [u8],
}

fn u32_at(buf: &[u8], pos: usize) -> Option<u32> {
    let b = buf.get(pos..pos.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// The record at `pos` of `buf` and the position after it; `base` is `buf`'s offset in
/// the file (for messages) and `what` names the container.
fn record<'a>(
    buf: &'a [u8],
    pos: usize,
    base: usize,
    what: &str,
) -> std::result::Result<(Record<'a>, usize), String> {
    let cut = || format!("{what} truncated in the record at byte {}", base + pos);
    let hlen = u32_at(buf, pos).ok_or_else(cut)? as usize;
    let hstart = pos + 4;
    let hend = hstart
        .checked_add(hlen)
        .filter(|&e| e <= buf.len())
        .ok_or_else(cut)?;
    let dlen = u32_at(buf, hend).ok_or_else(cut)? as usize;
    let dstart = hend + 4;
    let dend = dstart
        .checked_add(dlen)
        .filter(|&e| e <= buf.len())
        .ok_or_else(cut)?;
    let rec = Record {
        at: base + pos,
        header: &buf[hstart..hend],
        data: &buf[dstart..dend],
    };
    Ok((rec, dend))
}

/// The `name=value` fields of a record header (or of a connection header).
fn fields(header: &[u8]) -> impl Iterator<Item = (&[u8], &[u8])> {
    let mut pos = 0;
    std::iter::from_fn(move || {
        let len = u32_at(header, pos)? as usize;
        let field = header.get(pos + 4..(pos + 4).checked_add(len)?)?;
        pos += 4 + len;
        let eq = field.iter().position(|&b| b == b'=')?;
        Some((&field[..eq], &field[eq + 1..]))
    })
}

fn field<'a>(header: &'a [u8], name: &str) -> Option<&'a [u8]> {
    fields(header)
        .find(|(k, _)| *k == name.as_bytes())
        .map(|(_, v)| v)
}

fn field_u32(header: &[u8], name: &str) -> Option<u32> {
    let v = field(header, name)?;
    (v.len() == 4).then(|| u32::from_le_bytes([v[0], v[1], v[2], v[3]]))
}

/// A connection: its topic and message type (ROS 1 spelling).
#[derive(Debug, Clone)]
struct Connection {
    topic: String,
    msg_type: String,
}

/// The linear reader's state: the connections seen so far and the chunk buffer.
pub struct Ros1Reader<'a> {
    file: &'a str,
    connections: HashMap<u32, Connection>,
    chunk: Vec<u8>,
}

impl<'a> Ros1Reader<'a> {
    /// A reader for the bag named `file` (error messages).
    pub fn new(file: &'a str) -> Self {
        Ros1Reader {
            file,
            connections: HashMap::new(),
            chunk: Vec::new(),
        }
    }

    fn err(&self, msg: impl Into<String>) -> RosbagError {
        RosbagError::format(self.file, msg)
    }

    /// Reads every record of `bag` in order, calling `f` for each message; returns the
    /// connections' topics and types (all of them, also those without messages).
    /// `release(pos)` is called after each record with the position reached.
    pub fn read(
        &mut self,
        bag: &[u8],
        release: &dyn Fn(usize),
        f: &mut dyn FnMut(&RawMessage) -> Result<()>,
    ) -> Result<Vec<(String, String)>> {
        if !bag.starts_with(MAGIC) {
            return Err(self.err("not a ROS 1 bag: it does not start with `#ROSBAG V2.0`"));
        }
        let mut pos = MAGIC.len();
        while pos < bag.len() {
            let (rec, next) = record(bag, pos, 0, "the bag is").map_err(|m| self.err(m))?;
            pos = next;
            match field(rec.header, "op") {
                Some([OP_CHUNK]) => self.chunk(&rec, f)?,
                Some([OP_CONNECTION]) => self.connection(&rec)?,
                Some([OP_MSG_DATA]) => self.message(&rec, f)?,
                Some([_]) => {} // bag header, index data, chunk info
                _ => return Err(self.err(format!("record at byte {} has no op field", rec.at))),
            }
            release(pos);
        }
        let mut topics: Vec<_> = self
            .connections
            .values()
            .map(|c| (c.topic.clone(), c.msg_type.clone()))
            .collect();
        topics.sort();
        topics.dedup();
        Ok(topics)
    }

    fn connection(&mut self, rec: &Record) -> Result<()> {
        let bad = || {
            self.err(format!(
                "connection record at byte {} lacks its conn, topic or type",
                rec.at
            ))
        };
        let id = field_u32(rec.header, "conn").ok_or_else(bad)?;
        let topic = field(rec.header, "topic").ok_or_else(bad)?;
        let ty = field(rec.data, "type").ok_or_else(bad)?;
        let conn = Connection {
            topic: String::from_utf8_lossy(topic).into_owned(),
            msg_type: normalize_type(&String::from_utf8_lossy(ty)),
        };
        self.connections.insert(id, conn);
        Ok(())
    }

    fn message(&self, rec: &Record, f: &mut dyn FnMut(&RawMessage) -> Result<()>) -> Result<()> {
        let id = field_u32(rec.header, "conn").ok_or_else(|| {
            self.err(format!(
                "message record at byte {} has no conn field",
                rec.at
            ))
        })?;
        let time = field(rec.header, "time")
            .filter(|t| t.len() == 8)
            .ok_or_else(|| {
                self.err(format!(
                    "message record at byte {} has no time field",
                    rec.at
                ))
            })?;
        let sec = i64::from(u32::from_le_bytes([time[0], time[1], time[2], time[3]]));
        let nsec = i64::from(u32::from_le_bytes([time[4], time[5], time[6], time[7]]));
        let conn = self.connections.get(&id).ok_or_else(|| {
            self.err(format!(
                "message record at byte {} names connection {id}, not defined before it",
                rec.at
            ))
        })?;
        f(&RawMessage {
            topic: &conn.topic,
            msg_type: &conn.msg_type,
            time_ns: sec * 1_000_000_000 + nsec,
            data: rec.data,
            encoding: Encoding::Ros1,
        })
    }

    fn chunk(&mut self, rec: &Record, f: &mut dyn FnMut(&RawMessage) -> Result<()>) -> Result<()> {
        let at = rec.at;
        let size = field_u32(rec.header, "size")
            .ok_or_else(|| self.err(format!("chunk at byte {at} has no size field")))?
            as usize;
        let compression = field(rec.header, "compression").unwrap_or(b"none");
        if size > MAX_CHUNK {
            return Err(self.err(format!("chunk at byte {at} claims {size} bytes: corrupt")));
        }
        let mut buf = std::mem::take(&mut self.chunk);
        buf.clear();
        let result = self
            .decompress(compression, rec.data, size, &mut buf)
            .map_err(|m| self.err(format!("chunk at byte {at}: {m}")))
            .and_then(|()| self.chunk_records(&buf, at, f));
        self.chunk = buf;
        result
    }

    fn decompress(
        &self,
        compression: &[u8],
        data: &[u8],
        size: usize,
        out: &mut Vec<u8>,
    ) -> std::result::Result<(), String> {
        let limit = size as u64 + 1;
        let got = match compression {
            b"none" => {
                out.extend_from_slice(data);
                Ok(data.len())
            }
            b"bz2" => bzip2::read::BzDecoder::new(data)
                .take(limit)
                .read_to_end(out),
            b"lz4" => lz4_flex::frame::FrameDecoder::new(data)
                .take(limit)
                .read_to_end(out),
            other => {
                return Err(format!(
                    "compression {:?}: expected none, bz2 or lz4",
                    String::from_utf8_lossy(other)
                ))
            }
        };
        let name = String::from_utf8_lossy(compression);
        match got {
            Ok(n) if n == size => Ok(()),
            Ok(n) => Err(format!(
                "{name} data gives {n} bytes, the header says {size}: corrupt"
            )),
            Err(e) => Err(format!("{name} data is corrupt ({e})")),
        }
    }

    fn chunk_records(
        &mut self,
        buf: &[u8],
        at: usize,
        f: &mut dyn FnMut(&RawMessage) -> Result<()>,
    ) -> Result<()> {
        let mut pos = 0;
        let what = format!("the chunk at byte {at} is");
        while pos < buf.len() {
            let (rec, next) = record(buf, pos, 0, &what).map_err(|m| self.err(m))?;
            pos = next;
            match field(rec.header, "op") {
                Some([OP_CONNECTION]) => self.connection(&rec)?,
                Some([OP_MSG_DATA]) => self.message(&rec, f)?,
                _ => {
                    return Err(self.err(format!(
                        "the chunk at byte {at} holds a record (at its byte {}) that is neither a message nor a connection",
                        rec.at
                    )))
                }
            }
        }
        Ok(())
    }
}
