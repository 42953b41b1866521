//! Rendered images with known truth: centre bias and σ of the ellipse fit and of the
//! intensity-weighted centroid (sizes 6–60 px, tilt up to 70°, blur, noise), and the ping-pong
//! ball centre with and without the eccentricity correction.
//!
//! Run `cargo test -p pingcal-targets --release --test targets synthetic:: -- --nocapture` for the tables.

use pingcal_geometry::consensus::SeededRng;
use pingcal_targets::ball::{sphere_centre_from_ellipse, Pinhole};
use pingcal_targets::detect::BallMode;
use pingcal_targets::ellipse::Ellipse;
use pingcal_targets::{DetectParams, Detector, GrayImage, TargetKind};
use rand::Rng;
use rand_distr::{Distribution, Normal};

fn gaussian_blur(img: &mut GrayImage, sigma: f64) {
    if sigma <= 0.0 {
        return;
    }
    let r = (3.0 * sigma).ceil() as isize;
    let k: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let s: f32 = k.iter().sum();
    let k: Vec<f32> = k.iter().map(|v| v / s).collect();
    let (w, h) = (img.width as isize, img.height as isize);
    let mut tmp = img.data.clone();
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let xx = (x + j as isize - r).clamp(0, w - 1);
                acc += kv * img.data[(y * w + xx) as usize];
            }
            tmp[(y * w + x) as usize] = acc;
        }
    }
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (j, kv) in k.iter().enumerate() {
                let yy = (y + j as isize - r).clamp(0, h - 1);
                acc += kv * tmp[(yy * w + x) as usize];
            }
            img.data[(y * w + x) as usize] = acc;
        }
    }
}

fn add_noise(img: &mut GrayImage, sigma: f64, rng: &mut SeededRng) {
    let n = Normal::new(0.0, sigma).unwrap();
    for v in &mut img.data {
        *v += n.sample(rng) as f32;
    }
}

/// A bright ellipse (fg) on a dark background, 8×8 supersampling per pixel.
fn render_ellipse(w: usize, h: usize, e: &Ellipse, fg: f32, bg: f32) -> GrayImage {
    let mut img = GrayImage::new(w, h, bg);
    const SS: usize = 8;
    let x0 = (e.cx - e.a - 2.0).floor().max(0.0) as usize;
    let x1 = ((e.cx + e.a + 2.0).ceil() as usize).min(w - 1);
    let y0 = (e.cy - e.a - 2.0).floor().max(0.0) as usize;
    let y1 = ((e.cy + e.a + 2.0).ceil() as usize).min(h - 1);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let mut c = 0;
            for sy in 0..SS {
                for sx in 0..SS {
                    let px = x as f64 - 0.5 + (sx as f64 + 0.5) / SS as f64;
                    let py = y as f64 - 0.5 + (sy as f64 + 0.5) / SS as f64;
                    let (u, v) = e.unmap(px, py);
                    if u * u + v * v <= 1.0 {
                        c += 1;
                    }
                }
            }
            img.data[y * w + x] = bg + (fg - bg) * c as f32 / (SS * SS) as f32;
        }
    }
    img
}

struct Stats {
    n: usize,
    mean: [f64; 2],
    sd: [f64; 2],
}

fn stats(errs: &[[f64; 2]]) -> Stats {
    let n = errs.len();
    let mut mean = [0.0; 2];
    for e in errs {
        mean[0] += e[0] / n as f64;
        mean[1] += e[1] / n as f64;
    }
    let mut sd = [0.0; 2];
    for e in errs {
        sd[0] += (e[0] - mean[0]).powi(2) / (n as f64 - 1.0).max(1.0);
        sd[1] += (e[1] - mean[1]).powi(2) / (n as f64 - 1.0).max(1.0);
    }
    Stats {
        n,
        mean,
        sd: [sd[0].sqrt(), sd[1].sqrt()],
    }
}

