//! The integration tests of pingcal-targets, one test binary (each module was a file of its own).
//! Run one module with `cargo test -p pingcal-targets --release --test targets <module>::`.

mod decode_reference;
mod panel;

mod bad_input;
mod boards;
mod candidates_exact;
mod code_tables;
mod marker_boards;
mod panel_bundle;
mod png_fast_path;
mod printed_sheet;
mod real_panel;
mod synthetic;
mod tiff_fast_path;
