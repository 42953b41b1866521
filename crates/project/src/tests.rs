//! Tests of the crate: the documented example (docs/project.md) parses and validates; every closed set refuses
//! an unknown word at parse time with the file, the line, the value and the words allowed;
//! invalid values are named; the parser never panics.

use super::*;
use pingcal_lrf::sensor::NoiseProfile;
use pingcal_lrf::settings::{ServoMotion, Stamps};

/// The documented example (it was the README's): the first ```toml block of docs/project.md.
fn readme_example() -> String {
    let rest = include_str!("../../../docs/project.md");
    let start = rest
        .find("```toml\n")
        .expect("docs/project.md has a toml block")
        + 8;
    let len = rest[start..].find("```").expect("the block ends");
    rest[start..start + len].to_string()
}

/// A scan file of one scan, for the projects loaded here (a project's scan files are read
/// through when it is loaded).
const SCAN: &str = "# pingcal-scan v1\n# angle_min_deg=-10\n# angle_increment_deg=10\n# range_unit=mm\nstamp_s,servo_deg,r0\n0,0,1000\n";

#[test]
fn the_documented_example_is_valid() {
    let p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    p.validate("example.toml").unwrap();
    assert_eq!(p.cameras.len(), 2);
    assert_eq!(p.balls.labels.len(), 2);
    assert_eq!(p.method, Method::Both);
    assert_eq!(p.targets.family, TargetFamily::Aicon14);
    assert_eq!(p.cameras[0].model, CameraModel::Photogrammetric);
    assert_eq!(p.cameras[0].free, Parameter::ALL[..10]);
    assert_eq!(p.cameras[1].free, Parameter::ALL[..8]);
    // round trip
    let again = ProjectFile::parse(&p.to_toml_string(), "again").unwrap();
    assert_eq!(again, p);
}

fn err_of(edit: impl Fn(&mut ProjectFile)) -> String {
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    edit(&mut p);
    p.validate("p.toml").unwrap_err().to_string()
}

#[test]
fn invalid_values_are_named() {
    let e = err_of(|p| p.main_station = "S99".into());
    assert!(
        e.contains("main_station = \"S99\" is not the station of any image"),
        "{e}"
    );
    let e = err_of(|p| p.images[0].camera = "middle".into());
    assert!(e.contains("camera 'middle' is not in [[cameras]]"), "{e}");
    let e = err_of(|p| p.distances[0].sigma_mm = 0.0);
    assert!(e.contains("distances[0]") && e.contains("sigma_mm"), "{e}");
    let e = err_of(|p| p.balls.check.push("B99".into()));
    assert!(e.contains("'B99' is not one of the labelled balls"), "{e}");
    assert!(e.starts_with("p.toml: "), "{e}");
    let e = err_of(|p| {
        let first = p.balls.check[0].clone();
        p.balls.check.push(first)
    });
    assert!(
        e.starts_with("p.toml: ") && e.contains("check: 'B4' appears twice"),
        "{e}"
    );
}

/// Issue 37: `[lrf] lrf_model` gives the whole mount from a file; with the `mount_*` keys
/// too the mount would be given twice, which is refused naming both.
#[test]
fn lrf_model_file_and_mount_keys_are_not_both_given() {
    let p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    assert_eq!(p.lrf.lrf_model, None);
    let mut q = p.clone();
    q.lrf.lrf_model = Some("mount.json".into());
    q.lrf.mount_offset_mm = [0.0; 3];
    q.lrf.mount_tilt_x_deg = 0.0;
    q.lrf.mount_tilt_z_deg = 0.0;
    q.lrf.servo_zero_deg = 0.0;
    q.validate("p.toml").unwrap();
    let again = ProjectFile::parse(&q.to_toml_string(), "again").unwrap();
    assert_eq!(again.lrf.lrf_model.as_deref(), Some("mount.json"));
    let e = err_of(|p| {
        p.lrf.lrf_model = Some("mount.json".into());
        p.lrf.mount_tilt_x_deg = 0.3;
    });
    assert!(
        e.contains("lrf_model = \"mount.json\" and the mount_* / servo_zero_deg keys both"),
        "{e}"
    );
}

/// Issue 35: each camera model takes its own keys and parameter names; another model's are
/// refused with the model's list, and the focal length is required.
#[test]
fn each_camera_model_takes_its_own_parameters() {
    let fisheye = |p: &mut ProjectFile| {
        let c = &mut p.cameras[0];
        c.model = CameraModel::KannalaBrandt;
        c.initial = KeyedValues(vec![("fx".into(), 300.0), ("fy".into(), 301.0)]);
        c.free = Parameter::of(CameraModel::KannalaBrandt);
    };
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    fisheye(&mut p);
    p.validate("example.toml").unwrap();
    let c = &p.cameras[0];
    let i = c.intrinsics();
    let centre = [0.5 * (c.width as f64 - 1.0), 0.5 * (c.height as f64 - 1.0)];
    assert_eq!(
        i.values,
        [300.0, 301.0, centre[0], centre[1], 0.0, 0.0, 0.0, 0.0]
    );
    assert_eq!(c.free_flags(), vec![true; 8]);
    let again = ProjectFile::parse(&p.to_toml_string(), "again").unwrap();
    assert_eq!(again, p, "a fisheye camera round-trips through the file");
    let e = err_of(|p| {
        fisheye(p);
        p.cameras[0].free.push(Parameter::K1);
    });
    assert!(
        e.contains("free: 'K1' is not a parameter of model 'kannala-brandt' (its parameters: fx, fy, cx, cy, k1, k2, k3, k4)"),
        "{e}"
    );
    let e = err_of(|p| {
        fisheye(p);
        p.cameras[0].initial.0.push(("c_mm".into(), 2.45));
    });
    assert!(
        e.contains("initial: 'c_mm' is not a parameter of model 'kannala-brandt'"),
        "{e}"
    );
    let e = err_of(|p| {
        fisheye(p);
        p.cameras[0].initial.0.remove(1);
    });
    assert!(
        e.contains("initial: no fy: model 'kannala-brandt' needs its focal length"),
        "{e}"
    );
    let e = err_of(|p| {
        p.cameras[0].model = CameraModel::DoubleSphere;
        p.cameras[0].initial = KeyedValues(vec![
            ("fx".into(), 300.0),
            ("fy".into(), 300.0),
            ("alpha".into(), 1.2),
        ]);
        p.cameras[0].free.clear();
    });
    assert!(e.contains("initial alpha = 1.2"), "{e}");
}

