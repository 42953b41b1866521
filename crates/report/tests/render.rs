//! Rendering tests: escaping, determinism, non-finite numbers, section anchors, empty data,
//! size bound, and well-formedness (the whole document parses as XML).

use pingcal_report::sample::sample_report;
use pingcal_report::*;

use crate::common;
use common::IDS;

/// Parses the document as XML (it is written to be well-formed) and returns it for checks.
fn parse(html: &str) -> roxmltree::Document<'_> {
    let opts = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    match roxmltree::Document::parse_with_options(html, opts) {
        Ok(d) => d,
        Err(e) => {
            let pos = e.pos();
            let line = html.lines().nth(pos.row as usize - 1).unwrap_or("");
            let start = (pos.col as usize).saturating_sub(120);
            let snippet: String = line.chars().skip(start).take(240).collect();
            panic!("not well-formed: {e}\n…{snippet}…");
        }
    }
}

/// `html` with the base64 text of its `data:` URIs taken out: a PNG's bytes in base64 may
/// spell "NaN" or "inf" by chance, the text around them must not.
fn without_data_uris(html: &str) -> String {
    let mut out = String::with_capacity(html.len());
    let mut rest = html;
    while let Some(k) = rest.find("data:image/png;base64,") {
        let (head, tail) = rest.split_at(k);
        out.push_str(head);
        let end = tail.find('"').unwrap_or(tail.len());
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
}

fn svg_count(doc: &roxmltree::Document) -> usize {
    doc.descendants()
        .filter(|n| n.tag_name().name() == "svg")
        .count()
}

#[test]
fn sample_is_well_formed_with_all_sections_in_order() {
    let html = render_html(&sample_report(5_000));
    assert!(html.starts_with("<!DOCTYPE html>\n"));
    assert!(html.contains(r#"<meta charset="utf-8"/>"#));
    let doc = parse(&html);
    // every <svg is an element of the parsed tree: 1 chart + 22 images + 2 network + 2 cloud
    assert_eq!(svg_count(&doc), html.matches("<svg ").count());
    // + 2 extrinsic σ bar plots + 1 histogram + 22 coverage thumbnails + 1 distortion profile
    assert_eq!(svg_count(&doc), 1 + 22 + 2 + 2 + 2 + 1 + 22 + 1);
    for text in [
        "Relative precision <b>1 : ",
        "correlations of (θ, t)",
        "σ rotation about the right camera's X, Y, Z (°)",
        "at the corner (r = ",
        "/25 cells",
        "<td class=\"l\">plumb_bob</td><td class=\"l\">(",
        "What each export loses against pingcal's model",
        "<tr class=\"hi\"><td class=\"l\">left</td><td class=\"l\">kalibr/camchain.yaml</td>",
    ] {
        assert!(html.contains(text), "{text:?} missing");
    }
    // the verdict comes before the table of contents and every section
    assert!(html.find("id=\"verdict\"").unwrap() < html.find("<nav").unwrap());
    let mut last = 0;
    for id in IDS {
        let at = html
            .find(&format!("<section id=\"{id}\">"))
            .unwrap_or_else(|| panic!("section {id} missing"));
        assert!(at > last, "section {id} out of order");
        last = at;
        assert!(html.contains(&format!("href=\"#{id}\"")), "toc entry {id}");
    }
    for forbidden in [
        "<script", "http://", "https://", "NaN", "inf<", "@import", "url(",
    ] {
        let n = without_data_uris(&html).matches(forbidden).count();
        // the SVG namespace URI is the only allowed "http://"
        let allowed = if forbidden == "http://" {
            svg_count(&doc)
        } else {
            0
        };
        assert_eq!(n, allowed, "{forbidden:?} found {n} times");
    }
}

#[test]
fn output_is_deterministic_and_survives_json() {
    let data = sample_report(3_000);
    let a = render_html(&data);
    let b = render_html(&sample_report(3_000));
    assert_eq!(a, b);
    let json = serde_json::to_string(&data).unwrap();
    let back: ReportData = serde_json::from_str(&json).unwrap();
    assert_eq!(render_html(&back), a);
}

#[test]
fn user_strings_are_escaped() {
    let evil = r#"<script>alert("x" & 'y')</script>"#;
    let s = || evil.to_string();
    let data = ReportData {
        title: s(),
        generator: s(),
        verdict: Some(pingcal_report::VerdictView {
            status: s(),
            reasons: vec![s()],
            notes: vec![s()],
            checks: vec![pingcal_report::VerdictCheckView {
                name: s(),
                value: f64::NAN,
                bound: 1.0,
                passed: false,
            }],
            alpha: 0.01,
        }),
        summary: vec![(s(), s())],
        steps: vec![s()],
        images: vec![ImageResiduals {
            name: s(),
            width: 100,
            height: 80,
            points: vec![ImagePoint {
                label: s(),
                kind: s(),
                x: 10.0,
                y: 10.0,
                dx: 0.1,
                dy: 0.2,
                rejected: false,
            }],
        }],
        network: Network {
            cameras: vec![CameraStation {
                name: s(),
                main: true,
                rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                ..Default::default()
            }],
            points: vec![NetworkPoint {
                label: s(),
                kind: "ball".into(),
                xyz: [100.0, 200.0, 300.0],
                sigma: [0.1; 3],
            }],
        },
        cloud: CloudView {
            points: vec![[1.0, 2.0, 3.0]],
            spheres: vec![Sphere {
                label: s(),
                matched_to: Some(s()),
                radius: 19.0,
                ..Default::default()
            }],
        },
        methods: vec![
            MethodResult {
                name: s(),
                checks: vec![CheckRow {
                    id: s(),
                    role: "check".into(),
                    error_mm: 3.0,
                    ..Default::default()
                }],
                ..Default::default()
            },
            MethodResult {
                name: "broken".into(),
                error: Some(s()),
                ..Default::default()
            },
        ],
        lrf_mount: vec![pingcal_report::MountRow {
            name: s(),
            value: 1.0,
            sigma: Some(0.1),
            unit: s(),
            held: Some(s()),
            max_corr_extrinsic: Some((s(), 0.95)),
        }],
        intrinsics: vec![Intrinsics {
            camera: s(),
            names: vec![s()],
            units: vec![s()],
            values: vec![1.0],
            sigmas: vec![0.1],
            free: vec![true],
            high_correlations: vec![(s(), s(), 0.95)],
            r_max_mm: Some(3.0),
            opencv: Some(Default::default()),
            model: s(),
            lens_curve: Some((vec![(0.0, 0.0), (100.0, 30.0)], 200.0)),
        }],
        rejected: vec![Rejection {
            what: s(),
            why: s(),
        }],
        warnings: vec![s()],
        exterior: vec![ExteriorRow {
            name: s(),
            note: s(),
            ..Default::default()
        }],
        distances: vec![DistanceRow {
            from: s(),
            to: s(),
            sigma_mm: 0.1,
            ..Default::default()
        }],
        rig: Some(RigOrientation {
            left: s(),
            right: s(),
            ..Default::default()
        }),
        sensors: vec![pingcal_report::SensorRow {
            name: s(),
            kind: s(),
            translation_mm: [f64::NAN, f64::INFINITY, 1.0],
            ..Default::default()
        }],
        sensor_pairs: vec![pingcal_report::SensorRow {
            name: s(),
            ..Default::default()
        }],
        export_losses: vec![ExportLossRow {
            camera: s(),
            files: s(),
            model: s(),
            max_px: f64::NAN,
            rms_px: 1.0,
        }],
        overlays: vec![Overlay {
            name: s(),
            caption: s(),
            png_base64: s(),
            range_mm: [f64::NAN, f64::INFINITY],
            ..Default::default()
        }],
    };
    let html = render_html(&data);
    assert!(!html.contains("<script"), "raw markup leaked");
    let text = without_data_uris(&html);
    assert!(!text.contains("NaN") && !text.contains("inf–"));
    assert!(!html.contains(r#""x""#));
    assert!(html.contains("&lt;script&gt;alert(&quot;x&quot; &amp; &#39;y&#39;)&lt;/script&gt;"));
    assert!(
        html.contains("failed: &lt;script&gt;"),
        "method failure shown"
    );
    parse(&html);
}

#[test]
fn non_finite_numbers_print_as_dash_and_keep_svg_valid() {
    let nan = f64::NAN;
    let inf = f64::INFINITY;
    let mut data = sample_report(2_000);
    data.images[0].points[0].x = nan;
    data.images[0].points[1].dx = inf;
    data.images[0].points[2].dy = nan;
    data.images[1].width = 0; // inferred from the points
    data.network.points[0].xyz[0] = nan;
    data.network.points[1].sigma = [nan, inf, -1.0];
    data.network.cameras[3].centre[2] = -inf;
    data.network.cameras[4].rotation = [[nan; 3]; 3];
    data.cloud.points[0] = [f32::NAN, 0.0, 0.0];
    data.cloud.points[1] = [0.0, f32::INFINITY, 0.0];
    data.cloud.spheres[0].centre = [nan; 3];
    data.cloud.spheres[1].radius = inf;
    data.methods[0].translation_mm[0] = nan;
    data.methods[0].rotation[1][1] = inf;
    data.methods[0].checks[0].error_mm = nan;
    data.methods[0].mean_check_error_mm = Some(nan);
    data.methods[1].checks[1].dx_mm = -inf;
    data.intrinsics[0].values[0] = nan;
    data.intrinsics[0].high_correlations[0].2 = nan;
    data.intrinsics[1].values[3] = inf; // K1: no distortion profile for this camera
    data.intrinsics[0].r_max_mm = Some(nan);
    data.exterior[1].centre_mm[0] = nan;
    data.exterior[2].sigma_centre_mm = Some([inf; 3]);
    data.distances[0].sigma_mm = 0.0;
    data.distances[1].adjusted_mm = nan;
    data.methods[0].correlation.as_mut().unwrap()[0][1] = nan;
    data.methods[0].sigma_rotation_deg = Some([nan; 3]);
    let html = render_html(&data);
    assert!(html.contains("—"));
    let doc = parse(&html);
    for n in doc.descendants().filter(|n| n.is_element()) {
        // (a PNG's base64 may spell "nan" or "inf" by chance)
        for a in n
            .attributes()
            .filter(|a| !a.value().starts_with("data:image/png;base64,"))
        {
            let v = a.value().to_ascii_lowercase();
            assert!(
                !v.contains("nan") && !v.contains("inf"),
                "non-finite value in <{} {}=\"{}\">",
                n.tag_name().name(),
                a.name(),
                a.value()
            );
        }
    }
    let text = without_data_uris(&html);
    for bad in [">NaN<", ">inf<", ">-inf<", "NaN", " inf "] {
        assert!(!text.contains(bad), "{bad:?} printed");
    }
    // Everything non-finite: the whole report degrades, never breaks.
    let all_nan = ReportData {
        images: vec![ImageResiduals {
            name: "x".into(),
            width: 0,
            height: 0,
            points: vec![ImagePoint {
                x: nan,
                y: nan,
                dx: nan,
                dy: nan,
                ..Default::default()
            }],
        }],
        network: Network {
            cameras: vec![CameraStation {
                centre: [nan; 3],
                ..Default::default()
            }],
            points: vec![NetworkPoint {
                xyz: [inf; 3],
                ..Default::default()
            }],
        },
        cloud: CloudView {
            points: vec![[f32::NAN; 3]],
            spheres: vec![Sphere {
                centre: [nan; 3],
                radius: nan,
                ..Default::default()
            }],
        },
        methods: vec![MethodResult {
            checks: vec![CheckRow {
                id: "1".into(),
                error_mm: nan,
                role: "check".into(),
                ..Default::default()
            }],
            ..Default::default()
        }],
        ..Default::default()
    };
    let html = render_html(&all_nan);
    assert!(!without_data_uris(&html).contains("NaN"));
    parse(&html);
}

#[test]
fn empty_data_renders_every_section() {
    let html = render_html(&ReportData::default());
    let doc = parse(&html);
    assert_eq!(svg_count(&doc), 0);
    for id in IDS {
        assert!(html.contains(&format!("<section id=\"{id}\">")), "{id}");
    }
    for text in [
        "no summary",
        "no extrinsic calibration",
        "no check points",
        "no image residuals",
        "no network",
        "no LRF cloud",
        "no LRF points drawn on the images",
        "no intrinsics",
        "nothing rejected",
        "no warnings",
        "no steps logged",
    ] {
        assert!(html.contains(text), "{text:?} missing");
    }
}

#[test]
fn loo_rows_are_charted_when_there_are_no_check_rows() {
    let row = |id: &str, role: &str, e: f64| CheckRow {
        id: id.into(),
        error_mm: e,
        role: role.into(),
        ..Default::default()
    };
    let data = ReportData {
        methods: vec![MethodResult {
            name: "spheres".into(),
            checks: vec![
                row("1", "control", 1.0),
                row("2", "loo", 7.25),
                row("3", "loo", 8.5),
            ],
            ..Default::default()
        }],
        ..Default::default()
    };
    let html = render_html(&data);
    assert!(html.contains("(loo points, mean 7.9 mm)"), "{html}");
    assert!(html.contains("ball 2 error 7.25 mm"));
    assert!(
        !html.contains("ball 1 error"),
        "control rows are not charted"
    );
    parse(&html);
}

#[test]
fn size_bound_22_images_of_120_points_and_30k_cloud() {
    let mut data = sample_report(30_000);
    assert!(data.cloud.points.len() >= 30_000);
    assert_eq!(data.images.len(), 22);
    for img in &mut data.images {
        let mut k = 0;
        while img.points.len() < 120 {
            let mut p = img.points[k].clone();
            p.x = (p.x + 37.0 * (k + 1) as f64) % img.width as f64;
            p.y = (p.y + 23.0 * (k + 1) as f64) % img.height as f64;
            img.points.push(p);
            k += 1;
        }
    }
    let html = render_html(&data);
    eprintln!(
        "sample report with 22×120 image points and 30k cloud points: {} bytes",
        html.len()
    );
    assert!(html.len() < 3_000_000, "{} bytes", html.len());
    parse(&html);
}

// ---- Overlays: the LRF's points drawn on the images -----------------------------------

use pingcal_report::overlay::{
    render_png, GreyImage, OverlayOptions, OverlayPoint, PointKind, BALL_RGB,
};

/// Decodes an RGB PNG: (width, height, pixels).
fn decode_rgb(png_bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut dec = png::Decoder::new(std::io::Cursor::new(png_bytes))
        .read_info()
        .expect("a PNG");
    let mut buf = vec![0; dec.output_buffer_size().expect("its size")];
    let info = dec.next_frame(&mut buf).expect("its pixels");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

fn rgb_at(px: &[u8], w: u32, x: u32, y: u32) -> [u8; 3] {
    let k = 3 * (y * w + x) as usize;
    [px[k], px[k + 1], px[k + 2]]
}

/// A flat grey image of `w × h` at value `g`.
fn flat(w: u32, h: u32, g: u8) -> GreyImage {
    GreyImage {
        width: w,
        height: h,
        pixels: vec![g; (w * h) as usize],
    }
}

fn ball(x: f64, y: f64) -> OverlayPoint {
    OverlayPoint {
        x,
        y,
        kind: PointKind::Ball { label: "B7".into() },
    }
}

#[test]
fn a_ball_point_is_drawn_where_it_is_and_nothing_else_changes() {
    let img = flat(200, 100, 100);
    let opts = OverlayOptions {
        radius_px: Some(2.0),
        labels: false,
        ..OverlayOptions::default()
    };
    let r = render_png(&img, &[ball(50.0, 30.0)], &opts);
    let (w, h, px) = decode_rgb(&r.png);
    assert_eq!((w, h, r.width, r.height), (200, 100, 200, 100));
    assert_eq!((r.ball_points, r.range_points, r.outside), (1, 0, 0));
    // the disc of radius 2 px: its centre and a pixel 2 px off are the ball's colour
    assert_eq!(rgb_at(&px, w, 50, 30), BALL_RGB);
    assert_eq!(rgb_at(&px, w, 52, 30), BALL_RGB);
    // the background: 40 + 0.6 · 100 = 100 everywhere else (no colour bar without ranges)
    let dimmed = [100, 100, 100];
    assert_eq!(rgb_at(&px, w, 53, 30), dimmed);
    let coloured = (0..w * h)
        .filter(|&i| rgb_at(&px, w, i % w, i / w) != dimmed)
        .count();
    assert_eq!(coloured, 13, "the disc of radius 2 has 13 pixel centres");
}

#[test]
fn points_outside_the_image_are_counted_not_drawn() {
    let img = flat(64, 48, 0);
    let pts = [
        ball(-0.6, 10.0),
        ball(10.0, 47.6),
        ball(f64::NAN, 3.0),
        ball(63.5, 47.5),
        OverlayPoint {
            x: 1e300,
            y: -1e300,
            kind: PointKind::Range { range_mm: 5.0 },
        },
    ];
    let r = render_png(&img, &pts, &OverlayOptions::default());
    assert_eq!((r.ball_points, r.range_points, r.outside), (1, 0, 4));
    let (w, _, px) = decode_rgb(&r.png);
    assert_eq!(
        rgb_at(&px, w, 63, 47),
        BALL_RGB,
        "the corner pixel's edge is inside"
    );
}

#[test]
fn downscaling_keeps_the_aspect_and_the_point_positions() {
    let img = flat(1000, 600, 200);
    let opts = OverlayOptions {
        max_width: Some(250),
        radius_px: Some(1.0),
        labels: false,
        ..OverlayOptions::default()
    };
    // source pixel 401.5 → output (401.5 + 0.5) / 4 − 0.5 = 100
    let r = render_png(&img, &[ball(401.5, 201.5)], &opts);
    let (w, h, px) = decode_rgb(&r.png);
    assert_eq!((w, h), (250, 150));
    assert_eq!(rgb_at(&px, w, 100, 50), BALL_RGB);
    assert_eq!(rgb_at(&px, w, 102, 50), [160, 160, 160]);
    // never enlarged
    let small = render_png(&flat(100, 50, 0), &[], &opts);
    assert_eq!((small.width, small.height), (100, 50));
}

#[test]
fn range_points_follow_the_colour_map_and_near_ones_are_on_top() {
    let img = flat(300, 200, 0);
    let range = |x: f64, r: f64| OverlayPoint {
        x,
        y: 20.0,
        kind: PointKind::Range { range_mm: r },
    };
    let opts = OverlayOptions {
        radius_px: Some(3.0),
        range_mm: Some((1000.0, 3000.0)),
        labels: false,
        ..OverlayOptions::default()
    };
    // a far point and a near one at the same pixel, the near one listed first
    let r = render_png(
        &img,
        &[
            range(100.0, 1000.0),
            range(100.0, 3000.0),
            range(200.0, 2000.0),
        ],
        &opts,
    );
    let (w, _, px) = decode_rgb(&r.png);
    assert_eq!(r.range_mm, (1000.0, 3000.0));
    assert_eq!(
        rgb_at(&px, w, 100, 20),
        pingcal_report::overlay::range_colour(0.0)
    );
    assert_eq!(
        rgb_at(&px, w, 200, 20),
        pingcal_report::overlay::range_colour(0.5)
    );
    // the colour bar runs from turbo(0) to turbo(1) in the bottom-right corner
    let bar_row: Vec<[u8; 3]> = (0..w).map(|x| rgb_at(&px, w, x, 200 - 13 - 3)).collect();
    assert!(bar_row.contains(&pingcal_report::overlay::range_colour(0.0)));
    assert!(bar_row.contains(&pingcal_report::overlay::range_colour(1.0)));
}

#[test]
fn the_same_input_gives_the_same_bytes_and_a_wrong_buffer_no_panic() {
    let img = flat(120, 80, 90);
    let pts = [ball(10.0, 10.0), ball(12.0, 11.0)];
    let a = render_png(&img, &pts, &OverlayOptions::default());
    let b = render_png(&img, &pts, &OverlayOptions::default());
    assert_eq!(a.png, b.png);
    let broken = GreyImage {
        width: 10,
        height: 10,
        pixels: vec![1, 2, 3],
    };
    let r = render_png(&broken, &pts, &OverlayOptions::default());
    assert_eq!(decode_rgb(&r.png).0, 10);
}

/// Standard base64 back to bytes (padding allowed).
fn unbase64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let mut out = Vec::new();
    for chunk in s.as_bytes().chunks(4) {
        let digits: Vec<u8> = chunk
            .iter()
            .filter(|&&c| c != b'=')
            .map(|&c| val(c))
            .collect();
        let n =
            digits.iter().fold(0u32, |n, &d| (n << 6) | u32::from(d)) << (6 * (4 - digits.len()));
        out.extend_from_slice(&n.to_be_bytes()[1..digits.len()]);
    }
    out
}

#[test]
fn the_sample_report_shows_its_overlays_as_pngs_that_decode() {
    let data = sample_report(5_000);
    assert_eq!(data.overlays.len(), 2);
    assert!(data.overlays[0].main && !data.overlays[1].main);
    assert!(data
        .overlays
        .iter()
        .all(|v| v.ball_points > 0 && v.range_points > 0));
    let html = render_html(&data);
    let doc = parse(&html);
    let imgs: Vec<_> = doc
        .descendants()
        .filter(|n| n.tag_name().name() == "img")
        .collect();
    assert_eq!(imgs.len(), 2);
    for (img, v) in imgs.iter().zip(&data.overlays) {
        let src = img.attribute("src").expect("src");
        let b64 = src
            .strip_prefix("data:image/png;base64,")
            .expect("a data URI");
        let (w, h, _) = decode_rgb(&unbase64(b64));
        assert_eq!((w, h), (v.width, v.height));
        assert_eq!(img.attribute("width"), Some(w.to_string().as_str()));
    }
    assert_eq!(
        (data.overlays[0].width, data.overlays[0].height),
        (960, 540)
    );
}

#[test]
fn a_dense_cloud_is_thinned_evenly_and_ball_points_never() {
    let img = flat(120, 60, 50);
    let mut pts: Vec<OverlayPoint> = (0..10_000)
        .map(|k| OverlayPoint {
            x: (k % 120) as f64,
            y: (k / 120 % 60) as f64,
            kind: PointKind::Range {
                range_mm: 1000.0 + k as f64,
            },
        })
        .collect();
    pts.extend((0..500).map(|k| ball((k % 100) as f64, 30.0)));
    let r = render_png(&img, &pts, &OverlayOptions::default());
    // 120 · 60 / 60 = 120 range points at most; every ball point
    assert_eq!(r.ball_points, 500);
    assert!(
        r.range_points <= 120 && r.range_points >= 100,
        "{}",
        r.range_points
    );
    assert_eq!(r.range_points + r.range_points_skipped, 10_000);
    let given = OverlayOptions {
        max_range_points: Some(20_000),
        ..OverlayOptions::default()
    };
    assert_eq!(render_png(&img, &pts, &given).range_points, 10_000);
}

/// Issue 35: a camera whose model has no K1–K3 gets its lens curve (θ against r, beside the
/// pinhole's and the equidistant lens's) in the distortion section; a photogrammetric one
/// its Δr profile; an OpenCV camera's k1 is not taken for K1.
#[test]
fn the_distortion_section_draws_each_models_lens() {
    let mut d = sample_report(1000);
    let mut fisheye = d.intrinsics[0].clone();
    fisheye.camera = "fisheye".into();
    fisheye.model = "kannala-brandt".into();
    fisheye.names = vec![
        "fx".into(),
        "fy".into(),
        "cx".into(),
        "cy".into(),
        "k1".into(),
    ];
    fisheye.values = vec![300.0, 300.0, 640.0, 360.0, 0.05];
    fisheye.r_max_mm = Some(3.0);
    let pts: Vec<(f64, f64)> = (0..=10)
        .map(|i| (70.0 * i as f64, 9.5 * i as f64))
        .collect();
    fisheye.lens_curve = Some((pts, 300.0));
    d.intrinsics.push(fisheye);
    let html = pingcal_report::render_html(&d);
    let section = &html[html
        .find("id=\"distortion\"")
        .expect("a distortion section")..];
    let section = &section[..section.find("</section>").unwrap()];
    assert!(section.contains("lens curve"), "no lens curve drawn");
    assert!(
        section.contains("fisheye: θ = 95.0° at r = 700 px (f = 300.0 px)"),
        "{section}"
    );
    assert!(
        section.contains("radial distortion profile"),
        "the photogrammetric camera's profile"
    );
    assert_eq!(
        section.matches("µm at the corner").count(),
        d.intrinsics
            .iter()
            .filter(|c| c.model != "kannala-brandt")
            .count(),
        "the fisheye's k1 is not drawn as a photogrammetric K1"
    );
}
