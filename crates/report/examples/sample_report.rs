//! Writes the sample calibration report (22 images, 78 targets + 16 balls, a ray-cast LRF
//! cloud of a room corner with 16 spheres, two methods with 5 check balls each).
//!
//! `cargo run --release -p pingcal-report --example sample_report -- OUT.html [CLOUD_POINTS]`

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(out) = args.next() else {
        eprintln!("usage: sample_report OUT.html [CLOUD_POINTS (default 30000)]");
        std::process::exit(2);
    };
    let n: usize = match args.next().map(|s| s.parse()) {
        None => 30_000,
        Some(Ok(n)) => n,
        Some(Err(e)) => {
            eprintln!("CLOUD_POINTS: {e}");
            std::process::exit(2);
        }
    };
    let data = pingcal_report::sample::sample_report(n);
    let html = pingcal_report::render_html(&data);
    if let Err(e) = std::fs::write(&out, &html) {
        eprintln!("{out}: {e}");
        std::process::exit(1);
    }
    println!("{out}: {} bytes", html.len());
}
