//! Times the image side of `pingcal sphere-calib` on photographs: `bench_silhouette F_PX CX CY
//! RADIUS_MM [--reps N] [--draw DIR] IMAGE...` (an ideal pinhole camera: focal length and
//! principal point in px; the sphere's radius in mm). Per image: the load, the candidate
//! circles, the silhouette fits, the time of each step (the best of N repetitions), and with
//! `--draw` a PNG of the candidates (blue), the fitted outlines (green), the edge points used
//! (yellow) and those rejected (red). One core: run with `RAYON_NUM_THREADS=1`
//! (`bench/spherecalib/image_side.sh` does).
use pingcal_targets::ball::Pinhole;
use pingcal_targets::silhouette::{self, ColourImage, SilhouetteOptions};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 5 {
        eprintln!("usage: bench_silhouette F_PX CX CY RADIUS_MM [--reps N] [--draw DIR] IMAGE...");
        std::process::exit(2);
    }
    let num = |s: &str| -> f64 {
        s.parse().unwrap_or_else(|_| {
            eprintln!("not a number: {s}");
            std::process::exit(2)
        })
    };
    let cam = Pinhole {
        f: num(&args[0]),
        cx: num(&args[1]),
        cy: num(&args[2]),
    };
    let radius = num(&args[3]);
    let (mut reps, mut draw, mut images) = (1usize, None, Vec::new());
    let mut it = args[4..].iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--reps" => reps = it.next().map_or(1, |v| num(v) as usize).max(1),
            "--draw" => draw = it.next().cloned(),
            _ => images.push(a.clone()),
        }
    }
    for path in &images {
        let (times, (img, cands, fits)) = time_image(path, &cam, radius, reps);
        let [t_load, t_cand, t_fit] = times;
        println!(
            "{path}: load {:.3} s, candidates {:.3} s, candidates + fits {:.3} s (image side {:.3} s)",
            t_load,
            t_cand,
            t_fit,
            t_fit
        );
        print_candidates(&img, &cam, radius, &cands);
        for f in &fits {
            if std::env::var("SILHOUETTE_DEBUG").is_ok() && f.radius_px > 100.0 {
                print_radial_offsets(f);
            }
            print_fit(f);
        }
        if let Some(dir) = &draw {
            save_drawings(dir, path, &img, &cands, &fits);
        }
    }
}

/// An image with its candidate circles and its fits.
type Found = (
    ColourImage,
    Vec<(silhouette::Circle, usize)>,
    Vec<silhouette::Fit>,
);

