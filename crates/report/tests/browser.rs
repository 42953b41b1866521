//! Renders the sample report in headless Chromium (scripts/check-report.sh) and checks the
//! screenshot is a real page and that Chromium's DOM holds every section. Skips, with a printed reason, where /usr/bin/chromium is absent.

use crate::common;

use std::path::Path;
use std::process::Command;

#[test]
fn sample_report_renders_in_chromium() {
    if !Path::new("/usr/bin/chromium").exists() {
        println!("skipped: /usr/bin/chromium not installed");
        return;
    }
    let dir = std::env::temp_dir().join(format!("pingcal-report-browser-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let html = dir.join("sample.html");
    let png = dir.join("sample.png");
    std::fs::write(
        &html,
        pingcal_report::render_html(&pingcal_report::sample::sample_report(30_000)),
    )
    .unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/check-report.sh");
    let out = Command::new("bash")
        .arg(&script)
        .arg(&html)
        .arg(&png)
        .output()
        .expect("run check-report.sh");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "check-report.sh failed ({}): {}{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        stderr
    );
    let size = std::fs::metadata(&png).map(|m| m.len()).unwrap_or(0);
    assert!(
        size > 20_000,
        "screenshot {} is {size} bytes",
        png.display()
    );
    println!("{}: {size} bytes", png.display());
    // the DOM Chromium built holds every section (Australis-like ones included) as an element
    let profile = dir.join("profile");
    let dom = Command::new("timeout")
        .args([
            "120",
            "/usr/bin/chromium",
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", html.display()))
        .output()
        .expect("run chromium --dump-dom");
    let dom = String::from_utf8_lossy(&dom.stdout);
    for id in std::iter::once("verdict").chain(common::IDS) {
        assert!(
            dom.contains(&format!("id=\"{id}\"")),
            "section {id} missing from Chromium's DOM ({} bytes)",
            dom.len()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