#[test]
fn centre_bias_and_sigma_on_rendered_ellipses() {
    let det = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .unwrap();
    let mut rng = pingcal_geometry::consensus::rng(2024);
    const TRIALS: usize = 16;
    println!("| diameter px | tilt ° | blur σ px | noise σ | detected | ellipse bias x, y px | ellipse σ px | reported σ px | centroid bias x, y px | centroid σ px | reported centroid σ px |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for &d in &[6.0, 12.0, 30.0, 60.0] {
        for &tilt in &[0.0f64, 45.0, 70.0] {
            for &blur in &[0.0, 1.0, 2.0] {
                for &noise in &[0.01, 0.03] {
                    let mut el = Vec::new();
                    let mut ce = Vec::new();
                    let mut rep = 0.0;
                    let mut rep_c = 0.0;
                    for _ in 0..TRIALS {
                        let size = ((d * 1.6) as usize + 40).max(64);
                        let e = Ellipse {
                            cx: size as f64 / 2.0 + rng.random_range(-0.5..0.5),
                            cy: size as f64 / 2.0 + rng.random_range(-0.5..0.5),
                            a: d / 2.0,
                            b: d / 2.0 * tilt.to_radians().cos(),
                            theta: rng.random_range(-1.5..1.5),
                        };
                        let mut img = render_ellipse(size, size, &e, 0.7, 0.1);
                        gaussian_blur(&mut img, blur);
                        add_noise(&mut img, noise, &mut rng);
                        let r = det.detect(&img);
                        let best = r
                            .targets
                            .iter()
                            .filter(|t| t.kind == TargetKind::Plain)
                            .min_by(|a, b| {
                                let da = (a.x - e.cx).hypot(a.y - e.cy);
                                let db = (b.x - e.cx).hypot(b.y - e.cy);
                                da.total_cmp(&db)
                            });
                        if let Some(t) = best {
                            if (t.x - e.cx).hypot(t.y - e.cy) < 0.5 * e.b.max(1.0) {
                                el.push([t.x - e.cx, t.y - e.cy]);
                                ce.push([t.centroid[0] - e.cx, t.centroid[1] - e.cy]);
                                rep += t.sigma_px;
                                rep_c += t.sigma_centroid_px;
                            }
                        }
                    }
                    let minor = d / 2.0 * tilt.to_radians().cos() * 2.0;
                    if el.len() < 3 {
                        println!("| {d} | {tilt} | {blur} | {noise} | {}/{TRIALS} | – | – | – | – | – | – |", el.len());
                        // Below 4 px of minor axis nothing is promised; above, detection is.
                        if minor >= 4.0 {
                            failures.push(format!(
                                "d={d} tilt={tilt} blur={blur} noise={noise}: not detected"
                            ));
                        }
                        continue;
                    }
                    let s = stats(&el);
                    let c = stats(&ce);
                    let sd = (s.sd[0].powi(2) + s.sd[1].powi(2)).sqrt() / std::f64::consts::SQRT_2;
                    let csd = (c.sd[0].powi(2) + c.sd[1].powi(2)).sqrt() / std::f64::consts::SQRT_2;
                    let n = s.n as f64;
                    println!(
                        "| {d} | {tilt} | {blur} | {noise} | {}/{TRIALS} | {:+.3}, {:+.3} | {:.3} | {:.3} | {:+.3}, {:+.3} | {:.3} | {:.3} |",
                        s.n,
                        s.mean[0],
                        s.mean[1],
                        sd,
                        rep / n,
                        c.mean[0],
                        c.mean[1],
                        csd,
                        rep_c / n
                    );
                    // Bias: the mean of n errors has standard error σ/√n; a bias is flagged when
                    // it exceeds 4 standard errors plus 0.02 px (the accuracy asked of a target
                    // measurement is ~0.05 px).
                    for k in 0..2 {
                        if s.mean[k].abs() > 0.02 + 4.0 * s.sd[k] / n.sqrt() {
                            failures.push(format!(
                                "d={d} tilt={tilt} blur={blur} noise={noise}: ellipse bias {:.3}",
                                s.mean[k]
                            ));
                        }
                    }
                    if minor >= 4.0 && s.n < TRIALS * 3 / 4 {
                        failures.push(format!("d={d} tilt={tilt} blur={blur} noise={noise}: detected only {}/{TRIALS}", s.n));
                    }
                    // Precision: the centre σ of an edge fit is about σ_edge·√(2/N) with
                    // σ_edge ≈ σ_noise·(edge width)/contrast and N the perimeter in pixels; at the
                    // worst noise here (SNR 20) and a 2-px blur that is ≈ 0.03·5/0.6·√(2/N):
                    // under 0.1 px once N ≥ 30 (minor axis ≥ 10 px), under 0.2 px for the
                    // smallest targets. The reported σ must be within a factor 3 of the empirical
                    // one (a σ estimated from 16 trials is itself uncertain by ~18 %).
                    // Below 4 px of minor axis (where detection is not promised either) the
                    // blur eats the plateau, the contrast and with it the edge precision: no
                    // precision bound there, only the reported-σ check.
                    let sd_bound = if minor >= 10.0 { 0.1 } else { 0.2 };
                    if minor >= 4.0 && sd > sd_bound {
                        failures.push(format!(
                            "d={d} tilt={tilt} blur={blur} noise={noise}: ellipse σ {sd:.3}"
                        ));
                    }
                    let ratio = (rep / n) / sd.max(1e-4);
                    if noise >= 0.03 && !(1.0 / 3.0..=3.0).contains(&ratio) {
                        failures.push(format!("d={d} tilt={tilt} blur={blur} noise={noise}: reported σ {:.3} vs empirical {sd:.3}", rep / n));
                    }
                    let _ = csd;
                }
            }
        }
    }
    for f in &failures {
        println!("FAIL: {f}");
    }
    assert!(failures.is_empty(), "{} failures", failures.len());
}

