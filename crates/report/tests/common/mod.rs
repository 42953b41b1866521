//! What the report tests share: the sections every report has, in document order.

/// The section ids, in document order.
pub const IDS: [&str; 21] = [
    "summary",
    "extrinsic",
    "extrinsic_precision",
    "checks",
    "images",
    "histogram",
    "coverage",
    "network",
    "exterior",
    "points",
    "distances",
    "rig",
    "cloud",
    "overlays",
    "intrinsics",
    "distortion",
    "opencv",
    "mount",
    "rejected",
    "warnings",
    "steps",
];
