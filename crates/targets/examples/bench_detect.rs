//! Times `detect` (load + detection) on images and writes the centres, for the OpenCV
//! comparison in `bench/targets`: `bench_detect OUT.json IMAGE...`.
use pingcal_targets::{detect::BallMode, load_image, DetectParams, Detector};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: bench_detect OUT.json IMAGE...");
        std::process::exit(2);
    }
    let det = match Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    }) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let mut out = Vec::new();
    for path in &args[1..] {
        let t0 = std::time::Instant::now();
        let img = match load_image(std::path::Path::new(path)) {
            Ok(i) => i,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let t1 = std::time::Instant::now();
        let d = det.detect(&img);
        let t2 = std::time::Instant::now();
        let centres: Vec<[f64; 2]> = d.targets.iter().map(|t| [t.x, t.y]).collect();
        let centroids: Vec<[f64; 2]> = d.targets.iter().map(|t| t.centroid).collect();
        out.push(serde_json::json!({
            "file": path, "load_s": (t1 - t0).as_secs_f64(), "detect_s": (t2 - t1).as_secs_f64(),
            "centres": centres, "centroids": centroids,
            "ids": d.targets.iter().filter(|t| t.id.is_some()).count(),
        }));
    }
    if let Err(e) = std::fs::write(&args[0], serde_json::to_string(&out).unwrap_or_default()) {
        eprintln!("{}: {e}", args[0]);
        std::process::exit(1);
    }
}
