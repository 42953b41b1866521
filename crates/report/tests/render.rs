//! Rendering tests: escaping, determinism, non-finite numbers, section anchors, empty data,
//! size bound, and well-formedness (the whole document parses as XML).

use pingcal_report::sample::sample_report;
use pingcal_report::*;

mod common;
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
        "distCoeffs = (k1, k2, p1, p2, k3)",
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
        let n = html.matches(forbidden).count();
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
        verdict: Some(pingcal_report::Verdict {
            status: s(),
            reasons: vec![s()],
            notes: vec![s()],
            checks: vec![pingcal_report::VerdictCheck {
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
        cloud: Cloud {
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
    };
    let html = render_html(&data);
    assert!(!html.contains("<script"), "raw markup leaked");
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
        for a in n.attributes() {
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
    for bad in [">NaN<", ">inf<", ">-inf<", "NaN", " inf "] {
        assert!(!html.contains(bad), "{bad:?} printed");
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
        cloud: Cloud {
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
    assert!(!html.contains("NaN"));
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
