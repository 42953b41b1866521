//! The outputs for other ecosystems (issues 16 and 33), checked by each ecosystem's own
//! code: OpenCV (`cv2.projectPoints` with `opencv/camera_*.yaml` against pingcal's
//! projection, `cv2.stereoRectify` against `opencv/stereo.yaml`), SciPy's
//! `spatial.transform` (the quaternions, 4×4 matrices and ω φ κ of `results.json`), the ROS
//! tools' argument orders (commands and launch files parsed as they parse them), a URDF
//! parser (`urdf_parser_py`), PyYAML with `cv2.projectPoints` over a grid of the whole image
//! (Kalibr's camchain and ROS's camera_info, within the loss each file states), and
//! yourdfpy's forward kinematics of `ros/lrf_model.urdf` against `cloud.ply`.
//!
//! The checks are `tests/ecosystem/check.py`, run in the virtual environment that
//! `bash tests/ecosystem/setup.sh` makes under `target/ecosystem-venv`; without it each test
//! prints why it is skipped and passes. The project is the simulated one of the e2e tests
//! with `[frames]` renamed (so that the names are seen to come from the project),
//! calibrated once per test binary.

use crate::common;

use nalgebra::{Matrix3, Vector3};
use pingcal_ba::camera::CameraModel;
use pingcal_pipeline::exports::grid_pixels;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, OnceLock};

/// The frame names written into the test project.
const FRAMES: &str = "\n[frames]\ncamera = \"cam_left_optical\"\nlrf = \"hokuyo_servo\"\n";

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The venv's Python, or `None` after printing why the test is skipped.
fn python(test: &str) -> Option<PathBuf> {
    let py = workspace().join("target/ecosystem-venv/bin/python");
    if py.is_file() {
        return Some(py);
    }
    eprintln!(
        "{test}: skipped: no {} (run `bash tests/ecosystem/setup.sh` to install OpenCV, SciPy, PyYAML, urdf_parser_py and yourdfpy there)",
        py.display()
    );
    None
}

/// The output folder of the test project, calibrated on first use.
fn calibrated() -> &'static Path {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let dir = common::root().join("ecosystem");
        common::copy_dir(common::pristine(), &dir);
        let toml = dir.join("project.toml");
        let text = std::fs::read_to_string(&toml).expect("project.toml");
        std::fs::write(&toml, text + FRAMES).expect("write project.toml");
        let out = dir.join("out");
        let run = calibrate(&toml, &out, &["--quiet"]);
        assert!(run.success(), "calibrate failed: {}", run.stderr);
        out
    })
}

/// `pingcal calibrate TOML --out OUT` with `flags` after them, run in the project's folder.
fn calibrate(toml: &Path, out: &Path, flags: &[&str]) -> common::Run {
    let mut args = vec![
        "calibrate",
        toml.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(flags);
    common::run(&args, toml.parent().expect("the project's folder"))
}

fn mat3(v: &Value) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| v[i][j].as_f64().expect("a number"))
}

fn vec3(v: &Value) -> Vector3<f64> {
    Vector3::from_fn(|i, _| v[i].as_f64().expect("a number"))
}

/// pingcal's camera `c` of `results.json` in its project model, with its parameters.
fn camera(
    project: &pingcal_project::Project,
    c: &Value,
) -> (Arc<dyn CameraModel>, Vec<f64>, u32, u32) {
    let id = c["id"].as_str().unwrap();
    let pc = project.file.cameras.iter().find(|p| p.id == id).unwrap();
    let keys = pingcal_project::intrinsics::keys(pc.model);
    let p = keys.iter().map(|n| c[*n].as_f64().unwrap()).collect();
    (
        pc.model.model(pc.width, pc.height, pc.pixel_size_mm),
        p,
        pc.width,
        pc.height,
    )
}

