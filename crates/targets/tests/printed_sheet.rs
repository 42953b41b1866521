//! The printable sheet as a printer would see it (issue 18): the PDF of `sheet::to_pdf`
//! rendered to pixels by an independent renderer (poppler's `pdftoppm`, Debian's
//! poppler-utils), then read back by the detector: every coded target decodes to the number
//! printed under it, none to another, the plain targets are found, and the 100 mm scale bar
//! measures 100 mm at 300 dpi to ±0.5 px. Skipped, saying so, where `pdftoppm` is missing.

use pingcal_targets::detect::BallMode;
use pingcal_targets::image_io::load_image;
use pingcal_targets::refusal::RefusalReason;
use pingcal_targets::sheet::{layout, to_pdf, Page, PageSize, Shape, SheetSpec, SCALE_BAR_MM};
use pingcal_targets::{DetectParams, Detector, TargetKind};
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::Command;

const DPI: f64 = 300.0;

fn px(mm: f64) -> f64 {
    mm * DPI / 25.4
}

/// The pages of `pdf` rendered at 300 dpi in grey, or None (with the reason printed) when
/// pdftoppm cannot run.
fn render(pdf: &[u8], name: &str) -> Option<Vec<PathBuf>> {
    render_at(pdf, name, DPI)
}

/// The pages of `pdf` rendered at `dpi` in grey, or None (with the reason printed) when
/// pdftoppm cannot run.
fn render_at(pdf: &[u8], name: &str, dpi: f64) -> Option<Vec<PathBuf>> {
    let dir = std::env::temp_dir().join(format!("pingcal-sheet-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("sheet.pdf");
    std::fs::write(&file, pdf).unwrap();
    let run = Command::new("pdftoppm")
        .args(["-r", &dpi.to_string(), "-gray", "-png"])
        .arg(&file)
        .arg(dir.join("page"))
        .output();
    match run {
        Ok(o) if o.status.success() => {}
        Ok(o) => panic!(
            "pdftoppm failed on the sheet: {}",
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => {
            eprintln!("skipped: pdftoppm (Debian's poppler-utils) cannot run here: {e}");
            return None;
        }
    }
    let mut pages: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    pages.sort();
    Some(pages)
}

#[test]
fn a_printed_sheet_reads_back_to_its_numbers_and_its_scale_bar_is_100_mm() {
    // 60 numbers across the 14-bit table, 12 plain targets, a 3 mm dot: two A4 pages
    let ids: Vec<u32> = (0..60).map(|k| 2 + k * 8).collect();
    let spec = SheetSpec {
        bits: 14,
        ids: ids.clone(),
        plain: 12,
        dot_radius_mm: 3.0,
        ring: (2.0, 3.0),
        page: PageSize::A4,
    };
    let pages = layout(&spec).unwrap();
    assert!(pages.len() >= 2, "the test covers more than one page");
    let Some(files) = render(&to_pdf(&pages, spec.page), "a4") else {
        return;
    };
    assert_eq!(files.len(), pages.len(), "pdftoppm rendered every page");
    let det = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .unwrap();
    let (mut read, mut plain) = (BTreeSet::new(), 0);
    let mut worst_px = 0.0f64;
    for (f, page) in files.iter().zip(&pages) {
        let img = load_image(f).unwrap();
        // the scale bar: the darkness summed along the row through its middle, where the
        // ticks (above it) do not reach; anti-aliased edges count by their coverage
        let (_, ph) = PageSize::A4.mm();
        let row = px(ph - 10.0 - 4.0 - 1.0).floor() as usize;
        let (x0, x1) = (px(5.0) as usize, px(10.0 + SCALE_BAR_MM + 5.0) as usize);
        let length: f64 = (x0..x1)
            .map(|x| 1.0 - img.data[row * img.width + x] as f64)
            .sum();
        eprintln!(
            "{}: scale bar {length:.3} px (100 mm = {:.3} px)",
            f.display(),
            px(SCALE_BAR_MM)
        );
        assert!(
            (length - px(SCALE_BAR_MM)).abs() <= 0.5,
            "{}: the scale bar is {length:.2} px, 100 mm at 300 dpi is {:.2} px",
            f.display(),
            px(SCALE_BAR_MM)
        );
        // A photograph of the print exposed below saturation (the detector refuses targets
        // with more than a fifth of their samples saturated, as their edges are biased).
        let mut photo = img.clone();
        photo.data.iter_mut().for_each(|v| *v = 0.05 + 0.75 * *v);
        let found = det.detect(&photo).targets;
        // every printed dot is found where it is printed (pixel centres at integer
        // coordinates), a coded target's with its number, a plain target's as plain
        for (cx, cy, coded) in dots(page, spec.dot_radius_mm) {
            let (x, y) = (px(cx) - 0.5, px(cy) - 0.5);
            let dist = |t: &&pingcal_targets::Target| (t.x - x).hypot(t.y - y);
            let t = found
                .iter()
                .min_by(|a, b| dist(a).total_cmp(&dist(b)))
                .expect("targets found");
            let off = dist(&t);
            worst_px = worst_px.max(off);
            assert!(
                off < 0.5,
                "{}: the dot at ({cx:.1}, {cy:.1}) mm found {off:.2} px away",
                f.display()
            );
            match (coded, t.kind, t.id) {
                (true, TargetKind::Coded, Some(id)) => {
                    assert!(
                        ids.contains(&id),
                        "{}: read {id}, which is not printed",
                        f.display()
                    );
                    assert!(read.insert(id), "{id} read twice");
                }
                (false, TargetKind::Plain, _) => plain += 1,
                other => panic!(
                    "{}: the dot at ({cx:.1}, {cy:.1}) mm read as {other:?}",
                    f.display()
                ),
            }
        }
        // no number read anywhere else on the page, and no plain target (the header, the
        // numbers and the scale bar's text are not targets)
        let plain_found = found.iter().filter(|t| t.kind == TargetKind::Plain).count();
        let plain_printed = dots(page, spec.dot_radius_mm)
            .iter()
            .filter(|d| !d.2)
            .count();
        assert_eq!(
            plain_found,
            plain_printed,
            "{}: plain targets found where none is printed: {:?}",
            f.display(),
            found
                .iter()
                .filter(|t| t.kind == TargetKind::Plain)
                .map(|t| (
                    t.x.round(),
                    t.y.round(),
                    (2.0 * t.ellipse.radius() * 10.0).round() / 10.0
                ))
                .collect::<Vec<_>>()
        );
        let coded_found = found.iter().filter(|t| t.kind == TargetKind::Coded).count();
        let coded_printed = dots(page, spec.dot_radius_mm)
            .iter()
            .filter(|d| d.2)
            .count();
        assert_eq!(
            coded_found,
            coded_printed,
            "{}: coded targets found where none is printed",
            f.display()
        );
    }
    eprintln!(
        "{} of {} coded read, {plain} of {} plain found, centres within {worst_px:.3} px",
        read.len(),
        ids.len(),
        spec.plain
    );
    assert_eq!(
        read.len(),
        ids.len(),
        "every printed number read back: {read:?}"
    );
    assert_eq!(plain, spec.plain, "every plain target found as plain");
}

/// The printed dots of a page (mm) and whether each is a coded target's: a disc drawn right
/// after a black square of side 8 dot radii (coded) or 4 (plain).
fn dots(page: &Page, r: f64) -> Vec<(f64, f64, bool)> {
    let mut out = Vec::new();
    for w in page.shapes.windows(2) {
        if let [Shape::Rect { w, .. }, Shape::Disc { cx, cy, .. }] = w {
            out.push((*cx, *cy, (*w - 8.0 * r).abs() < 1e-9));
        }
    }
    out
}

/// A sheet rendered flat, as a scan or a screenshot of the print looks (issue 38): white paper
/// and white dots both at full scale, at 150 and 300 dpi. As the detector is, every dot is
/// refused as saturated, and says so (each one listed, with all of its samples saturated); the
/// insides of the text's letters are refused as text glyphs, never taken for plain targets.
/// Asked to measure saturated targets, it reads every number printed and finds every plain
/// target, and nothing else.
#[test]
fn a_flat_render_of_a_sheet_is_refused_as_saturated_or_read_when_asked() {
    let ids: Vec<u32> = (0..30).map(|k| 3 + k * 17).collect();
    let spec = SheetSpec {
        bits: 14,
        ids: ids.clone(),
        plain: 8,
        dot_radius_mm: 4.0,
        ring: (2.0, 3.0),
        page: PageSize::A4,
    };
    let pages = layout(&spec).unwrap();
    let pdf = to_pdf(&pages, spec.page);
    let refuse = Detector::new(DetectParams {
        balls: BallMode::Off,
        ..DetectParams::default()
    })
    .unwrap();
    let measure = Detector::new(DetectParams {
        balls: BallMode::Off,
        measure_saturated: true,
        ..DetectParams::default()
    })
    .unwrap();
    for dpi in [150.0, 300.0] {
        let Some(files) = render_at(&pdf, &format!("flat{dpi}"), dpi) else {
            return;
        };
        let (mut read, mut plain, mut saturated, mut glyphs) = (BTreeSet::new(), 0, 0, 0);
        for (f, page) in files.iter().zip(&pages) {
            let img = load_image(f).unwrap();
            let printed = dots(page, spec.dot_radius_mm);
            let at_dot = |x: f64, y: f64| {
                printed.iter().any(|&(cx, cy, _)| {
                    (px_at(cx, dpi) - 0.5 - x).hypot(px_at(cy, dpi) - 0.5 - y) < 1.0
                })
            };
            // as it is: nothing measured, every dot refused as saturated (and said so)
            let d = refuse.detect(&img);
            assert!(
                d.targets.is_empty(),
                "{}: {} targets",
                f.display(),
                d.targets.len()
            );
            for r in &d.refused {
                match r.reason {
                    RefusalReason::Saturated => {
                        assert!(at_dot(r.ellipse.cx, r.ellipse.cy), "{}: {r:?}", f.display());
                        assert_eq!(r.saturated_share, Some(1.0), "{r:?}");
                        saturated += 1;
                    }
                    RefusalReason::TextGlyph => glyphs += 1,
                    _ => assert!(!at_dot(r.ellipse.cx, r.ellipse.cy), "{r:?}"),
                }
            }
            // asked to measure them: every dot, with its number, and nothing else
            let d = measure.detect(&img);
            for t in &d.targets {
                assert!(t.saturated && at_dot(t.x, t.y), "{}: {t:?}", f.display());
                match (t.kind, t.id) {
                    (TargetKind::Coded, Some(id)) => {
                        assert!(ids.contains(&id) && read.insert(id), "{id}");
                    }
                    (TargetKind::Plain, None) => plain += 1,
                    other => panic!("{}: {other:?} at ({:.1}, {:.1})", f.display(), t.x, t.y),
                }
            }
        }
        eprintln!(
            "{dpi} dpi: {saturated} dots refused as saturated, {glyphs} text glyphs; measured when asked: {} of {} numbers, {plain} of {} plain",
            read.len(),
            ids.len(),
            spec.plain
        );
        assert_eq!(
            saturated,
            ids.len() + spec.plain,
            "{dpi} dpi: every dot refused"
        );
        assert!(glyphs > 0, "{dpi} dpi: the header's letters were not seen");
        assert_eq!(
            read.len(),
            ids.len(),
            "{dpi} dpi: every number read: {read:?}"
        );
        assert_eq!(plain, spec.plain, "{dpi} dpi: every plain target");
    }
}

fn px_at(mm: f64, dpi: f64) -> f64 {
    mm * dpi / 25.4
}
