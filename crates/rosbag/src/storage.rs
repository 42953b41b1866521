//! The ROS 2 storage formats: MCAP (the `mcap` crate's record reader over a memory map,
//! chunks uncompressed or decompressed here with a bound: zstd through `ruzstd`, lz4 through
//! `lz4_flex`) and sqlite3 `.db3` (through `rusqlite`, one row at a time).

use crate::error::{Result, RosbagError};
use crate::msgs::normalize_type;
use crate::wire::Encoding;
use crate::{RawMessage, TopicInfo};
use std::collections::BTreeMap;

fn encoding(file: &str, topic: &str, enc: &str) -> Result<Encoding> {
    match enc {
        "cdr" => Ok(Encoding::Cdr),
        "ros1" => Ok(Encoding::Ros1),
        other => Err(RosbagError::topic(
            file,
            topic,
            format!("message encoding {other:?}: expected cdr or ros1"),
        )),
    }
}

fn mcap_err(file: &str, e: mcap::McapError) -> RosbagError {
    RosbagError::format(file, format!("MCAP: {e}"))
}

/// Chunks that say they hold more than this many bytes uncompressed (1 GiB) are refused as
/// corrupt, before anything is allocated for them (as the ROS 1 reader's chunks are).
const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// The schemas and channels of an MCAP file met so far, in the data section or in its
/// chunks, and what each record means for the caller.
#[derive(Default)]
struct McapChannels {
    /// Schema id → message type (normalized).
    schemas: std::collections::HashMap<u16, String>,
    /// Channel id → (topic, message type, message encoding).
    channels: std::collections::HashMap<u16, (String, String, String)>,
}

impl McapChannels {
    /// The channels of a summary.
    fn from_summary(s: &mcap::Summary) -> Self {
        let mut me = Self::default();
        for c in s.channels.values() {
            let ty = c
                .schema
                .as_ref()
                .map_or(String::new(), |s| normalize_type(&s.name));
            me.channels
                .insert(c.id, (c.topic.clone(), ty, c.message_encoding.clone()));
        }
        me
    }

    /// The records of one chunk (uncompressed, or decompressed by [`decompress_chunk`]),
    /// through [`McapChannels::take`].
    fn chunk(
        &mut self,
        file: &str,
        header: &mcap::records::ChunkHeader,
        data: &[u8],
        want: &dyn Fn(&str) -> bool,
        f: &mut dyn FnMut(&RawMessage) -> Result<()>,
    ) -> Result<()> {
        let (h, body) = plain_chunk(file, header, data)?;
        self.records(file, h, &body, want, f)
    }

    /// The records of an uncompressed chunk, through [`McapChannels::take`].
    fn records(
        &mut self,
        file: &str,
        h: mcap::records::ChunkHeader,
        body: &[u8],
        want: &dyn Fn(&str) -> bool,
        f: &mut dyn FnMut(&RawMessage) -> Result<()>,
    ) -> Result<()> {
        for r in mcap::read::ChunkReader::new(h, body).map_err(|e| mcap_err(file, e))? {
            self.take(file, &r.map_err(|e| mcap_err(file, e))?, want, f)?;
        }
        Ok(())
    }