/// The rays of pingcal's model through the grid of the exported files' loss figures (every
/// pixel 8 px apart, corners included: `exports::grid_pixels`), as directions (x, y, z) of
/// OpenCV's optical frame (x right, y down, z along the axis; a fisheye's rays may point
/// sideways or behind, z ≤ 0), and pingcal's own projection of them, px. Each ray is the
/// pixel unprojected through the model; the projection goes forward through the whole model
/// and so checks the unprojection (to 1e-6 px). A pixel pingcal cannot unproject is left
/// out, as the files' figures leave it out.
fn grid(cam: &dyn CameraModel, p: &[f64], w: u32, h: u32) -> (Vec<[f64; 3]>, Vec<[f64; 2]>) {
    let (mut rays, mut px) = (Vec::new(), Vec::new());
    for uv in grid_pixels(w, h) {
        let Some(x) = cam.unproject(p, &uv) else {
            continue;
        };
        let back = cam.project(p, &x, None, None).expect("in front");
        assert!(
            (back - uv).norm() < 1e-6,
            "{uv:?}: pingcal projects its ray to {back:?}"
        );
        let x = x / x.norm();
        rays.push([x.x, -x.z, x.y]);
        px.push([back.x, back.y]);
    }
    (rays, px)
}

/// `probe.json`: for each camera, points of the LRF frame spread over its image at 0.8 to
/// 6 m, and pingcal's projection of them (through the extrinsic, and the rig for the right
/// camera); and the camera's [`grid`].
fn probe(out: &Path) -> PathBuf {
    static PROBE: OnceLock<PathBuf> = OnceLock::new();
    PROBE
        .get_or_init(|| write_probe(out, &out.join("../project.toml")))
        .clone()
}

/// Writes [`probe`]'s file (once per test binary: the tests run in parallel).
fn write_probe(out: &Path, project: &Path) -> PathBuf {
    let r = common::read_json(&out.join("results.json"));
    let project = pingcal_project::Project::load(project).unwrap();
    let (rot, t) = (
        mat3(&r["extrinsic"]["rotation"]),
        vec3(&r["extrinsic"]["translation_mm"]),
    );
    let main = r["conventions"]["main_camera"].as_str().unwrap();
    let rig = &r["bundle"]["rig"];
    let mut cams = Vec::new();
    for c in r["cameras"].as_array().unwrap() {
        let (cam, p, w, h) = camera(&project, c);
        let (mut lrf, mut px) = (Vec::new(), Vec::new());
        for i in 0..9 {
            for j in 0..7 {
                for depth in [800.0, 2500.0, 6000.0] {
                    let (x, z) = (-0.7 + 0.175 * i as f64, -0.4 + 0.133 * j as f64);
                    let main_cam = Vector3::new(x * depth, depth, z * depth);
                    let p_lrf = rot.transpose() * (main_cam - t);
                    let here = if c["id"] == main {
                        main_cam
                    } else {
                        mat3(&rig["rotation"]) * main_cam + vec3(&rig["translation_mm"])
                    };
                    let uv = cam.project(&p, &here, None, None).expect("in front");
                    lrf.push([p_lrf.x, p_lrf.y, p_lrf.z]);
                    px.push([uv.x, uv.y]);
                }
            }
        }
        let (rays, grid_px) = grid(cam.as_ref(), &p, w, h);
        cams.push(json!({
            "id": c["id"], "width": w, "height": h, "lrf_points_mm": lrf, "pingcal_px": px,
            "grid_rays_cv": rays, "grid_pingcal_px": grid_px,
        }));
    }
    let path = out.with_extension("probe.json");
    std::fs::write(&path, json!({ "cameras": cams }).to_string()).unwrap();
    path
}

/// Runs `check.py CHECK OUT [EXTRA]` on the test project; prints its figures; fails the
/// test when it fails.
fn check(test: &str, name: &str, extra: Option<&Path>) {
    if python(test).is_some() {
        check_in(test, name, calibrated(), extra);
    }
}

/// Runs `check.py CHECK OUT [EXTRA]` on output folder `out` (skipped, saying why, without
/// the venv).
pub(crate) fn check_in(test: &str, name: &str, out: &Path, extra: Option<&Path>) {
    let Some(py) = python(test) else { return };
    let mut cmd = Command::new(py);
    cmd.arg(workspace().join("tests/ecosystem/check.py"))
        .arg(name)
        .arg(out);
    if let Some(e) = extra {
        cmd.arg(e);
    }
    let o = cmd.output().expect("run python");
    let (so, se) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    eprintln!("{so}");
    assert!(o.status.success(), "check.py {name} failed:\n{so}\n{se}");
}

/// Check `name` of check.py with the probe of pingcal's own projection, where the
/// ecosystem's Python is there (else skipped with the reason [`python`] prints).
fn check_probed(name: &str) {
    if python(name).is_some() {
        let p = probe(calibrated());
        check(name, name, Some(&p));
    }
}