/// Renders a sphere (radius `r`, centre `c` in camera coordinates, x right, y down, z forward)
/// seen by a pinhole camera, shaded as under a flash at the camera: I = bg + (fg − bg)(0.3 +
/// 0.7 cos θ), θ the angle between the surface normal and the ray; 4×4 supersampling with exact
/// ray–sphere intersection.
fn render_sphere(cam: &Pinhole, w: usize, h: usize, c: [f64; 3], r: f64) -> GrayImage {
    let (fg, bg) = (0.85f32, 0.15f32);
    let mut img = GrayImage::new(w, h, bg);
    let d = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    let proj = [cam.cx + cam.f * c[0] / c[2], cam.cy + cam.f * c[1] / c[2]];
    let rad = cam.f * r / (c[2] - r) * 2.5 * d / c[2];
    const SS: usize = 4;
    let x0 = (proj[0] - rad).floor().max(0.0) as usize;
    let x1 = ((proj[0] + rad).ceil() as usize).min(w - 1);
    let y0 = (proj[1] - rad).floor().max(0.0) as usize;
    let y1 = ((proj[1] + rad).ceil() as usize).min(h - 1);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let mut acc = 0.0;
            for sy in 0..SS {
                for sx in 0..SS {
                    let px = x as f64 - 0.5 + (sx as f64 + 0.5) / SS as f64;
                    let py = y as f64 - 0.5 + (sy as f64 + 0.5) / SS as f64;
                    let q = [(px - cam.cx) / cam.f, (py - cam.cy) / cam.f, 1.0];
                    let qn = (q[0] * q[0] + q[1] * q[1] + 1.0).sqrt();
                    let q = [q[0] / qn, q[1] / qn, q[2] / qn];
                    let b = q[0] * c[0] + q[1] * c[1] + q[2] * c[2];
                    let disc = b * b - (d * d - r * r);
                    if disc < 0.0 {
                        acc += bg;
                        continue;
                    }
                    let t = b - disc.sqrt();
                    let p = [q[0] * t - c[0], q[1] * t - c[1], q[2] * t - c[2]];
                    let cos = -(p[0] * q[0] + p[1] * q[1] + p[2] * q[2]) / r;
                    acc += bg + (fg - bg) * (0.3 + 0.7 * cos.max(0.0) as f32);
                }
            }
            img.data[y * w + x] = acc / (SS * SS) as f32;
        }
    }
    img
}