    /// Takes in one record: a schema or a channel is remembered, a message of a wanted
    /// topic is handed to `f`.
    fn take(
        &mut self,
        file: &str,
        record: &mcap::records::Record,
        want: &dyn Fn(&str) -> bool,
        f: &mut dyn FnMut(&RawMessage) -> Result<()>,
    ) -> Result<()> {
        use mcap::records::Record;
        match record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, normalize_type(&header.name));
            }
            Record::Channel(c) => {
                let ty = self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                self.channels
                    .insert(c.id, (c.topic.clone(), ty, c.message_encoding.clone()));
            }
            Record::Message { header, data } => {
                let Some((topic, ty, enc)) = self.channels.get(&header.channel_id) else {
                    return Err(RosbagError::format(
                        file,
                        format!(
                            "MCAP: message {} on channel {}, which no channel record before it defines",
                            header.sequence, header.channel_id
                        ),
                    ));
                };
                if want(topic) {
                    f(&RawMessage {
                        topic,
                        msg_type: ty,
                        time_ns: i64::try_from(header.log_time).unwrap_or(i64::MAX),
                        data,
                        encoding: encoding(file, topic, enc)?,
                    })?;
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// A chunk as uncompressed records: its header saying so, and its bytes (borrowed when
/// stored uncompressed).
fn plain_chunk<'a>(
    file: &str,
    header: &mcap::records::ChunkHeader,
    data: &'a [u8],
) -> Result<(mcap::records::ChunkHeader, std::borrow::Cow<'a, [u8]>)> {
    if header.compression.is_empty() {
        return Ok((header.clone(), std::borrow::Cow::Borrowed(data)));
    }
    let plain = decompress_chunk(file, &header.compression, data, header.uncompressed_size)?;
    let h = mcap::records::ChunkHeader {
        compression: String::new(),
        compressed_size: plain.len() as u64,
        ..header.clone()
    };
    Ok((h, std::borrow::Cow::Owned(plain)))
}

/// A chunk's records, decompressed (zstd, lz4) into exactly the `uncompressed_size` its
/// header gives, which is bounded by [`MAX_CHUNK_BYTES`] before anything is allocated.
fn decompress_chunk(file: &str, compression: &str, data: &[u8], size: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let err = |msg: String| RosbagError::format(file, format!("MCAP: {msg}"));
    if size > MAX_CHUNK_BYTES {
        return Err(err(format!(
            "a {compression} chunk says it holds {size} bytes uncompressed, more than the {MAX_CHUNK_BYTES} pingcal accepts: the file is corrupt"
        )));
    }
    let mut out = Vec::with_capacity(size as usize);
    let read = match compression {
        "zstd" => zstd_chunk(data, size, &mut out)
            .map_err(|e| err(format!("a zstd chunk cannot be decompressed: {e}")))?,
        "lz4" => lz4_flex::frame::FrameDecoder::new(data)
            .take(size + 1)
            .read_to_end(&mut out),
        other => {
            return Err(err(format!(
                "chunk compression {other:?}: pingcal reads uncompressed, zstd and lz4 chunks"
            )))
        }
    };
    read.map_err(|e| err(format!("a {compression} chunk cannot be decompressed: {e}")))?;
    if out.len() as u64 != size {
        return Err(err(format!(
            "a {compression} chunk gives {}{} bytes, its header says {size}",
            if out.len() as u64 > size {
                "more than "
            } else {
                ""
            },
            out.len().min(size as usize)
        )));
    }
    Ok(out)
}

/// A zstd chunk decompressed into `out` (capacity `size`) by the pure-Rust `ruzstd`, with
/// one decoder per thread kept from chunk to chunk (its window buffers are not allocated and
/// faulted in again for every chunk). The output has room for one byte more than declared,
/// so that a chunk giving more is told.
#[cfg(not(feature = "zstd-c"))]
fn zstd_chunk(
    data: &[u8],
    size: u64,
    out: &mut Vec<u8>,
) -> std::result::Result<std::io::Result<usize>, String> {
    use ruzstd::decoding::{errors::FrameDecoderError, FrameDecoder};
    thread_local! {
        static DECODER: std::cell::RefCell<FrameDecoder> = std::cell::RefCell::new(FrameDecoder::new());
    }
    out.resize(size as usize + 1, 0);
    let got = DECODER.with(|d| d.borrow_mut().decode_all(data, &mut out[..]));
    match got {
        Ok(n) => {
            out.truncate(n);
            Ok(Ok(n))
        }
        // more than the room left: more than declared
        Err(FrameDecoderError::TargetTooSmall) => Ok(Ok(out.len())),
        Err(e) => {
            out.clear();
            Err(e.to_string())
        }
    }
}

/// A zstd chunk decompressed into `out` (capacity `size`) by the reference C library
/// (feature `zstd-c`): one call, bounded by the buffer; a chunk that would give more than
/// its header says fails for want of room, which the caller reports as a size mismatch.
#[cfg(feature = "zstd-c")]
fn zstd_chunk(
    data: &[u8],
    size: u64,
    out: &mut Vec<u8>,
) -> std::result::Result<std::io::Result<usize>, String> {
    // one byte more than declared, so that a longer chunk is told as such
    out.reserve_exact(size as usize + 1);
    match zstd_safe::decompress(out, data) {
        Ok(n) => Ok(Ok(n)),
        Err(code)
            if zstd_safe::get_error_name(code).contains("Destination buffer is too small") =>
        {
            out.resize(size as usize + 1, 0);
            Ok(Ok(out.len()))
        }
        Err(code) => Err(zstd_safe::get_error_name(code).to_string()),
    }
}

/// The chunk indexes of an MCAP summary in file order, when every one points inside the
/// file.
fn chunk_indexes(summary: &mcap::Summary, len: usize) -> Option<Vec<mcap::records::ChunkIndex>> {
    let mut idx = summary.chunk_indexes.clone();
    idx.sort_by_key(|c| c.chunk_start_offset);
    let fits = |c: &mcap::records::ChunkIndex| {
        c.chunk_length >= 9
            && c.chunk_start_offset
                .checked_add(c.chunk_length)
                .is_some_and(|e| e <= len as u64)
    };
    (!idx.is_empty() && idx.iter().all(fits)).then_some(idx)
}

/// Streams the messages of an MCAP file in file order, calling `f` for those whose topic
/// `want`s. With a summary, chunk by chunk through its index, straight from the map, each
/// chunk's pages handed back with `release` once read; else the records in order. A chunk
/// is uncompressed or decompressed here (zstd, lz4) and its records' CRC checked.
pub fn mcap_messages(
    file: &str,
    buf: &[u8],
    release: &dyn Fn(usize),
    want: &dyn Fn(&str) -> bool,
    f: &mut dyn FnMut(&RawMessage) -> Result<()>,
) -> Result<()> {
    use mcap::records::Record;
    let summary = mcap::Summary::read(buf).ok().flatten();
    if let Some((s, idx)) = summary.and_then(|s| chunk_indexes(&s, buf.len()).map(|i| (s, i))) {
        let mut channels = McapChannels::from_summary(&s);
        return indexed_chunks(file, buf, &idx, &mut channels, release, want, f);
    }
    let mut channels = McapChannels::default();
    for record in mcap::read::LinearReader::new(buf).map_err(|e| mcap_err(file, e))? {
        match record.map_err(|e| mcap_err(file, e))? {
            Record::Chunk { header, data } => channels.chunk(file, &header, &data, want, f)?,
            other => channels.take(file, &other, want, f)?,
        }
    }
    Ok(())
}

/// One chunk of the summary's index, parsed and made plain (decompressed).
fn indexed_chunk<'a>(
    file: &str,
    buf: &'a [u8],
    c: &mcap::records::ChunkIndex,
) -> Result<(
    mcap::records::ChunkHeader,
    std::borrow::Cow<'a, [u8]>,
    usize,
)> {
    use mcap::records::Record;
    let (start, end) = (
        c.chunk_start_offset as usize,
        (c.chunk_start_offset + c.chunk_length) as usize,
    );
    // a record is its opcode (1 byte), its length (8) and its body
    let record = mcap::parse_record(mcap::records::op::CHUNK, &buf[start + 9..end])
        .map_err(|e| mcap_err(file, e))?;
    let Record::Chunk { header, data } = record else {
        return Err(RosbagError::format(
            file,
            format!("MCAP: the summary's chunk at byte {start} is not a chunk"),
        ));
    };
    let data: &'a [u8] = match data {
        std::borrow::Cow::Borrowed(d) => d,
        // the crate hands the map's bytes back borrowed; should it not, decompress a copy
        std::borrow::Cow::Owned(d) => {
            let (h, body) = plain_chunk(file, &header, &d)?;
            return Ok((h, std::borrow::Cow::Owned(body.into_owned()), end));
        }
    };
    let (h, body) = plain_chunk(file, &header, data)?;
    Ok((h, body, end))
}

