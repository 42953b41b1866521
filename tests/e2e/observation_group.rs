//! A toy observation group added from outside the pipeline (issue 49, "Must show": a test
//! adds a toy observation group in one file plus its registration, and it appears in the
//! adjustment, results.json's χ² lines and the report with no other change).
//!
//! The group is a taped distance between two balls: `r = (|X_a − X_b| − L) / σ` on the two
//! ball centres of the joint problem. This file is all of it: the residual (with its
//! analytic Jacobian, checked by central differences), the group, its builder, and the one
//! line that registers it (`[BUILT_IN…, TapedDistance::build]`).

use crate::common::{replace_once, Work};
use nalgebra::Vector3;
use pingcal_ba::residual::check_residual_jacobians;
use pingcal_ba::{Block, Jacobians, PointKey, Problem, Residual};
use pingcal_ba::{ResidualBlock, Value};
use pingcal_pipeline::joint::groups::{
    retain_flagged, At, GroupContext, ObservationGroup, SensorKeys,
};
use pingcal_pipeline::joint::{GroupBuilder, BUILT_IN};
use pingcal_pipeline::{Options, PipelineError, Reporter};
use serde_json::Value as Json;
use std::any::Any;
use std::sync::OnceLock;

/// The group's name, in the χ² lines.
const NAME: &str = "taped distances";

/// The tape's σ (mm).
const TAPE_SIGMA_MM: f64 = 1.0;

/// The two balls and their taped distance (mm), set by the test before the run (a builder
/// is a plain function: it reads what the test measured from here).
static TAPE: OnceLock<(String, String, f64)> = OnceLock::new();

/// A taped distance between two ball centres.
#[derive(Clone, Debug)]
struct Tape {
    a: PointKey,
    b: PointKey,
    length_mm: f64,
}

impl Residual for Tape {
    fn dim(&self) -> usize {
        1
    }

    fn blocks(&self) -> Vec<Block> {
        vec![Block::Point(self.a), Block::Point(self.b)]
    }

    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let (Some(xa), Some(xb)) = (values[0].point(), values[1].point()) else {
            return false;
        };
        let d: Vector3<f64> = xa - xb;
        let n = d.norm();
        if !(n > 0.0) {
            return false;
        }
        residual[0] = (n - self.length_mm) / TAPE_SIGMA_MM;
        if let Some(j) = jacobians {
            let u = d / (n * TAPE_SIGMA_MM);
            for k in 0..3 {
                j[0][(0, k)] = u[k];
                j[1][(0, k)] = -u[k];
            }
        }
        true
    }

    fn group(&self) -> &str {
        NAME
    }
}

/// The group: one taped distance.
#[derive(Debug)]
struct TapedDistance {
    tapes: Vec<Tape>,
}

impl TapedDistance {
    /// The tape of [`TAPE`] between its two balls, where both are points of the problem.
    fn build(
        cx: &GroupContext,
        _base: &mut Problem,
    ) -> Result<Option<Box<dyn ObservationGroup>>, PipelineError> {
        let (a, b, length_mm) = TAPE.get().expect("the test sets the tape").clone();
        let key = |name: &str| {
            let scene = cx.input.scene;
            let (id, _) = scene
                .points
                .iter_enumerated()
                .find(|(_, p)| p.name == name)?;
            cx.input.adj.solved.map.point(id)
        };
        let (Some(a), Some(b)) = (key(&a), key(&b)) else {
            return Ok(None);
        };
        let tapes = vec![Tape { a, b, length_mm }];
        Ok(Some(Box::new(TapedDistance { tapes })))
    }
}

impl ObservationGroup for TapedDistance {
    fn name(&self) -> &str {
        NAME
    }

    fn len(&self) -> usize {
        self.tapes.len()
    }

    fn residuals(&self, _keys: &SensorKeys) -> Vec<ResidualBlock> {
        self.tapes.iter().cloned().map(ResidualBlock::new).collect()
    }

    fn sigmas(&self) -> Vec<f64> {
        vec![TAPE_SIGMA_MM; self.tapes.len()]
    }

    fn errors(&self, at: &At) -> Vec<f64> {
        (self.tapes.iter())
            .map(|t| {
                let d = at.problem[t.a].position - at.problem[t.b].position;
                d.norm() - t.length_mm
            })
            .collect()
    }