#[test]
fn ball_centre_with_and_without_eccentricity_correction() {
    let det = Detector::new(DetectParams {
        balls: BallMode::Diameter {
            min_px: 8.0,
            max_px: 500.0,
        },
        ..DetectParams::default()
    })
    .unwrap();
    let mut rng = pingcal_geometry::consensus::rng(7);
    let r = 19.0; // 38 mm ping-pong ball
    println!("| f px | distance mm | off-axis px | uncorrected error px | corrected error px | distance from cone mm |");
    println!("|---|---|---|---|---|---|");
    let mut worst_corr: f64 = 0.0;
    let mut sum_unc = 0.0;
    let mut sum_cor = 0.0;
    let mut count = 0;
    for &f in &[650.0, 1500.0] {
        let cam = Pinhole {
            f,
            cx: 639.5,
            cy: 359.5,
        };
        for &z in &[500.0, 1000.0] {
            for &(u, v) in &[(0.0, 0.0), (300.0, 150.0), (-500.0, 250.0), (480.0, -200.0)] {
                let (u, v): (f64, f64) = (
                    u + rng.random_range(-0.5..0.5),
                    v + rng.random_range(-0.5..0.5),
                );
                let c = [u / f * z, v / f * z, z];
                let truth = [cam.cx + u, cam.cy + v];
                let mut img = render_sphere(&cam, 1280, 720, c, r);
                gaussian_blur(&mut img, 0.7);
                add_noise(&mut img, 0.01, &mut rng);
                let res = det.detect(&img);
                let ball = res
                    .targets
                    .iter()
                    .filter(|t| t.kind == TargetKind::Ball)
                    .min_by(|a, b| {
                        (a.x - truth[0])
                            .hypot(a.y - truth[1])
                            .total_cmp(&(b.x - truth[0]).hypot(b.y - truth[1]))
                    })
                    .unwrap_or_else(|| panic!("ball not detected: f={f} z={z} at {truth:?}"));
                let unc = (ball.x - truth[0]).hypot(ball.y - truth[1]);
                let s = sphere_centre_from_ellipse(&ball.ellipse, &cam, Some(r)).expect("cone fit");
                let cor = (s.x - truth[0]).hypot(s.y - truth[1]);
                let dist = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                println!(
                    "| {f} | {z} | {:.0} | {unc:.3} | {cor:.3} | {:.1} (true {dist:.1}) |",
                    u.hypot(v),
                    s.distance.unwrap()
                );
                worst_corr = worst_corr.max(cor);
                sum_unc += unc;
                sum_cor += cor;
                count += 1;
            }
        }
    }
    // The distance from the cone angle is biased long (a few %) because the mid-level edge of a
    // shaded sphere lies inside its true limb; the axis, and so the corrected centre, is not.
    println!(
        "mean error: uncorrected {:.3} px, corrected {:.3} px",
        sum_unc / count as f64,
        sum_cor / count as f64
    );
    // The correction is exact for an ideal silhouette; what remains is the edge-fit error, well
    // under 0.1 px for these 12–70 px balls with noise 0.01 and a shaded limb.
    assert!(worst_corr < 0.1, "corrected error up to {worst_corr:.3} px");
    assert!(sum_cor < 0.3 * sum_unc, "correction does not help enough");
}