/// The chunks of an MCAP file through its index, in file order: each decompressed on a
/// thread of its own while the one before is decoded (at most [`CHUNKS_AHEAD`] waiting, so
/// memory stays a few chunks whatever the file), its pages handed back with `release` once
/// read.
fn indexed_chunks(
    file: &str,
    buf: &[u8],
    idx: &[mcap::records::ChunkIndex],
    channels: &mut McapChannels,
    release: &dyn Fn(usize),
    want: &dyn Fn(&str) -> bool,
    f: &mut dyn FnMut(&RawMessage) -> Result<()>,
) -> Result<()> {
    if idx.len() < 2 || idx.iter().all(|c| c.compression.is_empty()) {
        for c in idx {
            let (h, body, end) = indexed_chunk(file, buf, c)?;
            channels.records(file, h, &body, want, f)?;
            release(end);
        }
        return Ok(());
    }
    std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel(CHUNKS_AHEAD);
        scope.spawn(move || {
            for c in idx {
                let chunk = indexed_chunk(file, buf, c);
                let failed = chunk.is_err();
                // the reader stopped (an error, or its caller is done): stop too
                if tx.send(chunk).is_err() || failed {
                    break;
                }
            }
        });
        for chunk in rx {
            let (h, body, end) = chunk?;
            channels.records(file, h, &body, want, f)?;
            release(end);
        }
        Ok(())
    })
}

