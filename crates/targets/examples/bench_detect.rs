//! Times `detect` (load + detection) on images and writes the centres, for the OpenCV
//! comparison in `bench/targets`: `bench_detect OUT.json IMAGE...`. Images are loaded and
//! detected with [`detect_files`] (in parallel over the images as well as within each; the
//! thread count is rayon's, `RAYON_NUM_THREADS`).
use pingcal_targets::{detect::BallMode, detect_files, DetectParams, Detector};

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
    let paths = &args[1..];
    let t0 = std::time::Instant::now();
    let results = detect_files(paths, &det);
    let total_s = t0.elapsed().as_secs_f64();
    let mut out = Vec::new();
    for (path, d) in paths.iter().zip(results) {
        let d = match d {
            Ok(d) => d,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let centres: Vec<[f64; 2]> = d.targets.iter().map(|t| [t.x, t.y]).collect();
        let centroids: Vec<[f64; 2]> = d.targets.iter().map(|t| t.centroid).collect();
        out.push(serde_json::json!({
            "file": path, "batch_s": total_s,
            "centres": centres, "centroids": centroids,
            "ids": d.targets.iter().filter(|t| t.id.is_some()).count(),
        }));
    }
    if let Err(e) = std::fs::write(&args[0], serde_json::to_string(&out).unwrap_or_default()) {
        eprintln!("{}: {e}", args[0]);
        std::process::exit(1);
    }
}