/// Issue 16: `[frames]` defaults to `camera_optical` and `laser`; a name that cannot go
/// unquoted into a shell command, XML or Python, or two equal names, are refused.
#[test]
fn frame_names_default_and_are_checked() {
    let p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    assert_eq!(p.frames, ProjectFrames::default());
    assert_eq!(
        (p.frames.camera.as_str(), p.frames.lrf.as_str()),
        ("camera_optical", "laser")
    );
    let e = err_of(|p| p.frames.lrf = "my laser".into());
    assert!(e.contains("[frames] lrf = \"my laser\""), "{e}");
    let e = err_of(|p| p.frames.camera = "/cam".into());
    assert!(e.contains("[frames] camera = \"/cam\""), "{e}");
    let e = err_of(|p| p.frames.camera = "laser".into());
    assert!(e.contains("distinct"), "{e}");
    let mut q = p.clone();
    q.frames.lrf = "hokuyo_link".into();
    q.validate("q.toml").unwrap();
    assert_eq!(ProjectFile::parse(&q.to_toml_string(), "again").unwrap(), q);
}

/// Issue 17: `[network] min_intersection_angle_deg` defaults to 2°, is refused outside
/// [0°, 90°) by name, and survives a round trip when set.
#[test]
fn the_intersection_angle_defaults_and_is_checked() {
    let p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    assert_eq!(p.network.min_intersection_angle_deg, 2.0);
    for bad in [-1.0, 90.0, f64::NAN] {
        let e = err_of(|p| p.network.min_intersection_angle_deg = bad);
        assert!(
            e.contains("[network] min_intersection_angle_deg"),
            "{bad}: {e}"
        );
    }
    let mut q = p.clone();
    q.network.min_intersection_angle_deg = 5.0;
    q.validate("q.toml").unwrap();
    let text = q.to_toml_string();
    assert!(text.contains("[network]"), "{text}");
    assert_eq!(ProjectFile::parse(&text, "again").unwrap(), q);
    assert!(!p.to_toml_string().contains("[network]"));
}

/// Issue 14: values that were accepted although absurd (and then not used).
#[test]
fn absurd_sensor_values_are_named() {
    let e = err_of(|p| p.stereo.as_mut().unwrap().baseline_mm = f64::NAN);
    assert!(
        e.starts_with("p.toml: ") && e.contains("baseline_mm = NaN"),
        "{e}"
    );
    let e = err_of(|p| p.lrf.servo_resolution_deg = f64::NAN);
    assert!(e.contains("servo_resolution_deg = NaN"), "{e}");
    let e = err_of(|p| p.lrf.max_range_mm = 1.0);
    assert!(
        e.contains("max_range_mm = 1") && e.contains("metres"),
        "{e}"
    );
}

