//! The field guide's commands run as written (issue 18, "a test that follows the README and
//! docs' commands as written, from `cargo install` to a calibration of a simulated field"):
//! the shell block of `docs/install.md`'s "Five commands" runs in bash from the repository
//! root, with `HOME` and cargo's install root in a temporary folder (cargo and rustup keep
//! their own homes, and the build reuses this workspace's target folder, so the install is a
//! copy of what the tests already built). Then its outputs are checked.

use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The first ```sh block after the heading `heading` of a markdown text.
fn sh_block(md: &str, heading: &str) -> String {
    let at = md
        .find(heading)
        .unwrap_or_else(|| panic!("no heading {heading:?}"));
    let rest = &md[at..];
    let start = rest.find("```sh\n").expect("a sh block under the heading") + 6;
    let len = rest[start..].find("```").expect("the block ends");
    rest[start..start + len].to_string()
}

/// A home folder of the machine's (where cargo and rustup live unless told otherwise).
fn real_home(var: &str, default_sub: &str) -> Option<PathBuf> {
    std::env::var_os(var)
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(default_sub)))
}

#[test]
fn the_install_page_runs_as_written_from_cargo_install_to_a_calibration() {
    let root = workspace().canonicalize().unwrap();
    let md = std::fs::read_to_string(root.join("docs/install.md")).unwrap();
    let block = sh_block(&md, "## Five commands");
    assert!(block.contains("cargo install") && block.contains("pingcal calibrate"));
    let tmp = std::env::temp_dir().join(format!("pingcal-docs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let (home, install) = (tmp.join("home"), tmp.join("cargo-root"));
    std::fs::create_dir_all(&home).unwrap();
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    let path = format!(
        "{}:{}",
        install.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut cmd = Command::new("bash");
    cmd.args(["-euo", "pipefail", "-c", &block])
        .current_dir(&root)
        .env("HOME", &home)
        .env("CARGO_INSTALL_ROOT", &install)
        .env("CARGO_TARGET_DIR", &target)
        .env("PATH", path);
    for (var, sub) in [("CARGO_HOME", ".cargo"), ("RUSTUP_HOME", ".rustup")] {
        if let Some(h) = real_home(var, sub) {
            cmd.env(var, h);
        }
    }
    let out = cmd.output().expect("bash runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "docs/install.md's commands failed:\n{block}\n{err}"
    );
    assert!(
        install.join("bin/pingcal").is_file(),
        "cargo install installed no pingcal"
    );
    let try_dir = home.join("pingcal-try");
    let results = std::fs::read_to_string(try_dir.join("field/results/results.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&results).unwrap();
    assert!(
        v["mean_check_error_mm"].as_f64().is_some_and(|m| m < 10.0),
        "the calibration of the simulated field: {}",
        v["mean_check_error_mm"]
    );
    assert!(try_dir.join("field/results/report.html").is_file());
    let pdf = std::fs::read(try_dir.join("targets.pdf")).unwrap();
    assert!(pdf.starts_with(b"%PDF-"), "targets.pdf is a PDF");
    let _ = std::fs::remove_dir_all(&tmp);
}
