//! The integration tests of pingcal-report, one test binary (each module was a file of its own).
//! Run one module with `cargo test -p pingcal-report --release --test report <module>::`.

mod common;

mod browser;
mod render;
