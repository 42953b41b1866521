//! The rig checked per station (issue 52): a station whose images break the stereo rig is
//! named by the verdict.

use crate::common::{read_json, replace_once, Work};

/// The simulated project with station S03's left and right images swapped in project.toml:
/// every coded reading of one of them lies where the network puts another target, and the
/// verdict names the station (before, the verdict was ok with σ0 0.687 against 0.661 and
/// nothing said). The pristine project names no station.
#[test]
fn a_station_whose_images_are_swapped_is_named() {
    let w = Work::new("rig_swap");
    let p = w.project("p");
    let toml = p.join("project.toml");
    replace_once(&toml, "images/S03_left.png", "images/SWAP.png");
    replace_once(&toml, "images/S03_right.png", "images/S03_left.png");
    replace_once(&toml, "images/SWAP.png", "images/S03_right.png");
    let (run, out) = w.calibrate(&p, &["--accept-doubtful"]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let r = read_json(&out.join("results.json"));
    assert_ne!(r["verdict"]["status"], "ok", "{}", r["verdict"]);
    let reasons = r["verdict"]["reasons"].to_string();
    assert!(
        reasons.contains("station S03") && reasons.contains("is not where the project puts it"),
        "{reasons}"
    );
    let (run, out) = w.calibrate(&w.project("q"), &[]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let text = read_json(&out.join("results.json"))["verdict"].to_string();
    assert!(!text.contains("is not where the project puts it"), "{text}");
}
