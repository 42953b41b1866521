//! Times `detect` (load + detection) on images and writes the centres, for the OpenCV
//! comparison in `bench/targets`: `bench_detect OUT.json IMAGE...`. The next image is decoded
//! while the current one is detected.
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
    // Decoding is single-threaded: the next image is loaded on its own thread while the
    // current one is detected (at most one image waiting).
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    let paths = &args[1..];
    std::thread::scope(|s| {
        s.spawn(move || {
            for path in paths {
                let t0 = std::time::Instant::now();
                let img = load_image(std::path::Path::new(path));
                let load_s = t0.elapsed().as_secs_f64();
                let failed = img.is_err();
                if tx.send((path, img, load_s)).is_err() || failed {
                    break;
                }
            }
        });
        for (path, img, load_s) in rx {
            let img = match img {
                Ok(i) => i,
                Err(e) => {
                    eprintln!("{e}");
                    std::process::exit(1);
                }
            };
            let t1 = std::time::Instant::now();
            let d = det.detect(&img);
            let detect_s = t1.elapsed().as_secs_f64();
            let centres: Vec<[f64; 2]> = d.targets.iter().map(|t| [t.x, t.y]).collect();
            let centroids: Vec<[f64; 2]> = d.targets.iter().map(|t| t.centroid).collect();
            out.push(serde_json::json!({
                "file": path, "load_s": load_s, "detect_s": detect_s,
                "centres": centres, "centroids": centroids,
                "ids": d.targets.iter().filter(|t| t.id.is_some()).count(),
            }));
        }
    });
    if let Err(e) = std::fs::write(&args[0], serde_json::to_string(&out).unwrap_or_default()) {
        eprintln!("{}: {e}", args[0]);
        std::process::exit(1);
    }
}
