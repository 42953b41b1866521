//! The one error type of the crate: its `Display` is one line naming the file, the topic
//! (where there is one) and what was expected.

/// What went wrong reading a bag.
#[derive(Debug, thiserror::Error)]
pub enum RosbagError {
    /// The file could not be opened or read.
    #[error("{file}: {msg}")]
    Io {
        /// The bag.
        file: String,
        /// What the system said.
        msg: String,
    },
    /// The bag's container is not what its format says (truncated, corrupt chunk, ...).
    #[error("{file}: {msg}")]
    Format {
        /// The bag.
        file: String,
        /// What is wrong and where (byte offset).
        msg: String,
    },
    /// A topic asked for is not in the bag.
    #[error("{file}: topic {topic} is not in the bag (topics present: {present})")]
    MissingTopic {
        /// The bag.
        file: String,
        /// The topic asked for.
        topic: String,
        /// The topics the bag has, comma-separated.
        present: String,
    },
    /// A topic has another message type than the one needed.
    #[error("{file}: topic {topic} is {found}, expected {expected}")]
    WrongType {
        /// The bag.
        file: String,
        /// The topic.
        topic: String,
        /// Its type in the bag.
        found: String,
        /// The type(s) that would do.
        expected: String,
    },
    /// One message could not be decoded as its type.
    #[error("{file}: topic {topic}: message {index}: expected a {expected}: {msg}")]
    Decode {
        /// The bag.
        file: String,
        /// The topic.
        topic: String,
        /// 0-based index of the message on its topic.
        index: u64,
        /// The message type.
        expected: String,
        /// The field and the offset.
        msg: String,
    },
    /// A reader stopped early by its caller (never shown to a user: the caller that stops
    /// a read handles it).
    #[error("reading stopped by the caller")]
    Stopped,
    /// A topic's messages do not make scans (none at all, joint absent, beams changing, ...).
    #[error("{file}: topic {topic}: {msg}")]
    Topic {
        /// The bag(s).
        file: String,
        /// The topic.
        topic: String,
        /// What was expected.
        msg: String,
    },
}

/// Result with [`RosbagError`].
pub type Result<T> = std::result::Result<T, RosbagError>;

impl RosbagError {
    /// A container error for `file`.
    pub fn format(file: &str, msg: impl Into<String>) -> Self {
        RosbagError::Format {
            file: file.to_string(),
            msg: msg.into(),
        }
    }

    /// A topic-level error.
    pub fn topic(file: &str, topic: &str, msg: impl Into<String>) -> Self {
        RosbagError::Topic {
            file: file.to_string(),
            topic: topic.to_string(),
            msg: msg.into(),
        }
    }
}
