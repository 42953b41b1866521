//! Where the detector's time goes, stage by stage, on one thread:
//! `bench_stages IMAGE...` prints, summed over the images, the time of decoding, the candidate
//! search (threshold ladder + connected components + shape tests), the centre refinement of
//! every candidate, and the rest of [`Detector::detect`] (code rings, duplicates, kinds), with
//! the counts of candidates, refined centres and targets. Run it with `RAYON_NUM_THREADS=1`
//! for per-image CPU costs.
use pingcal_targets::candidates::find_candidates;
use pingcal_targets::centre::refine;
use pingcal_targets::{detect::BallMode, load_image, DetectParams, Detector};
use std::time::Instant;

fn main() {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        eprintln!("usage: bench_stages IMAGE...");
        std::process::exit(2);
    }
    let det = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .expect("default detector");
    let p = &det.params;
    let (mut t_load, mut t_cand, mut t_ref, mut t_all) = (0.0, 0.0, 0.0, 0.0);
    let (mut n_cand, mut n_ref, mut n_tgt, mut n_id) = (0, 0, 0, 0);
    for path in &paths {
        let t = Instant::now();
        let img = match load_image(std::path::Path::new(path)) {
            Ok(i) => i,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        t_load += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let cands = find_candidates(&img, &p.candidates);
        t_cand += t.elapsed().as_secs_f64();
        let t = Instant::now();
        n_ref += cands
            .iter()
            .filter(|c| refine(&img, &c.seed, &p.centre).is_ok())
            .count();
        t_ref += t.elapsed().as_secs_f64();
        n_cand += cands.len();
        let t = Instant::now();
        let d = det.detect(&img);
        t_all += t.elapsed().as_secs_f64();
        n_tgt += d.targets.len();
        n_id += d.targets.iter().filter(|t| t.id.is_some()).count();
    }
    let n = paths.len() as f64;
    let ms = |s: f64| 1e3 * s / n;
    println!("{} images; per image:", paths.len());
    println!("  decode            {:8.2} ms", ms(t_load));
    println!(
        "  candidates        {:8.2} ms  ({:.0} candidates)",
        ms(t_cand),
        n_cand as f64 / n
    );
    println!(
        "  centre refinement {:8.2} ms  ({:.0} refined)",
        ms(t_ref),
        n_ref as f64 / n
    );
    println!(
        "  rest of detect    {:8.2} ms  ({:.0} targets, {:.0} with IDs)",
        ms(t_all - t_cand - t_ref),
        n_tgt as f64 / n,
        n_id as f64 / n
    );
    println!("  detect in all     {:8.2} ms", ms(t_all));
}