/// Printed targets (the geometry of `printable`) seen under a perspective tilt decode to their
/// numbers: rendering → detection → ID.
#[test]
// The sampling ranges 0..6.28 and 0..3.14 are literal (changing them would change the seeded
// draws and the test's figures).
#[allow(clippy::approx_constant)]
fn printed_targets_decode_to_their_numbers() {
    use pingcal_targets::aicon::CodeTable;
    use pingcal_targets::printable::target_is_white;
    let table = CodeTable::generate(14).unwrap();
    let det = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .unwrap();
    let mut rng = pingcal_geometry::consensus::rng(99);
    let mut ok = 0;
    let mut wrong = 0;
    let n = 40;
    for k in 0..n {
        let id = 2 + (k * 13) % 500;
        let code = table.code(id).unwrap();
        // Target plane → image: rotation about the target normal, tilt up to 60° about a random
        // axis (a foreshortening), scale (dot radius 5–12 px), projective term.
        let rad = rng.random_range(5.0..12.0);
        let rot: f64 = rng.random_range(0.0..6.28);
        let tilt: f64 = rng.random_range(0.0f64..60.0).to_radians();
        let axis: f64 = rng.random_range(0.0..3.14);
        let (w, h) = (160usize, 160usize);
        let mut img = GrayImage::new(w, h, 0.35);
        let (ca, sa) = (axis.cos(), axis.sin());
        // Inverse map image → target plane for rendering: undo the translation and scale, then
        // stretch along the tilt axis by 1/cos(tilt), then undo the in-plane rotation.
        const SS: usize = 4;
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for sy in 0..SS {
                    for sx in 0..SS {
                        let px = (x as f64 - 0.5 + (sx as f64 + 0.5) / SS as f64 - 80.0) / rad;
                        let py = (y as f64 - 0.5 + (sy as f64 + 0.5) / SS as f64 - 80.0) / rad;
                        // Components along / across the tilt axis.
                        let along = px * ca + py * sa;
                        let across = (-px * sa + py * ca) / tilt.cos();
                        let (qx, qy) = (along * ca - across * sa, along * sa + across * ca);
                        let (u, v) = (
                            qx * rot.cos() + qy * rot.sin(),
                            -qx * rot.sin() + qy * rot.cos(),
                        );
                        let white =
                            u.abs() <= 4.0 && v.abs() <= 4.0 && target_is_white(code, 14, u, v);
                        let black = u.abs() <= 4.0 && v.abs() <= 4.0;
                        acc += if white {
                            0.8
                        } else if black {
                            0.05
                        } else {
                            0.35
                        };
                    }
                }
                img.data[y * w + x] = acc / (SS * SS) as f32;
            }
        }
        gaussian_blur(&mut img, 0.8);
        add_noise(&mut img, 0.01, &mut rng);
        let r = det.detect(&img);
        match r
            .targets
            .iter()
            .find(|t| t.kind == TargetKind::Coded && t.id.is_some())
        {
            Some(t) if t.id == Some(id) => ok += 1,
            Some(t) => {
                println!("WRONG: id {id} read as {:?}", t.id);
                wrong += 1
            }
            None => println!(
                "missed id {id} (dot radius {rad:.1} px, tilt {:.0}°)",
                tilt.to_degrees()
            ),
        }
    }
    println!("printed targets: {ok}/{n} decoded, {wrong} wrong");
    assert_eq!(wrong, 0);
    assert!(ok >= n * 3 / 4, "only {ok}/{n} decoded");
}

/// A printed target (the code of `id`, 14 bits) as the camera sees it: dot radius `rad` px,
/// in-plane rotation `rot`, tilt `tilt` about the axis at angle `axis`, centred in a square
/// image, 4×4 supersampled, then blurred by a Gaussian of σ `blur` px and given noise σ 0.01.
fn render_printed(
    code: u32,
    rad: f64,
    rot: f64,
    tilt: f64,
    axis: f64,
    blur: f64,
    rng: &mut SeededRng,
) -> GrayImage {
    let ring = pingcal_targets::printable::RING;
    render_printed_with_ring(code, rad, [rot, tilt, axis], blur, ring, rng)
}

