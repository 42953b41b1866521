//! Streaming readers of ROS bags for pingcal's LRF input: ROS 1 bags (format 2.0, chunks
//! uncompressed, bz2 or lz4), ROS 2 MCAP files (chunks uncompressed, zstd or lz4) and ROS 2 sqlite3 `.db3` bags, with exact
//! decoders of the messages a rotating 2D range finder publishes ([`msgs`]) and the
//! assembly of its scans, as drivers publish them, with the servo angle held (stop-and-go)
//! or interpolated at each beam's time (continuous), in one pass ([`assemble`],
//! [`motion`]), each topic at its header stamps or its record times ([`clock`]: two clocks
//! in one bag told apart).
//!
//! A bag is never loaded whole: ROS 1 bags and MCAP files are memory-mapped and read in
//! file order, one chunk decompressed at a time; `.db3` bags are read one row at a time.
//! Every error is one line naming the file, the topic and what was expected
//! ([`RosbagError`]); no input panics.

pub mod assemble;
pub mod clock;
pub mod error;
pub mod frames;
mod mmap;
pub mod motion;
pub mod msgs;
mod ros1;
mod storage;
pub mod wire;

pub use error::{Result, RosbagError};
pub use wire::Encoding;

use std::path::{Path, PathBuf};

/// One message as stored: its topic, type (ROS 1 spelling, `pkg/Name`), the bag's record
/// time (ROS 1 receive time, MCAP log time, `.db3` timestamp), bytes and wire format.
#[derive(Debug, Clone, Copy)]
pub struct RawMessage<'a> {
    /// Topic name.
    pub topic: &'a str,
    /// Message type, `pkg/Name`.
    pub msg_type: &'a str,
    /// Record time, nanoseconds since the epoch.
    pub time_ns: i64,
    /// The serialized message.
    pub data: &'a [u8],
    /// Its wire format.
    pub encoding: Encoding,
}

/// A topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// Topic name.
    pub name: String,
    /// Message type, `pkg/Name`.
    pub msg_type: String,
    /// Number of messages.
    pub count: u64,
}

/// The storage format of a bag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// ROS 1 bag, format 2.0.
    Ros1,
    /// ROS 2 MCAP.
    Mcap,
    /// ROS 2 sqlite3.
    Sqlite,
}

enum Source {
    Mapped(mmap::Mapped),
    Sqlite(rusqlite::Connection),
}

/// An open bag.
pub struct Bag {
    name: String,
    format: Format,
    source: Source,
}

const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The bag files a path names: the file itself, or for a ROS 2 bag directory its `.db3`
/// and `.mcap` files in name order (the splits of one recording).
pub fn bag_files(path: &Path) -> Result<Vec<PathBuf>> {
    let name = path.display().to_string();
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let io = |e: std::io::Error| RosbagError::Io {
        file: name.clone(),
        msg: e.to_string(),
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "db3" || x == "mcap"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(RosbagError::format(
            &name,
            "a directory without .db3 or .mcap files: not a ROS 2 bag",
        ));
    }
    Ok(files)
}

impl Bag {
    /// Opens a bag file, recognizing its format by its first bytes.
    pub fn open(path: &Path) -> Result<Bag> {
        let name = path.display().to_string();
        let io = |e: std::io::Error| RosbagError::Io {
            file: name.clone(),
            msg: e.to_string(),
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let map = mmap::Mapped::new(&file).map_err(io)?;
        let head = map.bytes();
        let format = if head.starts_with(ros1::MAGIC) {
            Format::Ros1
        } else if head.starts_with(MCAP_MAGIC) {
            Format::Mcap
        } else if head.starts_with(SQLITE_MAGIC) {
            Format::Sqlite
        } else {
            return Err(RosbagError::format(
                &name,
                "not a bag: expected a ROS 1 bag (#ROSBAG V2.0), an MCAP file or a ROS 2 sqlite3 bag",
            ));
        };
        let source = match format {
            Format::Sqlite => {
                drop(map);
                Source::Sqlite(storage::db3_open(path, &name)?)
            }
            _ => Source::Mapped(map),
        };
        Ok(Bag {
            name,
            format,
            source,
        })
    }

    /// The file name used in messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The storage format.
    pub fn format(&self) -> Format {
        self.format
    }

    /// The topics, their types and message counts, by name (reads a ROS 1 bag through).
    pub fn topics(&self) -> Result<Vec<TopicInfo>> {
        match (&self.source, self.format) {
            (Source::Sqlite(c), _) => storage::db3_topics(&self.name, c),
            (Source::Mapped(m), Format::Mcap) => storage::mcap_topics(&self.name, m.bytes()),
            (Source::Mapped(m), _) => self.ros1_topics(m.bytes()),
        }
    }

    fn release(&self, upto: usize) {
        if let Source::Mapped(m) = &self.source {
            m.release(upto);
        }
    }

    fn ros1_topics(&self, buf: &[u8]) -> Result<Vec<TopicInfo>> {
        let mut counts = std::collections::BTreeMap::<(String, String), u64>::new();
        let release = |at| self.release(at);
        let all = ros1::Ros1Reader::new(&self.name).read(buf, &release, &mut |m| {
            *counts
                .entry((m.topic.to_string(), m.msg_type.to_string()))
                .or_default() += 1;
            Ok(())
        })?;
        Ok(all
            .into_iter()
            .map(|(name, msg_type)| {
                let count = counts
                    .get(&(name.clone(), msg_type.clone()))
                    .copied()
                    .unwrap_or(0);
                TopicInfo {
                    name,
                    msg_type,
                    count,
                }
            })
            .collect())
    }

    /// Calls `f` for every message on one of `topics`, in storage order (time order for
    /// `.db3`; file order, which recorders keep in time order, for the others).
    pub fn for_each(
        &self,
        topics: &[&str],
        f: &mut dyn FnMut(&RawMessage) -> Result<()>,
    ) -> Result<()> {
        let want = |t: &str| topics.contains(&t);
        match (&self.source, self.format) {
            (Source::Sqlite(c), _) => storage::db3_messages(&self.name, c, &want, f),
            (Source::Mapped(m), Format::Mcap) => {
                storage::mcap_messages(&self.name, m.bytes(), &|at| m.release(at), &want, f)
            }
            (Source::Mapped(m), _) => ros1::Ros1Reader::new(&self.name)
                .read(m.bytes(), &|at| m.release(at), &mut |msg| {
                    if want(msg.topic) {
                        f(msg)
                    } else {
                        Ok(())
                    }
                })
                .map(drop),
        }
    }
}
