//! The project directory: same seed ⇒ byte-identical files; the files are consistent with
//! the truth; impossible configurations are refused with an error naming the value.

use pingcal_sim::{project_files, SimConfig, Simulation};
use std::path::{Path, PathBuf};

/// A small but complete configuration (fewer stations and scans) to keep the test quick.
fn small_config() -> SimConfig {
    let mut cfg = SimConfig::default();
    cfg.stations.convergent = 1;
    cfg.render.supersampling = 2;
    cfg.lrf.servo_start_deg = -10.0;
    cfg.lrf.servo_end_deg = 10.0;
    cfg.lrf.servo_step_deg = 2.0;
    cfg
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pingcal-sim-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for sub in ["", "images", "scans"] {
        let mut names: Vec<_> = std::fs::read_dir(dir.join(sub))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        names.sort();
        for p in names {
            out.push((
                p.strip_prefix(dir).unwrap().display().to_string(),
                std::fs::read(&p).unwrap(),
            ));
        }
    }
    out
}

#[test]
fn same_seed_gives_identical_files_and_another_seed_does_not() {
    let cfg = small_config();
    let (a, b, c) = (tmp("a"), tmp("b"), tmp("c"));
    project_files::write_project(&Simulation::new(&cfg, 7).unwrap(), &a).unwrap();
    project_files::write_project(&Simulation::new(&cfg, 7).unwrap(), &b).unwrap();
    project_files::write_project(&Simulation::new(&cfg, 8).unwrap(), &c).unwrap();
    let (fa, fb, fc) = (files(&a), files(&b), files(&c));
    assert_eq!(
        fa.len(),
        3 + 2 * 2 + 1,
        "{:?}",
        fa.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((na, da), (nb, db)) in fa.iter().zip(&fb) {
        assert_eq!(na, nb);
        assert!(da == db, "{na} differs between two runs with the same seed");
    }
    let differing = fa.iter().zip(&fc).filter(|(x, y)| x.1 != y.1).count();
    assert!(
        differing >= fa.len() - 2,
        "another seed changed only {differing} files"
    );

    // The files agree with each other and with the truth.
    let truth = project_files::read_truth(&a.join("truth.json")).unwrap();
    let project = project_files::read_project(&a.join("project.toml")).unwrap();
    assert_eq!(truth.seed, 7);
    assert_eq!(truth.balls.len(), 16);
    assert_eq!(truth.targets.len(), 78);
    assert!(truth.targets.iter().filter(|t| t.kind == "coded").count() >= 24);
    assert_eq!(project.images.len(), truth.images.len());
    for im in &project.images {
        let img = image::open(a.join(&im.file)).unwrap();
        assert_eq!((img.width(), img.height()), (1280, 720));
    }
    assert_eq!(project.distances.len(), 5);
    for d in &project.distances {
        let t = |id| {
            truth
                .targets
                .iter()
                .find(|t| t.id == id && t.kind == "coded")
                .unwrap()
        };
        let (p, q) = (t(d.from).photogrammetric_mm, t(d.to).photogrammetric_mm);
        let true_d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        assert!(
            (true_d - d.distance_mm).abs() < 5.0 * d.sigma_mm,
            "distance {} - {}",
            d.from,
            d.to
        );
    }
    // Ball centres: p_camera = R p_lrf + t.
    let r = truth.extrinsic.rotation;
    let t = truth.extrinsic.translation_mm;
    for b in &truth.balls {
        for i in 0..3 {
            let p = r[i][0] * b.lrf_mm[0] + r[i][1] * b.lrf_mm[1] + r[i][2] * b.lrf_mm[2] + t[i];
            assert!((p - b.photogrammetric_mm[i]).abs() < 1e-6, "{}", b.id);
        }
    }
    // The scan file follows docs/formats.md.
    let csv = std::fs::read_to_string(a.join(project.lrf.scans[0].file())).unwrap();
    assert!(csv.starts_with("# pingcal-scan v1\n"));
    let rows: Vec<&str> = csv.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(rows[0].split(',').count(), 2 + 682);
    assert_eq!(rows.len(), 1 + 11);
    for d in [a, b, c] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn impossible_values_are_refused_naming_the_value() {
    let cases: &[(&str, &[&str])] = &[
        (
            "[targets]\ndot_radius_mm = -5.0\n",
            &["targets.dot_radius_mm", "-5", "positive"],
        ),
        (
            "[balls]\ndiameter_mm = 0.0\n",
            &["balls.diameter_mm", "positive"],
        ),
        (
            "[balls]\nstandoff_range_mm = [10.0, 30.0]\n",
            &["balls.standoff_range_mm", "inside the wall"],
        ),
        (
            "[room]\nwall_length_mm = -2500.0\n",
            &["room.wall_length_mm", "-2500"],
        ),
        (
            "[targets]\ncount = 10\ncoded = 20\n",
            &["targets.coded", "20"],
        ),
        (
            "[camera]\npixel_size_mm = -0.00375\n",
            &["camera.pixel_size_mm"],
        ),
        (
            "[lrf]\nservo_start_deg = 10.0\nservo_end_deg = -10.0\n",
            &["lrf.servo_end_deg"],
        ),
        ("[targets]\ndot_radus_mm = 5.0\n", &["dot_radus_mm"]),
    ];
    for (text, needles) in cases {
        let e = SimConfig::from_toml_str(text).expect_err(text);
        println!("{text:?} -> {e}");
        assert!(!e.contains('\n'), "not one line: {e}");
        for n in *needles {
            assert!(e.contains(n), "error for {text:?} does not name {n:?}: {e}");
        }
    }
}

#[test]
fn geometric_impossibilities_are_refused() {
    // A ball placed 10 mm above the floor: inside it.
    let mut cfg = small_config();
    cfg.balls.placements = Some(vec![
        pingcal_sim::config::BallPlacement {
            surface: "wall1".into(),
            u_mm: 600.0,
            v_mm: 10.0,
            standoff_mm: 80.0,
        },
        pingcal_sim::config::BallPlacement {
            surface: "wall1".into(),
            u_mm: 900.0,
            v_mm: 600.0,
            standoff_mm: 80.0,
        },
        pingcal_sim::config::BallPlacement {
            surface: "wall2".into(),
            u_mm: 900.0,
            v_mm: 600.0,
            standoff_mm: 80.0,
        },
    ]);
    cfg.balls.check_balls = vec![];
    let e = Simulation::new(&cfg, 1).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("balls.placements[0]") && e.contains("inside a wall") && e.contains("floor"),
        "{e}"
    );

    // The main camera behind wall 2 (x < 0).
    let mut cfg = small_config();
    cfg.stations.main_centre_mm = [-300.0, 1100.0, 700.0];
    let e = Simulation::new(&cfg, 1).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("stations.main_centre_mm") && e.contains("behind wall2"),
        "{e}"
    );

    // A convergent station behind the floor.
    let mut cfg = small_config();
    cfg.stations.extra = vec![pingcal_sim::config::StationPlacement {
        centre_mm: [1000.0, 1000.0, -50.0],
        look_at_mm: [300.0, 300.0, 400.0],
        roll_deg: 0.0,
    }];
    let e = Simulation::new(&cfg, 1).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("stations.extra[0]") && e.contains("behind floor"),
        "{e}"
    );
}