/// [`render_printed`] with a code ring from `ring.0` to `ring.1` dot radii on a black square
/// of half-side max(4, `ring.1` + 1) dot radii; `[rot, tilt, axis]` as there.
fn render_printed_with_ring(
    code: u32,
    rad: f64,
    [rot, tilt, axis]: [f64; 3],
    blur: f64,
    ring: (f64, f64),
    rng: &mut SeededRng,
) -> GrayImage {
    let half = (ring.1 + 1.0).max(4.0);
    let target_is_white = |code, bits, u, v| {
        pingcal_targets::printable::target_is_white_with_ring(code, bits, u, v, ring)
    };
    let w = (2.5 * half * rad).ceil() as usize + 20;
    let c = 0.5 * w as f64;
    let mut img = GrayImage::new(w, w, 0.35);
    let (ca, sa) = (axis.cos(), axis.sin());
    const SS: usize = 4;
    for y in 0..w {
        for x in 0..w {
            let mut acc = 0.0;
            for sy in 0..SS {
                for sx in 0..SS {
                    let px = (x as f64 - 0.5 + (sx as f64 + 0.5) / SS as f64 - c) / rad;
                    let py = (y as f64 - 0.5 + (sy as f64 + 0.5) / SS as f64 - c) / rad;
                    let along = px * ca + py * sa;
                    let across = (-px * sa + py * ca) / tilt.cos();
                    let (qx, qy) = (along * ca - across * sa, along * sa + across * ca);
                    let (u, v) = (
                        qx * rot.cos() + qy * rot.sin(),
                        -qx * rot.sin() + qy * rot.cos(),
                    );
                    let inside = u.abs() <= half && v.abs() <= half;
                    acc += if inside && target_is_white(code, 14, u, v) {
                        0.8
                    } else if inside {
                        0.05
                    } else {
                        0.35
                    };
                }
            }
            img.data[y * w + x] = acc / (SS * SS) as f32;
        }
    }
    gaussian_blur(&mut img, blur);
    add_noise(&mut img, 0.01, rng);
    img
}

/// The ring reader against blur and dot size: rendered targets (random IDs, rotations, tilts
/// up to 45°) at blur σ 0.5–2 px and dot radius 3–20 px; the reading rate per cell is printed
/// (`-- --nocapture`) and no ID may be wrong anywhere.
#[test]
fn ring_reading_rate_against_blur_and_dot_radius() {
    use pingcal_targets::aicon::CodeTable;
    let table = CodeTable::generate(14).unwrap();
    let det = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .unwrap();
    let mut rng = pingcal_geometry::consensus::rng(1919);
    const TRIALS: usize = 12;
    let blurs = [0.5, 0.75, 0.9, 1.2, 1.5, 2.0];
    let radii = [3.0, 3.5, 4.0, 6.0, 10.0, 20.0];
    println!(
        "| dot radius px | {} |",
        blurs.map(|b| format!("blur {b} px")).join(" | ")
    );
    println!("|---|{}", "---|".repeat(blurs.len()));
    let mut wrong = Vec::new();
    let mut rate = std::collections::BTreeMap::new();
    for &rad in &radii {
        let mut row = Vec::new();
        for &blur in &blurs {
            let mut ok = 0;
            for _ in 0..TRIALS {
                let id = rng.random_range(1..=table.codes.len() as u32);
                let rot: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let tilt: f64 = rng.random_range(0.0f64..45.0).to_radians();
                let axis: f64 = rng.random_range(0.0..std::f64::consts::PI);
                let img = render_printed(
                    table.code(id).unwrap(),
                    rad,
                    rot,
                    tilt,
                    axis,
                    blur,
                    &mut rng,
                );
                let r = det.detect(&img);
                for t in r.targets.iter().filter(|t| t.kind == TargetKind::Coded) {
                    match t.id {
                        Some(got) if got == id => ok += 1,
                        Some(got) => {
                            wrong.push(format!("rad {rad} blur {blur}: id {id} read as {got}"))
                        }
                        None => {}
                    }
                }
            }
            rate.insert((rad.to_string(), blur.to_string()), ok);
            row.push(format!("{ok}/{TRIALS}"));
        }
        println!("| {rad} | {} |", row.join(" | "));
    }
    assert!(wrong.is_empty(), "wrong IDs: {wrong:?}");
    // The small dots of a real head's images (3.5–4 px) through the blur of a hand-held shot
    // (≤ 1.2 px): the blurred-ring model must read nearly all (at most 2 of 12 missed; the
    // sharp thresholds alone read 0–1 of 12 at 0.9–1.2 px).
    for rad in ["3.5", "4"] {
        for blur in ["0.5", "0.75", "0.9", "1.2"] {
            let ok = rate[&(rad.to_string(), blur.to_string())];
            assert!(
                ok + 2 >= TRIALS,
                "dot radius {rad} px, blur {blur} px: {ok}/{TRIALS} read"
            );
        }
    }
    // Large sharp targets must all be read (a regression of the reader, not a hard case).
    for rad in ["6", "10", "20"] {
        for blur in ["0.5", "0.75", "0.9", "1.2"] {
            let ok = rate[&(rad.to_string(), blur.to_string())];
            assert!(
                ok == TRIALS,
                "dot radius {rad} px, blur {blur} px: {ok}/{TRIALS} read"
            );
        }
    }
}

