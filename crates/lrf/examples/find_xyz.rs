//! Times `find_balls` on a text cloud (`x y z` per line) and prints what it found.
//! `cargo run -p pingcal-lrf --release --example find_xyz -- FILE DIAMETER_MM [UNIT=m|mm] [NOISE=VLP-16] [REPEATS=5]`
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::Cloud;
use pingcal_lrf::sensor::RangeNoise;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() < 2 {
        eprintln!("usage: find_xyz FILE DIAMETER_MM [m|mm] [NOISE] [REPEATS]");
        std::process::exit(2);
    }
    let scale = if a.get(2).map_or("m", |s| s.as_str()) == "mm" {
        1.0
    } else {
        1000.0
    };
    let text = std::fs::read_to_string(&a[0]).expect("readable file");
    let pts = text
        .lines()
        .filter_map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .take(3)
                .filter_map(|t| t.parse().ok())
                .collect();
            (v.len() == 3).then(|| nalgebra::Vector3::new(v[0], v[1], v[2]) * scale)
        })
        .collect();
    let cloud = Cloud::from_points(pts);
    let opt = FinderOptions {
        diameter_mm: a[1].parse().expect("a diameter in mm"),
        noise: RangeNoise::named(a.get(3).map_or("VLP-16", |s| s.as_str()))
            .expect("a noise profile"),
        ..Default::default()
    };
    let repeats: usize = a.get(4).map_or(5, |s| s.parse().expect("a count"));
    let mut times = Vec::new();
    let mut found = None;
    for _ in 0..repeats.max(1) {
        let t0 = std::time::Instant::now();
        found = Some(find_balls(&cloud, &opt));
        times.push(t0.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let f = found.unwrap();
    println!(
        "{}: {} points, median {:.1} ms (min {:.1}), {} planes, {} balls",
        a[0],
        cloud.len(),
        1e3 * times[times.len() / 2],
        1e3 * times[0],
        f.planes.len(),
        f.balls.len()
    );
    for b in &f.balls {
        let s = b.cov.diagonal().map(|v| v.sqrt());
        println!(
            "  ball {:.2} {:.2} {:.2}  σ {:.2} {:.2} {:.2} mm, {} rays",
            b.centre.x,
            b.centre.y,
            b.centre.z,
            s.x,
            s.y,
            s.z,
            b.inliers.len()
        );
    }
}