/// `cv2.projectPoints` with each camera's YAML and the OpenCV extrinsic (and rig) of
/// `results.json` puts the LRF points where pingcal's own model does, within 0.02 px.
#[test]
fn opencv_projects_the_lrf_points_where_pingcal_does() {
    check_probed("opencv");
}

/// `cv2.stereoRectify` on `stereo.yaml`'s cameras gives its R1, R2, P1, P2, Q; E and F
/// follow from its R, T, K; R and T are the rig of `results.json`.
#[test]
fn opencv_stereo_rectify_agrees() {
    check("stereo", "stereo", None);
}

/// Every quaternion and 4×4 matrix, through `scipy.spatial.transform`, is the R and t of
/// `results.json` (and ω φ κ give the same R), in both frames.
#[test]
fn quaternions_and_matrices_agree_with_scipy() {
    check("transforms", "transforms", None);
}

/// The ROS 1 and ROS 2 commands and launch files carry the extrinsic in the optical frame
/// in metres, between the project's frame names.
#[test]
fn ros_commands_and_launch_files_publish_the_extrinsic() {
    check("ros", "ros", None);
}

/// The URDF joint, parsed by `urdf_parser_py` and composed, maps back to the extrinsic.
#[test]
fn urdf_joint_composes_back_to_the_extrinsic() {
    check("urdf", "urdf", None);
}

/// `ros/head.urdf`, parsed by `urdf_parser_py`: a fixed joint per sensor of `sensors`
/// (the right camera's optical frame, the LRF's) composes back to its `camera_from_sensor`,
/// and the pair is the composition of the two; Kalibr's chain is `sensors`' too.
#[test]
fn head_urdf_composes_back_to_every_sensor() {
    check("head", "head", None);
    check("chain", "chain", None);
}

/// Kalibr's camchain, read by PyYAML: its radtan refit (cv2.projectPoints with k3 = 0,
/// Kalibr's pinhole-radtan) puts pingcal's rays over the whole image within the loss its
/// comment states (0.05 px or that, and the stated loss equal to the measured one to
/// 1e-3 px), and T_cn_cnm1 is the rig.
#[test]
fn kalibr_camchain_reads_back() {
    check_probed("kalibr");
}

/// `ros/camera_info_<id>.yaml`, read as camera_calibration_parsers lays it out: K and D
/// through cv2.projectPoints over the whole image against pingcal's projection, within the
/// loss its comment states; R and P the stereo rectification's (Tx = −fx'·B, B in m).
#[test]
fn camera_info_projects_where_pingcal_does() {
    check_probed("camera_info");
}

/// `ros/lrf_model.urdf` through yourdfpy's forward kinematics (mimic joint included), at
/// each scan line's servo reading and with the range correction its comment states, puts
/// every beam of the scan file where `cloud.ply` has it (0.01 mm), on the joint project
/// (`lrf_model` the joint adjustment's: every mount and range parameter estimated).
#[test]
fn lrf_model_urdf_rebuilds_cloud_ply_joint() {
    if python("lrf_model_joint").is_none() {
        return;
    }
    let out = calibrated();
    let r = common::read_json(&out.join("results.json"));
    assert_eq!(
        r["lrf_model"]["source"], "joint adjustment",
        "the joint adjustment did not run"
    );
    check_in(
        "lrf_model_joint",
        "lrf_model",
        out,
        Some(&out.join("../project.toml")),
    );
}

/// The mount written into the `method = "spheres"` copy: offset, tilts and servo zero all
/// non-zero (the project has no servo scale or range keys; the joint test covers those).
const SPHERES_MOUNT: &str = "mount_offset_mm = [3.5, -2.0, 8.25]\nmount_tilt_x_deg = 0.3\nmount_tilt_z_deg = -0.2\nservo_zero_deg = 1.75\n";

