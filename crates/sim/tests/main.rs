//! The integration tests of pingcal-sim, one test binary (each module was a file of its own).
//! Run one module with `cargo test -p pingcal-sim --release --test sim <module>::`.

mod detect_rendered;
mod lrf_noise;
mod nod;
mod project;
mod render_centroids;
mod scene;
mod sphere_range_study;