    fn retain(&mut self, keep: &[bool]) {
        retain_flagged(&mut self.tapes, keep);
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// The registration: the built-in groups and the tape.
const GROUPS: [GroupBuilder; 3] = [BUILT_IN[0], BUILT_IN[1], TapedDistance::build];

#[test]
fn the_tapes_jacobian_is_its_central_differences() {
    let tape = Tape {
        a: PointKey(0),
        b: PointKey(1),
        length_mm: 500.0,
    };
    let (xa, xb) = (
        Vector3::new(120.0, 900.0, -40.0),
        Vector3::new(-300.0, 1150.0, 210.0),
    );
    let worst = check_residual_jacobians(&tape, &[Value::Point(&xa), Value::Point(&xb)], 1e-3)
        .expect("defined");
    assert!(worst < 1e-6, "largest Jacobian error {worst}");
}

/// The first two control balls of the simulation's truth and their true distance.
fn true_tape(project: &std::path::Path) -> (String, String, f64) {
    let truth: Json = serde_json::from_str(
        &std::fs::read_to_string(project.join("truth.json")).expect("truth.json"),
    )
    .expect("truth.json is JSON");
    let balls: Vec<(String, Vector3<f64>)> = (truth["balls"].as_array().expect("balls").iter())
        .filter(|b| b["check"] == Json::Bool(false))
        .map(|b| {
            let x = &b["photogrammetric_mm"];
            let c = |i: usize| x[i].as_f64().expect("a coordinate");
            (
                b["id"].as_str().expect("an id").to_string(),
                Vector3::new(c(0), c(1), c(2)),
            )
        })
        .collect();
    let (a, b) = (&balls[0], &balls[1]);
    (a.0.clone(), b.0.clone(), (a.1 - b.1).norm())
}

/// The tape joins the joint adjustment of the quick project (with the joint method) and
/// shows as a χ² line of results.json and of the report, consistent with its σ.
#[test]
fn a_toy_group_added_from_outside_appears_in_the_adjustment_results_and_report() {
    let w = Work::new("toy_group");
    let dir = w.quick_project("p");
    replace_once(
        &dir.join("project.toml"),
        "method = \"spheres\"",
        "method = \"joint\"",
    );
    TAPE.set(true_tape(&dir)).expect("set once");
    let project = pingcal_project::Project::load(&dir.join("project.toml")).expect("loads");
    let out = pingcal_pipeline::calibrate_with_groups(
        &project,
        &Options::default(),
        &GROUPS,
        &Reporter::silent(),
    )
    .expect("calibrates");
    let results = serde_json::to_value(&out.results).expect("serialises");
    let joint = (results["methods"].as_array().expect("methods").iter())
        .find(|m| m["method"] == "joint")
        .expect("a joint method");
    let groups = joint["observation_groups"].as_array().expect("groups");
    let names: Vec<&str> = groups
        .iter()
        .map(|g| g["group"].as_str().unwrap())
        .collect();
    assert!(
        names.contains(&"beams") && names.contains(&NAME),
        "{names:?}"
    );
    let line = groups
        .iter()
        .find(|g| g["group"] == NAME)
        .expect("the tape's line");
    assert_eq!(line["observations"], 1, "{line}");
    // one observation of σ 1 mm whose ball centres the photographs fix to a fraction of a
    // millimetre: its χ² is below χ²₁'s 99.9 % point unless it was not adjusted with them
    let chi2 = line["chi2"].as_f64().expect("χ²");
    assert!(chi2.is_finite() && chi2 < 10.83, "χ² {chi2}");
    // its variance-component group is the joint adjustment's too
    let comps = joint["variance_components"].as_array().expect("components");
    assert!(comps.iter().any(|c| c["group"] == NAME), "{comps:?}");
    // and the report's summary has its χ² line
    let key = format!("joint χ² of the {NAME}");
    assert!(
        out.report.summary.iter().any(|(k, _)| *k == key),
        "{:?}",
        out.report.summary
    );
}

/// A nodding 360° scanner (issue 53: ±18°, the mount of `crates/sim/tests/nod.rs`) seen
/// through `pingcal calibrate`: the ball finder's walls are none (each wall is a band of the
/// nod), so the room mount searches the room as `pingcal lrf-mount` does, and the joint
/// adjustment takes the room's planes (before, "no wall, floor or ceiling was found" and the
/// joint had the few balls' beams only); the offsets a nod cannot tell are held with the
/// reason and with how far the extrinsic would move were they off by their plausible size.
#[test]
fn a_nodding_scanners_joint_adjustment_takes_the_rooms_planes() {
    let w = Work::new("nod_joint");
    let config = "[balls]\ncheck_balls = []\n\n[lrf]\nbeams = 1024\nangle_min_deg = -180.0\nangle_increment_deg = 0.3515625\nservo_start_deg = -18.0\nservo_end_deg = 18.0\nservo_step_deg = 0.2\nservo_passes = 2\nmount_offset_mm = [10.0, 5.0, 20.0]\nmount_tilt_x_deg = 0.8\nmount_tilt_z_deg = -0.6\nrange_offset_mm = 20.0\n";
    let project = w.simulate("p", config);
    let (run, out) = w.calibrate(&project, &["--accept-doubtful"]);
    assert!(run.success(), "{}\n{}", run.stdout, run.stderr);
    let r: Json = serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap())
        .expect("results.json");
    let joint = (r["methods"].as_array().unwrap().iter())
        .find(|m| m["method"] == "joint")
        .expect("the joint method");
    let planes = (joint["observation_groups"].as_array().unwrap().iter())
        .find(|g| g["group"] == "planes")
        .unwrap_or_else(|| panic!("no plane group: {}", joint["observation_groups"]));
    assert!(planes["observations"].as_u64().unwrap() > 1000, "{planes}");
    let offset_x = (r["lrf_mount"].as_array().unwrap().iter())
        .find(|p| p["name"] == "offset_x")
        .expect("offset_x");
    let held = offset_x["held"].as_str().unwrap_or_default();
    assert!(held.contains("do not determine"), "{offset_x}");
    // and what holding it costs: the simulator's offsets (10, 20 mm) moved tx by 13 mm
    let moved: f64 = (held.split("would move by up to ").nth(1))
        .and_then(|t| t.split(" mm").next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no shift in {held}"));
    assert!(moved > 5.0, "{held}");
    // which the σ's do not hold: the verdict says so
    let reasons = r["verdict"]["reasons"].to_string();
    assert!(
        reasons.contains("offset_x is held for want of data"),
        "{reasons}"
    );
}