#[test]
fn syntax_errors_have_the_line() {
    let text = readme_example().replace("width = 1280", "width = \"wide\"");
    let e = ProjectFile::parse(&text, "x.toml").unwrap_err().to_string();
    assert!(e.starts_with("x.toml: ") && e.contains("line"), "{e}");
    assert!(!e.contains('\n'));
    let e = ProjectFile::parse(
        &readme_example().replace("[lrf]", "[lrf]\ncolour = 3"),
        "x.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("colour"), "{e}");
}

/// The README's example with the first `from` replaced by `to`, parsed: the error, and the
/// line of the replacement.
fn parse_err_of(from: &str, to: &str) -> (String, usize) {
    let example = readme_example();
    let at = example
        .find(from)
        .unwrap_or_else(|| panic!("{from:?} in the example"));
    let line = 1 + example[..at].matches('\n').count();
    let text = example.replacen(from, to, 1);
    let e = ProjectFile::parse(&text, "project.toml")
        .unwrap_err()
        .to_string();
    assert!(!e.contains('\n'), "{e}");
    (e, line)
}

#[test]
fn an_unknown_method_is_refused_at_parse_time() {
    let (e, line) = parse_err_of("method = \"both\"", "method = \"joint2\"");
    assert_eq!(
        e,
        format!(
            "project.toml: line {line}: method = \"joint2\": expected one of spheres, corner, both, joint, all"
        )
    );
    // the message of the validation this replaces
    let (e, _) = parse_err_of("method = \"both\"", "method = \"magic\"");
    assert!(e.contains("method = \"magic\""), "{e}");
}

#[test]
fn an_unknown_target_family_is_refused_at_parse_time() {
    let (e, line) = parse_err_of("family = \"aicon14\"", "family = \"aicon16\"");
    assert_eq!(
        e,
        format!(
            "project.toml: line {line}: family = \"aicon16\": expected one of aicon14, aicon12"
        )
    );
}

#[test]
fn an_unknown_camera_model_is_refused_at_parse_time() {
    let (e, line) = parse_err_of("model = \"photogrammetric\"", "model = \"pinhole\"");
    assert_eq!(
        e,
        format!("project.toml: line {line}: model = \"pinhole\": expected one of photogrammetric, brown-backward, opencv, kannala-brandt, double-sphere")
    );
}

#[test]
fn an_unknown_free_parameter_is_refused_at_parse_time() {
    let all = "c, xp, yp, K1, K2, K3, P1, P2, B1, B2, fx, fy, cx, cy, k1, k2, k3, k4, k5, k6, p1, p2, s1, s2, s3, s4, xi, alpha";
    let (e, line) = parse_err_of("free = [\"c\", ", "free = [\"K9\", \"c\", ");
    assert_eq!(
        e,
        format!("project.toml: line {line}: free: \"K9\": expected one of {all}")
    );
    // a list over several lines: the value alone
    let (e, line) = parse_err_of("free = [\"c\", ", "free = [\n\"K9\", \"c\", ");
    assert_eq!(
        e,
        format!(
            "project.toml: line {}: \"K9\": expected one of {all}",
            line + 1
        )
    );
}

#[test]
fn a_word_of_the_wrong_type_is_refused_with_the_words_allowed() {
    let (e, line) = parse_err_of("method = \"both\"", "method = 3");
    assert_eq!(
        e,
        format!("project.toml: line {line}: method = 3: invalid type: integer `3`, expected one of spheres, corner, both, joint, all")
    );
}

/// A file without `method` runs the joint adjustment.
#[test]
fn the_method_defaults_to_joint() {
    let text = readme_example().replacen("method = \"both\"", "", 1);
    let p = ProjectFile::parse(&text, "project.toml").expect("parses");
    assert_eq!(p.method, Method::Joint);
}

#[test]
fn other_syntax_errors_name_the_entry() {
    let (e, line) = parse_err_of("width = 1280", "width = \"wide\"");
    assert_eq!(
        e,
        format!("project.toml: line {line}: width = \"wide\": invalid type: string \"wide\", expected u32")
    );
    let (e, line) = parse_err_of("c_mm = 2.45", "c_mm = 2.45\nc_mm = 2.5");
    assert_eq!(
        e,
        format!("project.toml: line {}: c_mm: duplicate key", line + 1)
    );
    // inside an inline table: the key of the value, quotes and separators in strings skipped
    let (e, line) = parse_err_of("id = \"B4\", x = 61.5", "id = \"B=,{\\\"4\", x = \"61.5\"");
    assert_eq!(
        e,
        format!(
            "project.toml: line {line}: x = \"61.5\": invalid type: string \"61.5\", expected f64"
        )
    );
    let (e, line) = parse_err_of("x = 61.5", "y = 1.0, x = 61.5");
    assert_eq!(e, format!("project.toml: line {line}: y: duplicate key"));
    // a missing key of a table: the table's header
    let (e, _) = parse_err_of("dot_radius_mm = 8.0", "");
    let header = 1 + readme_example()
        .lines()
        .position(|l| l == "[targets]")
        .unwrap();
    assert_eq!(
        e,
        format!("project.toml: line {header}: [targets]: missing field `dot_radius_mm`")
    );
}

#[test]
fn the_closed_sets_spell_as_the_file() {
    fn check<T: Copy + PartialEq + std::fmt::Debug + std::fmt::Display + serde::Serialize>(
        all: &[T],
        names: &[&str],
        as_str: fn(T) -> &'static str,
        from_word: fn(&str) -> Option<T>,
    ) {
        assert_eq!(all.len(), names.len());
        for (v, n) in all.iter().zip(names) {
            assert_eq!(as_str(*v), *n);
            assert_eq!(v.to_string(), *n);
            assert_eq!(from_word(n), Some(*v));
        }
        assert_eq!(from_word("nothing"), None);
    }
    check(
        &Method::ALL,
        &Method::NAMES,
        Method::as_str,
        Method::from_word,
    );
    check(
        &TargetFamily::ALL,
        &TargetFamily::NAMES,
        TargetFamily::as_str,
        TargetFamily::from_word,
    );
    check(
        &CameraModel::ALL,
        &CameraModel::NAMES,
        CameraModel::name,
        CameraModel::from_name,
    );
    check(
        &Parameter::ALL,
        &Parameter::NAMES,
        Parameter::as_str,
        Parameter::from_word,
    );
    assert_eq!(Method::NAMES, ["spheres", "corner", "both", "joint", "all"]);
    check(
        &MountParameter::ALL,
        &MountParameter::NAMES,
        MountParameter::as_str,
        MountParameter::from_word,
    );
    for (k, p) in MountParameter::ALL.iter().enumerate() {
        assert_eq!(p.index(), k);
    }
    assert_eq!(TargetFamily::NAMES, ["aicon14", "aicon12"]);
    assert_eq!(
        CameraModel::NAMES,
        pingcal_camera::ModelKind::NAMES,
        "the project's models are the camera crate's"
    );
    for m in CameraModel::ALL {
        for (k, p) in Parameter::of(m).iter().enumerate() {
            assert_eq!(p.index_in(m), Some(k), "{m} {p}");
        }
    }
    assert_eq!(
        PARAMETER_NAMES,
        ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1", "B2"]
    );
    assert_eq!(
        Parameter::of(CameraModel::Photogrammetric),
        Parameter::ALL[..10]
    );
    for f in TargetFamily::ALL {
        assert_eq!(TargetFamily::from_code_bits(f.code_bits()), Some(f));
        assert_eq!(f.as_str(), format!("aicon{}", f.code_bits()));
    }
    assert_eq!(TargetFamily::from_code_bits(16), None);
    assert!(Method::Both.spheres() && Method::Both.corner());
    assert!(Method::Spheres.spheres() && !Method::Spheres.corner());
    assert!(!Method::Corner.spheres() && Method::Corner.corner());
    assert!(Method::Joint.joint() && Method::Joint.spheres() && !Method::Joint.corner());
    assert!(Method::All.joint() && Method::All.spheres() && Method::All.corner());
    assert!(!Method::Both.joint() && Method::default() == Method::Joint);
}

proptest::proptest! {
    #[test]
    fn parser_never_panics(cut in 0usize..4000, junk in "[ -~\n]{0,40}") {
        let example = readme_example();
        let cut = cut.min(example.len());
        let cut = (0..=cut).rev().find(|&c| example.is_char_boundary(c)).unwrap_or(0);
        let text = format!("{}{}", &example[..cut], junk);
        if let Ok(p) = ProjectFile::parse(&text, "fuzz.toml") {
            let _ = p.validate("fuzz.toml");
        }
    }
}

/// `[targets] layout` is read with the project: its errors name the project, the key, the
/// layout file and its line; a layout too large to be one is refused unread; `layout_sigma_mm`
/// must be a positive length.
#[test]
fn the_layout_is_read_with_the_project_and_its_errors_named() {
    let dir = std::env::temp_dir().join(format!("pingcal-project-layout-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    p.images
        .iter()
        .for_each(|im| std::fs::write(dir.join(im.file.replace('/', "_")), b"").unwrap());
    for im in &mut p.images {
        im.file = im.file.replace('/', "_");
    }
    p.lrf
        .scans
        .iter()
        .for_each(|s| std::fs::write(dir.join(s.file().replace('/', "_")), SCAN).unwrap());
    for s in &mut p.lrf.scans {
        *s = ScanEntry::File(s.file().replace('/', "_"));
    }
    p.targets.layout = Some("layout.csv".into());
    let toml = dir.join("project.toml");
    std::fs::write(&toml, p.to_toml_string()).unwrap();
    let load = |layout: &str| {
        std::fs::write(dir.join("layout.csv"), layout).unwrap();
        Project::load(&toml)
    };
    let ok = load("id,x_mm,y_mm,z_mm\n17,1,2,3\n").unwrap();
    assert_eq!(ok.layout.unwrap().points[&17], [1.0, 2.0, 3.0]);
    let e = load("17,1,2,3\n18,1,2\n").unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}: [targets] layout: ", toml.display()))
            && e.ends_with("layout.csv:2: 3 fields: expected 4 (id,x_mm,y_mm,z_mm)"),
        "{e}"
    );
    let big = std::fs::File::create(dir.join("layout.csv")).unwrap();
    big.set_len(MAX_TEXT_BYTES + 1).unwrap();
    drop(big);
    let e = Project::load(&toml).unwrap_err().to_string();
    assert!(
        e.contains("more than the") && e.contains("layout.csv"),
        "{e}"
    );
    std::fs::remove_file(dir.join("layout.csv")).unwrap();
    let e = Project::load(&toml).unwrap_err().to_string();
    assert!(
        e.contains("[targets] layout \"layout.csv\"") && e.contains("not found"),
        "{e}"
    );
    let e = err_of(|p| p.targets.layout_sigma_mm = 0.0);
    assert!(
        e.contains("layout_sigma_mm = 0: expected a positive length"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 16: `[lrf.bag]` names bags and their topics instead of (or besides) scan files.
#[test]
fn an_lrf_bag_section_is_read_and_checked() {
    let bag = "\n[lrf.bag]\nfiles = [\"run.bag\"]\nscan_topic = \"/scan\"\nservo_topic = \"/joint_states\"\nservo_joint = \"servo\"\n";
    let text = format!("{}{bag}", readme_example());
    let p = ProjectFile::parse(&text, "p.toml").unwrap();
    p.validate("p.toml").unwrap();
    let b = p.lrf.bag.clone().unwrap();
    assert_eq!(
        (b.files.len(), b.servo_joint.as_deref()),
        (1, Some("servo"))
    );
    let again = ProjectFile::parse(&p.to_toml_string(), "again").unwrap();
    assert_eq!(again, p);
    let check = |edit: &dyn Fn(&mut ProjectFile)| {
        let mut q = p.clone();
        edit(&mut q);
        q.validate("p.toml").unwrap_err().to_string()
    };
    let e = check(&|q| q.lrf.bag.as_mut().unwrap().servo_scale = Some(0.088));
    assert!(
        e.contains("[lrf.bag] servo_joint, servo_scale/servo_offset and servo_tf_child: give one"),
        "{e}"
    );
    let e = check(&|q| q.lrf.bag.as_mut().unwrap().servo_tf_child = Some("servo_link".into()));
    assert!(e.contains("servo_tf_child: give one"), "{e}");
    let e = check(&|q| q.lrf.bag.as_mut().unwrap().servo_axis = Some([0.0, 1.0, 0.0]));
    assert!(
        e.contains("[lrf.bag] servo_axis = [0.0, 1.0, 0.0]: only for a tf servo topic"),
        "{e}"
    );
    let tf = |axis: [f64; 3]| {
        move |q: &mut ProjectFile| {
            let b = q.lrf.bag.as_mut().unwrap();
            b.servo_joint = None;
            b.servo_tf_child = Some("servo_link".into());
            b.servo_axis = Some(axis);
        }
    };
    let mut q = p.clone();
    tf([0.0, 2.0, 0.0])(&mut q);
    q.validate("p.toml").unwrap();
    let e = check(&tf([0.0, 0.0, 0.0]));
    assert!(
        e.contains("servo_axis = [0.0, 0.0, 0.0]: expected three finite numbers"),
        "{e}"
    );
    let e = check(&|q| {
        q.lrf.noise = Some(NoiseProfile::Utm30lx);
        q.lrf.noise_sigma_mm = Some([10.0, 0.0])
    });
    assert!(
        e.contains("[lrf] noise and [lrf] noise_sigma_mm: give one"),
        "{e}"
    );
    let e = check(&|q| q.lrf.noise_sigma_mm = Some([-1.0, 0.0]));
    assert!(
        e.contains("[lrf] noise_sigma_mm = [-1, 0]: expected 0 < a"),
        "{e}"
    );
    let e = check(&|q| q.lrf.bag.as_mut().unwrap().files.clear());
    assert!(e.contains("[lrf.bag] files: no bag"), "{e}");
    let e = check(&|q| {
        q.lrf.bag = None;
        q.lrf.scans.clear()
    });
    assert!(
        e.contains("[lrf] scans: no scan file (and no [lrf.bag])"),
        "{e}"
    );
    let e = check(&|q| {
        let b = q.lrf.bag.as_mut().unwrap();
        b.servo_joint = None;
        b.servo_scale = Some(0.0);
    });
    assert!(e.contains("the scale not 0"), "{e}");
    let mut q = p.clone();
    q.lrf.bag.as_mut().unwrap().servo_motion = Some(ServoMotion::StopAndGo);
    q.validate("p.toml").unwrap();
    let again = ProjectFile::parse(&q.to_toml_string(), "again").unwrap();
    assert_eq!(again, q);
    let t = text.replace("servo_joint = ", "servo_jiont = ");
    assert!(ProjectFile::parse(&t, "p.toml").is_err());
}

/// Issue 39: values no camera, ball or mount can have are refused with the bound named, and
/// a mount parameter that is never estimated is refused in `self_calibrate`.
#[test]
fn implausible_values_are_refused_with_the_bound() {
    let e = err_of(|p| p.cameras[0].initial.set("k1", 1e308));
    assert!(
        e.contains("cameras[0] (id 'left'): initial k1 = 1e308: the distortion would move the sensor's corner by"),
        "{e}"
    );
    let e = err_of(|p| p.cameras[0].initial.set("p2", -1e3));
    assert!(e.contains("initial p2 = -1000"), "{e}");
    let e = err_of(|p| p.cameras[0].initial.set("c_mm", 1e6));
    assert!(
        e.contains("initial c_mm = 1000000: more than 100 times"),
        "{e}"
    );
    let e = err_of(|p| p.cameras[1].initial.set("xp_mm", 3.0));
    assert!(
        e.contains("the principal point must lie on the sensor"),
        "{e}"
    );
    let e = err_of(|p| p.cameras[0].initial.set("b2", 2.0));
    assert!(
        e.contains("initial b2 = 2: an affinity or shear beyond ±0.5"),
        "{e}"
    );
    // a model in pixels is bounded in pixels
    let pixels = |fx: f64, cx: f64| {
        move |p: &mut ProjectFile| {
            let c = &mut p.cameras[0];
            c.model = CameraModel::OpenCv;
            c.free = Parameter::of(CameraModel::OpenCv);
            c.initial = KeyedValues(vec![
                ("fx".into(), fx),
                ("fy".into(), 611.0),
                ("cx".into(), cx),
                ("cy".into(), 360.0),
            ]);
        }
    };
    let e = err_of(pixels(611.0, -5.0));
    assert!(
        e.contains("initial cx = -5, cy = 360: the principal point must lie on the image (0 to 1280, 0 to 720 px)"),
        "{e}"
    );
    let e = err_of(pixels(1e9, 640.0));
    assert!(
        e.contains("initial fx = 1e9: more than 100 times the image's diagonal"),
        "{e}"
    );
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    pixels(611.0, 640.0)(&mut p);
    p.validate("p.toml").unwrap();
    // a strong but real wide-angle distortion passes (15 % at the corner)
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    p.cameras[0].initial.set("k1", -0.02);
    p.validate("p.toml").unwrap();
    let e = err_of(|p| p.targets.dot_radius_mm = 1e300);
    assert!(
        e.contains("[targets] dot_radius_mm = 1e300: beyond the bound of 1e6 mm"),
        "{e}"
    );
    let e = err_of(|p| p.distances[0].distance_mm = 2e6);
    assert!(
        e.contains("distance_mm = 2000000: beyond the bound of 1e6 mm"),
        "{e}"
    );
    let e = err_of(|p| p.lrf.accuracy_far_fraction = 3.0);
    assert!(
        e.contains("[lrf] accuracy_far_fraction = 3: beyond the bound of 1e0"),
        "{e}"
    );
    let e = err_of(|p| p.balls.labels[0].id = String::new());
    assert!(e.contains("[balls] labels: an id is empty"), "{e}");
    let e = err_of(|p| p.lrf.self_calibrate = Some(vec![MountParameter::OffsetY]));
    assert!(
        e.contains("[lrf] self_calibrate: \"offset_y\" is the LRF frame's origin")
            && e.contains("estimable: offset_x, offset_z, tilt_x"),
        "{e}"
    );
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    p.lrf.self_calibrate = Some(vec![MountParameter::OffsetX, MountParameter::TiltZ]);
    p.validate("p.toml").unwrap();
}

/// Issue 39: one image or scan listed twice under two spellings is refused by the files'
/// canonical paths (the project's own check compares the text only).
#[test]
fn a_file_listed_twice_under_two_spellings_is_refused() {
    let dir = std::env::temp_dir().join(format!("pingcal-project-twice-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("images")).unwrap();
    std::fs::create_dir_all(dir.join("scans")).unwrap();
    let base = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    for im in &base.images {
        std::fs::write(dir.join(&im.file), b"").unwrap();
    }
    for s in &base.lrf.scans {
        std::fs::write(dir.join(s.file()), SCAN).unwrap();
    }
    let toml = dir.join("project.toml");
    let load = |p: &ProjectFile| {
        std::fs::write(&toml, p.to_toml_string()).unwrap();
        Project::load(&toml)
    };
    load(&base).unwrap();
    let mut p = base.clone();
    let first = p.images[0].file.clone();
    let (d, f) = first.rsplit_once('/').unwrap();
    p.images[1].file = format!("{d}/./{f}");
    let e = load(&p).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "images[1] file \"{d}/./{f}\" is the same file as images[0] file \"{first}\""
        )),
        "{e}"
    );
    let mut p = base.clone();
    let s = p.lrf.scans[0].clone();
    p.lrf.scans.push(s.clone());
    let e = load(&p).unwrap_err().to_string();
    assert!(
        e.contains(&format!(
            "[lrf] scans[1] \"{s}\" is the same file as [lrf] scans[0] \"{s}\""
        )),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 49: every closed-set key of the file given a wrong word is refused while the file
/// is read, in one line naming the file, the line, the key and its value, and the words
/// allowed — the LRF's words (`noise`, `cloud_unit`, `servo_motion`) as the others.
#[test]
fn every_closed_set_key_refuses_a_wrong_word_with_its_line_and_the_words_allowed() {
    let bag = "\n[lrf.bag]\nfiles = [\"run.bag\"]\nscan_topic = \"/scan\"\nservo_topic = \"/joint_states\"\nservo_joint = \"servo\"\nservo_motion = \"auto\"\n";
    let example = readme_example() + bag;
    let max = "max_range_mm = 5600.0";
    let own = "self_calibrate = [\"offset_x\"";
    let cases = [
        (
            "method = \"both\"",
            "method = \"bogus\"".to_string(),
            "method = \"bogus\": expected one of spheres, corner, both, joint, all",
        ),
        (
            "family = \"aicon14\"",
            "family = \"bogus\"".into(),
            "family = \"bogus\": expected one of aicon14, aicon12",
        ),
        (
            "model = \"photogrammetric\"",
            "model = \"bogus\"".into(),
            "model = \"bogus\": expected one of photogrammetric",
        ),
        (
            "free = [\"c\", ",
            "free = [\"bogus\", \"c\", ".into(),
            "free: \"bogus\": expected one of c, xp, yp, K1",
        ),
        (
            max,
            format!("noise = \"bogus\"\n{max}"),
            "noise = \"bogus\": expected one of URG-04LX, UTM-30LX, UST-10LX, VLP-16",
        ),
        (
            max,
            format!("cloud_unit = \"bogus\"\n{max}"),
            "cloud_unit = \"bogus\": expected one of mm, m",
        ),
        (
            own,
            "self_calibrate = [\"bogus\", \"offset_x\"".into(),
            "self_calibrate: \"bogus\": expected one of offset_x, offset_y, offset_z, tilt_x, tilt_z, servo_scale, range_offset, range_scale",
        ),
        (
            "servo_motion = \"auto\"",
            "servo_motion = \"bogus\"".into(),
            "servo_motion = \"bogus\": expected one of auto, stop-and-go, continuous",
        ),
        (
            "servo_motion = \"auto\"",
            "servo_motion = \"auto\"\nstamps = \"sundial\"".into(),
            "stamps = \"sundial\": expected one of auto, header, record",
        ),
    ];
    for (from, to, message) in cases {
        let at = example.find(from).unwrap_or_else(|| panic!("{from:?}"));
        // the wrong word's line: the replaced line, or the line inserted after it
        let line = 1 + example[..at].matches('\n').count() + usize::from(to.starts_with(from));
        let text = example.replacen(from, &to, 1);
        let e = ProjectFile::parse(&text, "project.toml")
            .unwrap_err()
            .to_string();
        assert!(!e.contains('\n'), "{e}");
        let head = format!("project.toml: line {line}: {message}");
        assert!(e.starts_with(&head), "{e}\nnot\n{head}");
    }
    // a profile's name is read with case and -/_ ignored, and written as spelt
    let text = example.replacen(max, &format!("noise = \"utm_30lx\"\n{max}"), 1);
    let p = ProjectFile::parse(&text, "project.toml").unwrap();
    assert_eq!(p.lrf.noise, Some(NoiseProfile::Utm30lx));
    assert!(p.to_toml_string().contains("noise = \"UTM-30LX\""));
}

/// The `[lrf]` settings are resolved while the file is checked: the noise of the
/// `accuracy_*` keys, of a profile or of σ = a + b·r, and the bag's servo.
#[test]
fn the_lrf_settings_are_resolved_once_at_validation() {
    use pingcal_lrf::sensor::RangeNoise;
    use pingcal_lrf::settings::ServoSource;
    let mut p = ProjectFile::parse(&readme_example(), "p.toml").unwrap();
    let s = p.checked("p.toml").unwrap();
    assert_eq!(s.noise, RangeNoise::from_datasheet(30.0, 0.03, 3.0));
    assert!(s.bag.is_none());
    p.lrf.noise = Some(NoiseProfile::Vlp16);
    assert_eq!(
        p.checked("p.toml").unwrap().noise,
        NoiseProfile::Vlp16.noise()
    );
    p.lrf.noise = None;
    p.lrf.noise_sigma_mm = Some([5.0, 0.002]);
    assert_eq!(p.checked("p.toml").unwrap().noise.sigma(1000.0), 7.0);
    p.lrf.bag = Some(ProjectBag {
        files: vec!["run.bag".into()],
        scan_topic: "/scan".into(),
        servo_topic: "/tf".into(),
        servo_joint: None,
        servo_scale: None,
        servo_offset: None,
        servo_tf_child: Some("servo_link".into()),
        servo_axis: Some([0.0, 0.0, -3.0]),
        servo_motion: Some(ServoMotion::Continuous),
        stamps: Some(Stamps::Record),
    });
    let bag = p.checked("p.toml").unwrap().bag.unwrap();
    assert_eq!(
        bag.source,
        ServoSource::Tf {
            child: "servo_link".into(),
            axis: [0.0, 0.0, -1.0]
        }
    );
    assert_eq!(bag.motion, ServoMotion::Continuous);
    assert_eq!(bag.stamps, Stamps::Record);
}

/// Issue 51: `[board]`, its words refused at parse time with the line, its keys checked with
/// the file, and Kalibr's `target.yaml` read at load.
#[test]
fn a_board_is_read_from_its_table_or_from_kalibrs_target_file() {
    let board = "\n[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]\nsquare_mm = 25.0\n";
    let text = readme_example() + board;
    let p = ProjectFile::parse(&text, "project.toml").unwrap();
    p.validate("project.toml").unwrap();
    assert_eq!(
        p.board.as_ref().unwrap().table().unwrap(),
        Board::Chessboard {
            cols: 9,
            rows: 6,
            square_mm: 25.0
        }
    );
    assert_eq!(ProjectFile::parse(&p.to_toml_string(), "again").unwrap(), p);
    let line = 1 + text.matches('\n').count() - 3;
    let e = ProjectFile::parse(
        &text.replace("\"chessboard\"", "\"checkerboard\""),
        "project.toml",
    )
    .unwrap_err()
    .to_string();
    assert_eq!(
        e,
        format!("project.toml: line {line}: kind = \"checkerboard\": expected one of chessboard, charuco, aprilgrid")
    );
    let e = ProjectFile::parse(&text.replace("square_mm = 25.0\n", ""), "project.toml")
        .unwrap()
        .validate("project.toml")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "project.toml: [board] kind = \"chessboard\" needs square_mm"
    );
    // `from`: Kalibr's file, read when the project is loaded; no other key beside it.
    let dir = std::env::temp_dir().join(format!("pingcal-project-board-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    for im in &mut p.images {
        im.file = im.file.replace('/', "_");
        std::fs::write(dir.join(&im.file), b"").unwrap();
    }
    for s in &mut p.lrf.scans {
        *s = ScanEntry::File(s.file().replace('/', "_"));
        std::fs::write(dir.join(s.file()), SCAN).unwrap();
    }
    p.board = Some(ProjectBoard {
        from: Some("target.yaml".into()),
        ..Default::default()
    });
    let toml = dir.join("project.toml");
    std::fs::write(&toml, p.to_toml_string()).unwrap();
    std::fs::write(
        dir.join("target.yaml"),
        "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n",
    )
    .unwrap();
    Project::load(&toml).unwrap();
    std::fs::write(dir.join("target.yaml"), "target_type: 'circlegrid'\n").unwrap();
    let e = Project::load(&toml).unwrap_err().to_string();
    assert!(
        e.contains("[board] from = \"target.yaml\"") && e.contains("checkerboard and aprilgrid"),
        "{e}"
    );
    p.board.as_mut().unwrap().square_mm = Some(20.0);
    std::fs::write(&toml, p.to_toml_string()).unwrap();
    let e = Project::load(&toml).unwrap_err().to_string();
    assert!(e.contains("give no other [board] key beside it"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scan file whose servo contradicts `[lrf] kind` is refused at load, naming the entry:
/// a rotating LRF's scans that never turned, a fixed LRF's that swept; the same files with
/// the other kind load.
#[test]
fn a_scan_file_of_the_other_lrf_kind_is_refused_at_load() {
    let dir = std::env::temp_dir().join(format!("pingcal-project-kind-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("images")).unwrap();
    std::fs::create_dir_all(dir.join("scans")).unwrap();
    let base = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    for im in &base.images {
        std::fs::write(dir.join(&im.file), b"").unwrap();
    }
    let head = "# pingcal-scan v1\n# angle_min_deg=-10\n# angle_increment_deg=10\n# range_unit=mm\nstamp_s,servo_deg,r0\n";
    let standing = format!("{head}0,0,1000\n0.1,0,1000\n0.2,0.1,1000\n");
    let sweeping = format!("{head}0,-90,1000\n0.1,0,1000\n0.2,90,1000\n");
    let toml = dir.join("project.toml");
    let load = |scan: &str, kind: Option<LrfKind>| {
        for s in &base.lrf.scans {
            std::fs::write(dir.join(s.file()), scan).unwrap();
        }
        let mut p = base.clone();
        p.lrf.kind = kind;
        p.lrf.station = p.main_station.clone();
        p.method = Method::All;
        std::fs::write(&toml, p.to_toml_string()).unwrap();
        Project::load(&toml)
    };
    let e = load(&standing, None).unwrap_err().to_string();
    assert!(
        e.contains("[lrf] scans[0]")
            && e.contains("within 0.10° of 0.00°: a scanner that did not turn"),
        "{e}"
    );
    let e = load(&sweeping, Some(LrfKind::Fixed))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("[lrf] scans[0]") && e.contains("span 180.0°: a rotating LRF's sweep"),
        "{e}"
    );
    load(&sweeping, None).unwrap();
    load(&standing, Some(LrfKind::Fixed)).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 51: a board's project needs no `[targets]` or `[balls]` (written without them, read
/// back the same); any other project still needs both, refused naming the table.
#[test]
fn a_board_project_needs_no_targets_or_balls_and_another_needs_both() {
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    p.targets = ProjectTargets::absent();
    p.balls = ProjectBalls::absent();
    let text = p.to_toml_string();
    assert!(
        !text.contains("[targets]") && !text.contains("[balls]"),
        "{text}"
    );
    let again = ProjectFile::parse(&text, "p.toml").unwrap();
    assert_eq!(again, p);
    let e = again.validate("p.toml").unwrap_err().to_string();
    assert_eq!(
        e,
        "p.toml: missing [targets] (the coded targets' family and dot_radius_mm), or a [board]"
    );
    let mut with_targets = again.clone();
    with_targets.targets = ProjectFile::parse(&readme_example(), "x").unwrap().targets;
    let e = with_targets.validate("p.toml").unwrap_err().to_string();
    assert_eq!(e, "p.toml: missing [balls] (diameter_mm), or a [board]");
    let board = "\n[board]\nkind = \"chessboard\"\ninner_corners = [9, 6]\nsquare_mm = 25.0\n";
    let p = ProjectFile::parse(&(text + board), "p.toml").unwrap();
    p.validate("p.toml").unwrap();
    assert!(p.targets.is_absent() && p.balls.is_absent());
}

/// `[[rig.cameras]]`: a camera of `[[cameras]]` once, not the main camera nor one of
/// `[stereo]`'s, at a finite pose; each wrong entry is named with what is expected.
#[test]
fn a_rig_camera_is_checked() {
    use crate::{ProjectCamera, ProjectRig, ProjectRigCamera};
    let side = |id: &str| ProjectRigCamera {
        id: id.into(),
        opk_deg: [0.0, 0.0, 60.0],
        t_mm: [60.0, -25.0, 10.0],
        hold: false,
    };
    let with = |cams: Vec<ProjectRigCamera>| {
        move |p: &mut ProjectFile| {
            let mut third: ProjectCamera = p.cameras[0].clone();
            third.id = "side".into();
            p.cameras.push(third);
            p.rig = Some(ProjectRig {
                cameras: cams.clone(),
            });
        }
    };
    let e = err_of(with(vec![side("nope")]));
    assert!(
        e.contains("[[rig.cameras]] id = \"nope\": the camera is not in [[cameras]]"),
        "{e}"
    );
    let e = err_of(with(vec![side("right")]));
    assert!(e.contains("[rig] lists the others"), "{e}");
    let e = err_of(with(vec![side("side"), side("side")]));
    assert!(e.contains("listed twice"), "{e}");
    let mut bad = side("side");
    bad.t_mm[1] = f64::NAN;
    let e = err_of(with(vec![bad]));
    assert!(e.contains("opk_deg and t_mm must be finite"), "{e}");
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    with(vec![side("side")])(&mut p);
    let text = toml::to_string(&p).unwrap();
    let back = ProjectFile::parse(&text, "again.toml").unwrap();
    assert_eq!(back.rig, p.rig, "written and read back");
}

/// `[[lrfs]]`: each needs its own id, new and of letters, digits, `_` or `-`; `[lrf] id`
/// (absent: `lrf`) is another's; written and read back. (Each sensor's other keys are
/// checked as `[lrf]`'s when the project is loaded, as a project of its own.)
#[test]
fn more_range_sensors_need_their_own_ids() {
    let with = |ids: Vec<Option<&'static str>>| {
        move |p: &mut ProjectFile| {
            p.lrfs = ids
                .iter()
                .map(|id| {
                    let mut l = p.lrf.clone();
                    l.id = id.map(String::from);
                    l
                })
                .collect();
        }
    };
    let e = err_of(with(vec![None]));
    assert!(e.contains("[[lrfs]] entry 0: no id"), "{e}");
    let e = err_of(with(vec![Some("lrf")]));
    assert!(
        e.contains("[[lrfs]] id = \"lrf\": expected a new id"),
        "{e}"
    );
    let e = err_of(with(vec![Some("a b")]));
    assert!(e.contains("letters, digits"), "{e}");
    let e = err_of(with(vec![Some("two"), Some("two")]));
    assert!(e.contains("[[lrfs]] id = \"two\""), "{e}");
    let mut p = ProjectFile::parse(&readme_example(), "example.toml").unwrap();
    with(vec![Some("floor_lrf")])(&mut p);
    p.validate("p.toml").unwrap();
    let back = ProjectFile::parse(&toml::to_string(&p).unwrap(), "again.toml").unwrap();
    assert_eq!(back.lrfs, p.lrfs, "written and read back");
    let mut board = p.clone();
    board.board = Some(crate::board::ProjectBoard {
        kind: Some(crate::BoardKind::Chessboard),
        inner_corners: Some([9, 6]),
        square_mm: Some(25.0),
        ..Default::default()
    });
    let e = board.validate("b.toml").unwrap_err().to_string();
    assert!(e.contains("[[lrfs]] with [board]"), "{e}");
    let one = p.with_range_sensor(0);
    assert_eq!(
        (one.lrf.id(), one.frames.lrf.as_str()),
        ("floor_lrf", "floor_lrf")
    );
    assert!(one.lrfs.is_empty());
}
