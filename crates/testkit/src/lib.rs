//! Test support shared by the integration tests of the pingcal crates.
//!
//! This crate is dev-only: it is never published and only ever named under
//! `[dev-dependencies]`, so nothing here reaches a library or the binary. It holds the
//! harnesses that more than one crate's tests would otherwise copy, so that a harness is
//! written, documented and fixed once:
//!
//! * [`mutations`]: the readers' mutation harness ("nothing silent", issue 14). A reader's
//!   test takes a valid file, mutates it the ways real files go wrong (a line duplicated,
//!   data appended, the file cut short, a UTF-8 byte-order mark in front, a number made
//!   huge) and checks that the reader either refuses it with an error naming the file or
//!   reads what the mutated text legally means. The harness generates and applies the
//!   mutations and holds the checks every reader shares; what a mutated file legally
//!   means stays with each reader's test (pingcal-ba's `tests/reader_mutations.rs` for
//!   BAL, the measurement JSON and DBAT's files; pingcal-lrf's for scans, XYZ, labelled
//!   points and PLY).
//!
//! It depends on no pingcal crate (any crate's tests may use it) and on nothing but
//! `proptest`, which the tests already use.
#![warn(missing_docs)]

pub mod mutations;