/// Decompressed chunks that may wait for the reader (module doc of [`indexed_chunks`]).
const CHUNKS_AHEAD: usize = 2;

/// The topics of an MCAP file: from its summary when it has one (channels without messages
/// included), else by reading it through.
pub fn mcap_topics(file: &str, buf: &[u8]) -> Result<Vec<TopicInfo>> {
    let summary = mcap::Summary::read(buf).ok().flatten();
    if let Some(s) = summary.filter(|s| s.stats.is_some()) {
        let counts = s
            .stats
            .as_ref()
            .map(|st| st.channel_message_counts.clone())
            .unwrap_or_default();
        let mut out: Vec<TopicInfo> = s
            .channels
            .values()
            .map(|c| TopicInfo {
                name: c.topic.clone(),
                msg_type: c
                    .schema
                    .as_ref()
                    .map_or(String::new(), |s| normalize_type(&s.name)),
                count: counts.get(&c.id).copied().unwrap_or(0),
            })
            .collect();
        out.sort_by(|a, b| a.name.cmp(&b.name));
        return Ok(out);
    }
    let mut map: BTreeMap<String, TopicInfo> = BTreeMap::new();
    mcap_messages(file, buf, &|_| {}, &|_| true, &mut |m| {
        map.entry(m.topic.to_string())
            .or_insert_with(|| TopicInfo {
                name: m.topic.to_string(),
                msg_type: m.msg_type.to_string(),
                count: 0,
            })
            .count += 1;
        Ok(())
    })?;
    Ok(map.into_values().collect())
}

fn sql_err(file: &str, e: rusqlite::Error) -> RosbagError {
    RosbagError::format(file, format!("sqlite3 bag: {e}"))
}

/// A ROS 2 sqlite3 bag, opened read-only.
pub fn db3_open(path: &std::path::Path, file: &str) -> Result<rusqlite::Connection> {
    let flags =
        rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let c = rusqlite::Connection::open_with_flags(path, flags).map_err(|e| sql_err(file, e))?;
    // Reading the schema checks that the file is a database with the bag's tables.
    c.prepare("SELECT id, name, type, serialization_format FROM topics")
        .map_err(|e| sql_err(file, e))?;
    // SQLite reads a truncated file's missing pages as absent rows: refuse it instead.
    let pages: i64 = c
        .query_row("PRAGMA page_count", [], |r| r.get(0))
        .map_err(|e| sql_err(file, e))?;
    let page_size: i64 = c
        .query_row("PRAGMA page_size", [], |r| r.get(0))
        .map_err(|e| sql_err(file, e))?;
    let len = std::fs::metadata(path).map_or(0, |m| m.len());
    let want = pages.saturating_mul(page_size).max(0) as u64;
    if len < want {
        return Err(RosbagError::format(
            file,
            format!("sqlite3 bag truncated: {len} bytes, its header says {pages} pages of {page_size} bytes"),
        ));
    }
    Ok(c)
}