/// The same on a copy of the test project with `method = "spheres"` and a non-zero mount
/// in `[lrf]`, so `lrf_model` is the project's mount.
#[test]
fn lrf_model_urdf_rebuilds_cloud_ply_spheres() {
    if python("lrf_model_spheres").is_none() {
        return;
    }
    let dir = common::root().join("ecosystem-spheres");
    common::copy_dir(common::pristine(), &dir);
    let toml = dir.join("project.toml");
    let mut text = std::fs::read_to_string(&toml).expect("project.toml");
    for key in [
        "method",
        "mount_offset_mm",
        "mount_tilt_x_deg",
        "mount_tilt_z_deg",
        "servo_zero_deg",
    ] {
        let n = text
            .lines()
            .filter(|l| l.starts_with(&format!("{key} =")))
            .count();
        assert!(n <= 1, "{key} given {n} times");
        text = text
            .lines()
            .filter(|l| !l.starts_with(&format!("{key} =")))
            .collect::<Vec<_>>()
            .join("\n");
    }
    let text = text.replacen("\n[", "\nmethod = \"spheres\"\n\n[", 1);
    let text = text.replacen("\n[lrf]\n", &format!("\n[lrf]\n{SPHERES_MOUNT}"), 1);
    std::fs::write(&toml, text + "\n" + FRAMES).expect("write project.toml");
    let out = dir.join("out");
    // The mount written is not the simulator's, so the registration is rightly doubtful
    // (exit 3); what is checked here is that the files agree with each other, not the fit.
    let run = calibrate(&toml, &out, &["--quiet", "--accept-doubtful"]);
    assert!(run.success(), "calibrate failed: {}", run.stderr);
    assert!(
        run.stderr.contains("doubtful"),
        "a mount that is not the truth passed as ok: {}",
        run.stderr
    );
    let r = common::read_json(&out.join("results.json"));
    let m = &r["lrf_model"];
    assert_eq!(m["source"], "project");
    assert_eq!(
        (m["servo_zero_deg"].as_f64(), m["tilt_x_deg"].as_f64()),
        (Some(1.75), Some(0.3))
    );
    check_in("lrf_model_spheres", "lrf_model", &out, Some(&toml));
}

/// The project's `[frames]` names reach every ROS file of a tf (checked without Python);
/// `camera_info` has no frame (its camera_name is the camera's id).
#[test]
fn frame_names_come_from_the_project() {
    let ros = calibrated().join("ros");
    for f in std::fs::read_dir(&ros).unwrap() {
        let path = f.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("camera_info_") {
            assert!(!text.contains("cam_left_optical"), "{name}");
            continue;
        }
        assert!(
            text.contains("cam_left_optical") && text.contains("hokuyo_servo"),
            "{name}"
        );
    }
    for n in [
        "lrf_model.urdf",
        "lrf_model_ros1.launch",
        "lrf_model_ros2.launch.py",
    ] {
        let text = std::fs::read_to_string(ros.join(n)).unwrap();
        assert!(
            text.contains("hokuyo_servo_scanner") && text.contains("hokuyo_servo_servo"),
            "{n}"
        );
    }
}

/// The simulated field through a fisheye (`pingcal simulate --camera-model M`), simulated
/// once per test binary per model: half the supersampling and the LRF as stated (a quarter
/// of the beams), calibrated by the two-step method, since what is checked is the camera's
/// model and its exports, not the LRF's.
fn fisheye_set(model: &'static str) -> PathBuf {
    static SETS: std::sync::Mutex<Vec<(&'static str, PathBuf)>> = std::sync::Mutex::new(Vec::new());
    let mut sets = SETS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, d)) = sets.iter().find(|(m, _)| *m == model) {
        return d.clone();
    }
    let dir = common::root().join(format!("ecosystem-{model}"));
    let log = common::root().join(format!("ecosystem-{model}-log"));
    std::fs::create_dir_all(&log).expect("log folder");
    let seed = common::SEED.to_string();
    let config = log.join("fisheye.toml");
    std::fs::write(
        &config,
        format!(
            "[render]\nsupersampling = 2\n{}{}",
            common::LRF_AS_STATED,
            common::QUARTER_BEAMS
        ),
    )
    .expect("write the simulator configuration");
    let args = [
        "simulate",
        "--out",
        dir.to_str().unwrap(),
        "--seed",
        &seed,
        "--camera-model",
        model,
        "--config",
        config.to_str().unwrap(),
    ];
    let run = common::run(&args, &log);
    assert!(
        run.success(),
        "simulate --camera-model {model} failed: {}",
        run.stderr
    );
    common::two_step_method(&dir);
    sets.push((model, dir.clone()));
    dir
}