/// `[targets] ring_inner` and `ring_outer` are used: targets printed with a ring from 2.5 to
/// 4 dot radii (not AICON's 2 to 3) are read by the detector told so, and never misread by
/// the one that expects AICON's ring.
#[test]
fn a_ring_of_another_size_is_read_when_the_project_gives_it() {
    use pingcal_targets::aicon::CodeTable;
    let table = CodeTable::generate(14).unwrap();
    let detector = |ring| {
        Detector::new(DetectParams {
            balls: BallMode::Off,
            ring,
            ..DetectParams::default()
        })
        .unwrap()
    };
    let (told, aicon) = (detector((2.5, 4.0)), detector((2.0, 3.0)));
    let mut rng = pingcal_geometry::consensus::rng(2540);
    const TRIALS: usize = 24;
    let (mut read_told, mut read_aicon, mut wrong) = (0, 0, Vec::new());
    for _ in 0..TRIALS {
        let id = rng.random_range(1..=table.codes.len() as u32);
        let rad = rng.random_range(5.0..12.0);
        let pose = [
            rng.random_range(0.0..std::f64::consts::TAU),
            rng.random_range(0.0f64..40.0).to_radians(),
            rng.random_range(0.0..std::f64::consts::PI),
        ];
        let code = table.code(id).unwrap();
        let img = render_printed_with_ring(code, rad, pose, 0.7, (2.5, 4.0), &mut rng);
        for (det, count) in [(&told, &mut read_told), (&aicon, &mut read_aicon)] {
            for t in det
                .detect(&img)
                .targets
                .iter()
                .filter(|t| t.kind == TargetKind::Coded)
            {
                match t.id {
                    Some(got) if got == id => *count += 1,
                    Some(got) => wrong.push(format!("id {id} read as {got}")),
                    None => {}
                }
            }
        }
    }
    println!(
        "ring 2.5–4: {read_told}/{TRIALS} read when told, {read_aicon}/{TRIALS} with AICON's ring"
    );
    assert!(wrong.is_empty(), "wrong IDs: {wrong:?}");
    assert!(
        read_told + 1 >= TRIALS,
        "only {read_told}/{TRIALS} read with the ring given"
    );
    assert!(
        read_aicon < read_told,
        "AICON's ring reads as many ({read_aicon}): the test does not see the ring"
    );
}

#[path = "stress/mod.rs"]
mod stress;