/// The best of `reps` times of the load, the candidates and the fits of `path`, and the
/// last repetition's image, candidates and fits.
fn time_image(path: &str, cam: &Pinhole, radius: f64, reps: usize) -> ([f64; 3], Found) {
    let (mut t_load, mut t_cand, mut t_fit) = (f64::MAX, f64::MAX, f64::MAX);
    let mut last = None;
    for _ in 0..reps {
        let t0 = Instant::now();
        let img = match pingcal_targets::load_colour(std::path::Path::new(path)) {
            Ok(i) => i,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let t1 = Instant::now();
        let opts = SilhouetteOptions::new(radius, img.width(), img.height());
        let cands = silhouette::candidates(&img, &opts);
        let t2 = Instant::now();
        let fits = silhouette::find_silhouettes(&img, cam, &opts);
        let t3 = Instant::now();
        t_load = t_load.min((t1 - t0).as_secs_f64());
        t_cand = t_cand.min((t2 - t1).as_secs_f64());
        // find_silhouettes finds the candidates again: its own time less theirs
        t_fit = t_fit.min((t3 - t2).as_secs_f64());
        last = Some((img, cands, fits));
    }
    let (img, cands, fits): Found = last.expect("one repetition");
    ([t_load, t_cand, t_fit], (img, cands, fits))
}

/// The first ten candidate circles (and, with `SILHOUETTE_DEBUG`, each one's own fit).
fn print_candidates(
    img: &ColourImage,
    cam: &Pinhole,
    radius: f64,
    cands: &[(silhouette::Circle, usize)],
) {
    for (c, s) in cands.iter().take(10) {
        println!(
            "  circle ({:.1}, {:.1}) r {:.1} px, support {:.2}, scale {s}",
            c.cx, c.cy, c.r, c.support
        );
        if std::env::var("SILHOUETTE_DEBUG").is_ok() {
            let c0 = silhouette::centre_of_circle(c, cam, radius);
            let f = c0.and_then(|c0| {
                silhouette::refine::refine(img, cam, radius, c0, silhouette::start_width(c, *s))
            });
            match f {
                Some(f) => println!(
                    "    → ({:.1}, {:.1}) r {:.1}, coverage {:.2}, rms {:.2}",
                    f.image_centre.0, f.image_centre.1, f.radius_px, f.coverage, f.rms_px
                ),
                None => println!("    → no fit (start {c0:?})"),
            }
        }
    }
}

/// The mean radial offset of a fit's edge points from its outline, per 30° sector.
fn print_radial_offsets(f: &silhouette::Fit) {
    // mean radial offset of the edge points from the fitted outline, per 30° sector
    let mut sec = [(0.0f64, 0usize); 12];
    for &(x, y) in &f.edges {
        let (dx, dy) = (x - f.image_centre.0, y - f.image_centre.1);
        let a = dy.atan2(dx).to_degrees().rem_euclid(360.0);
        let k = (a / 30.0) as usize % 12;
        let rr = dx.hypot(dy);
        // the outline's radius in that direction
        let ro = f
            .outline
            .iter()
            .map(|o| (o.0 - f.image_centre.0, o.1 - f.image_centre.1))
            .min_by(|p, q| {
                let ap = (p.1.atan2(p.0) - dy.atan2(dx)).sin().abs();
                let aq = (q.1.atan2(q.0) - dy.atan2(dx)).sin().abs();
                ap.total_cmp(&aq)
            })
            .map_or(0.0, |o| o.0.hypot(o.1));
        sec[k].0 += rr - ro;
        sec[k].1 += 1;
    }
    println!(
        "  radial offsets by sector (0° = right, 90° = down): {}",
        sec.iter()
            .enumerate()
            .map(|(k, (s, n))| format!("{}°:{:+.2}({})", k * 30, s / (*n).max(1) as f64, n))
            .collect::<Vec<_>>()
            .join(" ")
    );
}

/// One fit: its image centre and radius, its 3D centre with σ, coverage, RMS and edges.
fn print_fit(f: &silhouette::Fit) {
    println!(
    "  fit: image centre ({:.2}, {:.2}), r {:.2} px, centre ({:.1}, {:.1}, {:.1}) mm ± ({:.1}, {:.1}, {:.1}), coverage {:.2}, visible {:.2}, rms {:.3} px, blur {:.2} px, {} edges, {} rejected",
    f.image_centre.0,
    f.image_centre.1,
    f.radius_px,
    f.centre.x,
    f.centre.y,
    f.centre.z,
    f.cov[(0, 0)].sqrt(),
    f.cov[(1, 1)].sqrt(),
    f.cov[(2, 2)].sqrt(),
    f.coverage,
    f.visible,
    f.rms_px,
    f.sigma_blur_px,
    f.edges.len(),
    f.rejected.len()
);
}

/// With `--draw DIR`: the drawing of `path`'s candidates and fits, an optional zoom
/// (`SILHOUETTE_ZOOM=x,y,size`) and each fit's neighbourhood at full resolution.
fn save_drawings(
    dir: &str,
    path: &str,
    img: &ColourImage,
    cands: &[(silhouette::Circle, usize)],
    fits: &[silhouette::Fit],
) {
    let name = std::path::Path::new(path)
        .file_stem()
        .map_or("image".into(), |s| s.to_string_lossy().into_owned());
    let out = std::path::Path::new(dir).join(format!("{name}_silhouette.png"));
    let d = drawing(img, cands, fits);
    if let Ok(z) = std::env::var("SILHOUETTE_ZOOM") {
        // x,y,size: that square of the drawing, enlarged 4 times
        let v: Vec<u32> = z.split(',').filter_map(|t| t.parse().ok()).collect();
        if v.len() == 3 {
            let crop = image::imageops::crop_imm(&d, v[0], v[1], v[2], v[2]).to_image();
            let big = image::imageops::resize(
                &crop,
                4 * v[2],
                4 * v[2],
                image::imageops::FilterType::Nearest,
            );
            let _ = big.save(std::path::Path::new(dir).join(format!("{name}_zoom.png")));
        }
    }
    d.save(&out)
        .unwrap_or_else(|e| eprintln!("{}: {e}", out.display()));
    // each fit's neighbourhood at full resolution
    for (k, f) in fits.iter().enumerate() {
        let r = 1.25 * f.radius_px + 10.0;
        let x0 = (f.image_centre.0 - r).max(0.0) as u32;
        let y0 = (f.image_centre.1 - r).max(0.0) as u32;
        let x1 = ((f.image_centre.0 + r) as u32).min(d.width() - 1);
        let y1 = ((f.image_centre.1 + r) as u32).min(d.height() - 1);
        if x1 > x0 && y1 > y0 {
            let crop = image::imageops::crop_imm(&d, x0, y0, x1 - x0, y1 - y0).to_image();
            let p = std::path::Path::new(dir).join(format!("{name}_fit{k}.png"));
            let _ = crop.save(p);
        }
    }
}

/// The image in grey with the candidates, outlines and edge points drawn.
fn drawing(
    img: &ColourImage,
    cands: &[(silhouette::Circle, usize)],
    fits: &[silhouette::Fit],
) -> image::RgbImage {
    let grey = img.luminance();
    let (w, h) = (grey.width as u32, grey.height as u32);
    let mut out = image::RgbImage::from_fn(w, h, |x, y| {
        let v = (grey.get(x as usize, y as usize).clamp(0.0, 1.0) * 200.0 + 30.0) as u8;
        image::Rgb([v, v, v])
    });
    let mut dot = |x: f64, y: f64, c: [u8; 3]| {
        if x >= 0.0 && y >= 0.0 && x < w as f64 - 0.5 && y < h as f64 - 0.5 {
            out.put_pixel(x.round() as u32, y.round() as u32, image::Rgb(c));
        }
    };
    for (c, _) in cands {
        for k in 0..720 {
            let t = std::f64::consts::TAU * k as f64 / 720.0;
            dot(c.cx + c.r * t.cos(), c.cy + c.r * t.sin(), [60, 120, 255]);
        }
    }
    for f in fits {
        for &(x, y) in &f.outline {
            dot(x, y, [0, 255, 0]);
        }
        for &(x, y) in &f.rejected {
            dot(x, y, [255, 0, 0]);
        }
        for &(x, y) in &f.edges {
            dot(x, y, [255, 255, 0]);
        }
    }
    out
}