/// The topics of a sqlite3 bag: (id, name, type, serialization format).
fn db3_topic_rows(
    file: &str,
    c: &rusqlite::Connection,
) -> Result<Vec<(i64, String, String, String)>> {
    let mut st = c
        .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY name")
        .map_err(|e| sql_err(file, e))?;
    let rows = st
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
        .map_err(|e| sql_err(file, e))?;
    rows.collect::<rusqlite::Result<Vec<_>>>()
        .map_err(|e| sql_err(file, e))
}

/// The topics of a sqlite3 bag and their message counts.
pub fn db3_topics(file: &str, c: &rusqlite::Connection) -> Result<Vec<TopicInfo>> {
    let mut st = c
        .prepare("SELECT COUNT(*) FROM messages WHERE topic_id = ?1")
        .map_err(|e| sql_err(file, e))?;
    db3_topic_rows(file, c)?
        .into_iter()
        .map(|(id, name, ty, _)| {
            let count: i64 = st
                .query_row([id], |r| r.get(0))
                .map_err(|e| sql_err(file, e))?;
            Ok(TopicInfo {
                name,
                msg_type: normalize_type(&ty),
                count: count.max(0) as u64,
            })
        })
        .collect()
}

/// Streams the messages of the wanted topics of a sqlite3 bag in time order.
pub fn db3_messages(
    file: &str,
    c: &rusqlite::Connection,
    want: &dyn Fn(&str) -> bool,
    f: &mut dyn FnMut(&RawMessage) -> Result<()>,
) -> Result<()> {
    let mut topics = BTreeMap::new();
    for (id, name, ty, ser) in db3_topic_rows(file, c)? {
        if want(&name) {
            let enc = encoding(file, &name, &ser)?;
            topics.insert(id, (name, normalize_type(&ty), enc));
        }
    }
    let ids: Vec<String> = topics.keys().map(i64::to_string).collect();
    let sql = format!(
        "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({}) ORDER BY timestamp, id",
        ids.join(",")
    );
    let mut st = c.prepare(&sql).map_err(|e| sql_err(file, e))?;
    let mut rows = st.query([]).map_err(|e| sql_err(file, e))?;
    while let Some(row) = rows.next().map_err(|e| sql_err(file, e))? {
        let id: i64 = row.get(0).map_err(|e| sql_err(file, e))?;
        let time_ns: i64 = row.get(1).map_err(|e| sql_err(file, e))?;
        let data = row.get_ref(2).map_err(|e| sql_err(file, e))?;
        let data = data.as_blob().map_err(|e| sql_err(file, e.into()))?;
        let Some((name, ty, enc)) = topics.get(&id) else {
            continue;
        };
        f(&RawMessage {
            topic: name,
            msg_type: ty,
            time_ns,
            data,
            encoding: *enc,
        })?;
    }
    Ok(())
}

#[cfg(test)]
mod chunk_tests {
    use super::decompress_chunk;

    /// A chunk's declared size bounds what is allocated and must be what it gives.
    #[test]
    fn a_compressed_chunk_gives_exactly_its_declared_size_or_an_error() {
        let text = b"pingcal ".repeat(100);
        let mut lz4 = lz4_flex::frame::FrameEncoder::new(Vec::new());
        std::io::Write::write_all(&mut lz4, &text).unwrap();
        let lz4 = lz4.finish().unwrap();
        assert_eq!(decompress_chunk("f.mcap", "lz4", &lz4, 800).unwrap(), text);
        for (size, want) in [
            (1u64 << 40, "more than the 1073741824 pingcal accepts"),
            (799, "gives more than 799 bytes, its header says 799"),
            (801, "gives 800 bytes, its header says 801"),
        ] {
            let e = decompress_chunk("f.mcap", "lz4", &lz4, size)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("f.mcap: ") && e.contains(want), "{e}");
        }
        let e = decompress_chunk("f.mcap", "zstd", &lz4, 800)
            .unwrap_err()
            .to_string();
        assert!(e.contains("a zstd chunk cannot be decompressed"), "{e}");
        let e = decompress_chunk("f.mcap", "brotli", &lz4, 800)
            .unwrap_err()
            .to_string();
        assert!(e.contains("chunk compression \"brotli\""), "{e}");
    }
}