/// The false-read stress test of issue 38: scenes made to tempt the ring decoder (rings
/// partly covered, targets overlapping, rings half in shadow, printed text, checkerboards, all
/// at once; `tests/stress`), over many seeds. The table (scenes, numbers read, wrong per
/// thousand reads, per temptation) is printed with `-- --nocapture`;
/// `PINGCAL_STRESS_SEEDS=600` runs more seeds than the default 300, and
/// `PINGCAL_STRESS_DIR=DIR` writes the overlay of every scene with a wrong read there:
///
/// `PINGCAL_STRESS_SEEDS=600 cargo test -p pingcal-targets --release --test targets synthetic::
/// false_read_stress -- --nocapture`
///
/// No number may be read in the printed text or on the checkerboards. A ring partly covered by
/// something as dark as the target's own black (another target's square, a black bar) can hide
/// whole bright sectors and leave another number's pattern, clean to every margin of
/// `pingcal_targets::confidence`: those reads are wrong in the image itself, and only the
/// network can find them (the pipeline's named blunders). On the default 300 scenes the
/// decoder before issue 38 read 37 wrong in 893 reads (41.4 per thousand), its first margins
/// 30 in 833 (36.0); on 600, 70 in 1,797 (39.0) and 53 in 1,658 (32.0). The `fragment` margin
/// and the refusal of reads whose ring overlaps another ring (`pingcal_targets::detect::
/// RING_OVERLAP_MAX`) bring the 300 to 27 in 820 (32.9), the 600 to 39 in 1,624 (24.0). Most
/// of those were clean to every margin of the ring: a printed target beneath another, a dark
/// bar over bright sectors. The `outline` margin (a target on uniform paper whose dark print
/// reaches beyond its square is refused: the dark thing may lie over its ring) brings the 300
/// to 4 in 521 (7.7), the 600 to 5 in 1,046 (4.8); the upper of two overlapping targets and
/// targets touched by a bar or a line of text go with them (the right reads fall from 1,585 to
/// 1,041 on 600). What is left are rings half in a shadow, whose paper is not uniform. The
/// test holds the rate under 20 per thousand: with 4 wrong reads expected on the 300 scenes, a
/// count of 10 or more (19.2 per thousand of 521) has a Poisson probability under 0.3 %, so
/// a rise past the bound is a change of the decoder, not chance. The targets of the text and
/// checkerboard scenes are clean (the tempters lie around them): at least 85 % of them must be
/// read (93 % and 98 % are).
#[test]
fn false_read_stress() {
    use rayon::prelude::*;
    let seeds: u64 = std::env::var("PINGCAL_STRESS_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(300);
    let dir = std::env::var("PINGCAL_STRESS_DIR").ok();
    let det = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .unwrap();
    let runs: Vec<(&str, usize, usize, Vec<String>)> = (0..seeds)
        .into_par_iter()
        .map(|seed| {
            let s = stress::scene(38_000 + seed);
            let found = det.detect(&s.image);
            let (read, mut wrong) = stress::score(&s, &found);
            for w in &mut wrong {
                *w = format!("seed {seed}, {w}");
            }
            if let (Some(dir), false) = (&dir, wrong.is_empty()) {
                let ov = pingcal_targets::overlay::draw_detections_and_refusals(&s.image, &found);
                ov.save(&std::path::Path::new(dir).join(format!("stress-{seed}.png")))
                    .unwrap();
            }
            (s.kind, s.targets.len(), read, wrong)
        })
        .collect();
    println!(
        "| temptation | scenes | targets drawn | numbers read | wrong | wrong per 1000 reads |"
    );
    println!("|---|---|---|---|---|---|");
    let mut all_wrong = Vec::new();
    let (mut tot_read, mut tot_drawn) = (0, 0);
    for kind in stress::KINDS {
        let rs: Vec<_> = runs.iter().filter(|r| r.0 == kind).collect();
        let drawn: usize = rs.iter().map(|r| r.1).sum();
        let read: usize = rs.iter().map(|r| r.2).sum();
        let wrong: Vec<String> = rs.iter().flat_map(|r| r.3.clone()).collect();
        println!(
            "| {kind} | {} | {drawn} | {read} | {} | {:.1} |",
            rs.len(),
            wrong.len(),
            1000.0 * wrong.len() as f64 / read.max(1) as f64
        );
        if kind == "printed text" || kind == "checkerboard" {
            assert!(wrong.is_empty(), "{kind}: {wrong:?}");
            assert!(
                read * 100 >= drawn * 85,
                "{kind}: only {read} of {drawn} clean targets read"
            );
        }
        tot_read += read;
        tot_drawn += drawn;
        all_wrong.extend(wrong);
    }
    let rate = 1000.0 * all_wrong.len() as f64 / tot_read.max(1) as f64;
    println!(
        "| all | {seeds} | {tot_drawn} | {tot_read} | {} | {rate:.1} |",
        all_wrong.len()
    );
    for w in &all_wrong {
        println!("WRONG: {w}");
    }
    assert!(
        tot_read * 3 > tot_drawn,
        "only {tot_read} of {tot_drawn} targets read"
    );
    assert!(rate < 20.0, "{rate:.1} wrong per 1000 reads: {all_wrong:?}");
}
