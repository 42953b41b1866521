//! The ROS 2 storage formats: MCAP (through the `mcap` crate, over a memory map) and
//! sqlite3 `.db3` (through `rusqlite`, one row at a time).

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

fn mcap_message(
    file: &str,
    m: &mcap::Message,
    want: &dyn Fn(&str) -> bool,
    f: &mut dyn FnMut(&RawMessage) -> Result<()>,
) -> Result<()> {
    let topic = m.channel.topic.as_str();
    if !want(topic) {
        return Ok(());
    }
    let ty = m
        .channel
        .schema
        .as_ref()
        .map_or(String::new(), |s| normalize_type(&s.name));
    f(&RawMessage {
        topic,
        msg_type: &ty,
        time_ns: i64::try_from(m.log_time).unwrap_or(i64::MAX),
        data: &m.data,
        encoding: encoding(file, topic, &m.channel.message_encoding)?,
    })
}

/// The chunk indexes of an MCAP summary in file order, when every one points inside the
/// file (the `mcap` crate slices the file with them unchecked).
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

/// Streams the messages of an MCAP file, calling `f` for those whose topic `want`s: chunk
/// by chunk through the summary's index when the file has one (handing each chunk's pages
/// back with `release` once read), else through the data section in order.
pub fn mcap_messages(
    file: &str,
    buf: &[u8],
    release: &dyn Fn(usize),
    want: &dyn Fn(&str) -> bool,
    f: &mut dyn FnMut(&RawMessage) -> Result<()>,
) -> Result<()> {
    let summary = mcap::Summary::read(buf).ok().flatten();
    if let Some((s, idx)) = summary.and_then(|s| chunk_indexes(&s, buf.len()).map(|i| (s, i))) {
        for c in &idx {
            for m in s.stream_chunk(buf, c).map_err(|e| mcap_err(file, e))? {
                mcap_message(file, &m.map_err(|e| mcap_err(file, e))?, want, f)?;
            }
            release((c.chunk_start_offset + c.chunk_length) as usize);
        }
        return Ok(());
    }
    let stream = mcap::MessageStream::new(buf).map_err(|e| mcap_err(file, e))?;
    for m in stream {
        mcap_message(file, &m.map_err(|e| mcap_err(file, e))?, want, f)?;
    }
    Ok(())
}

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