/// The fisheye set calibrated with its own model: the verdict is ok (exit 0).
fn fisheye_calibrated(model: &'static str) -> PathBuf {
    let dir = fisheye_set(model);
    // outside the simulated folder, which another test copies
    let out = common::root().join(format!("ecosystem-{model}-out"));
    let toml = dir.join("project.toml");
    let run = calibrate(&toml, &out, &["--quiet"]);
    assert!(
        run.success(),
        "calibrate ({model}) failed or was doubtful: {}",
        run.stderr
    );
    out
}

/// A fisheye's files read back by each ecosystem's code over the whole image: OpenCV's YAML
/// (`cv::fisheye`) with `cv2.fisheye.projectPoints` (the LRF points and the grid), ROS's
/// `camera_info` (equidistant) likewise, and Kalibr's camchain (pinhole-equidistant for the
/// Kannala–Brandt model, exact; `ds` for the double sphere, exact, projected by the paper's
/// formula written in check.py), each within the loss its comment states.
fn fisheye_exports_read_back(model: &'static str, kalibr_model: &str) {
    let test = format!("fisheye_exports_{model}");
    if python(&test).is_none() {
        return;
    }
    let out = fisheye_calibrated(model);
    let r = common::read_json(&out.join("results.json"));
    assert_eq!(r["verdict"]["status"], "ok", "{}", r["verdict"]);
    for c in r["cameras"].as_array().unwrap() {
        assert_eq!(c["model"], model);
        assert_eq!(
            c["opencv"]["distortion_model"], "fisheye",
            "{}",
            c["opencv"]
        );
    }
    let chain = std::fs::read_to_string(out.join("kalibr/camchain.yaml")).unwrap();
    assert!(
        chain.contains(&format!("camera_model: {kalibr_model}\n")),
        "{chain}"
    );
    let probe = write_probe(&out, &fisheye_set(model).join("project.toml"));
    for name in ["opencv", "camera_info", "kalibr"] {
        check_in(&test, name, &out, Some(&probe));
    }
}

#[test]
fn fisheye_exports_read_back_kannala_brandt() {
    fisheye_exports_read_back("kannala-brandt", "pinhole");
}

#[test]
fn fisheye_exports_read_back_double_sphere() {
    fisheye_exports_read_back("double-sphere", "ds");
}

/// The fisheye's images given as the photogrammetric model (a lens that model cannot
/// describe): the run is doubtful (exit 3), and its first reason names the lens and the
/// models to give instead. `method = "spheres"`: the bundle is what is judged here, and the
/// joint adjustment of a network this wrong takes minutes to give up.
#[test]
fn a_fisheye_given_the_photogrammetric_model_is_named() {
    let src = fisheye_set("kannala-brandt");
    let dir = common::root().join("ecosystem-fisheye-as-photogrammetric");
    common::copy_dir(&src, &dir);
    let toml = dir.join("project.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    let mut out = String::new();
    let mut skip = false;
    for line in text.lines() {
        if line.starts_with('[') {
            skip = false;
        }
        if skip || line.starts_with("free = [\"fx\"") || line.starts_with("method = ") {
            continue;
        }
        match line {
            "model = \"kannala-brandt\"" => {
                out.push_str("model = \"photogrammetric\"\n");
                out.push_str(
                    "free = [\"c\", \"xp\", \"yp\", \"K1\", \"K2\", \"K3\", \"P1\", \"P2\"]\n",
                );
            }
            "[cameras.initial]" => {
                // fx 374 px of 3.75 µm pixels
                out.push_str("[cameras.initial]\nc_mm = 1.4025\n");
                skip = true;
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let out = out.replacen("\n[", "\nmethod = \"spheres\"\n\n[", 1);
    std::fs::write(&toml, out).unwrap();
    let res = dir.join("out");
    let run = calibrate(&toml, &res, &["--json"]);
    assert_eq!(run.code, Some(3), "not doubtful: {}", run.stderr);
    let r = common::read_json(&res.join("results.json"));
    let first = r["verdict"]["reasons"][0]
        .as_str()
        .unwrap_or_default()
        .to_string();
    assert!(
        first.starts_with("camera 'left': ")
            && first.contains("more than model 'photogrammetric' can hold")
            && first.contains("model = \"kannala-brandt\""),
        "the first reason does not name the lens: {}",
        r["verdict"]
    );
}
