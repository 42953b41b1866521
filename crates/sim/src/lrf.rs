//! The rotating 2D LRF: a Hokuyo URG-04LX turned by a Dynamixel MX-28T servo.
//!
//! LRF frame (docs/formats.md, paper eq. 2): origin at the scanner centre, Y along the servo shaft,
//! X along the beam α = 0 at β = 0; a beam (α, β) of range r is at
//! `x = r cos α cos β, y = r sin α, z = r cos α sin β`, i.e. `M(β)·r(cos α, sin α, 0)` with
//! `M(β)` the rotation about Y taking X to (cos β, 0, sin β).
//!
//! What the simulation models:
//! * range noise: Gaussian, σ = datasheet accuracy / `accuracy_sigmas` (default 3: the
//!   datasheet's ±30 mm under 1 m and ±3 % beyond taken as 3σ bounds), then rounding to mm;
//! * beam footprint: five sub-rays over `beam_width_deg`; the reading is the
//!   power-weighted mean of their ranges (weights reflectivity·cos i / r²), which gives
//!   the mixed pixels of an AM phase-shift scanner at depth edges;
//! * no return (0) on surfaces darker than `min_reflectivity` (the black print of the
//!   targets), beyond `max_range_mm`, or under `min_range_mm`;
//! * the servo: commanded angles in `servo_step_deg` steps, the true angle off by
//!   N(0, `servo_sigma_deg`), the reported angle the true one quantised to the encoder's
//!   0.088°;
//! * a mount offset: the scanner centre off the shaft by `mount_offset_mm` in the rotating
//!   frame (eq. 2 assumes zero; the default is zero);
//! * the servo's timing: stop-and-go (the default) or a continuous sweep, over
//!   `servo_passes` passes alternately forward and back, with the servo's stamps late by
//!   `servo_time_offset_s` against the scanner's (each beam's servo angle in the file is
//!   then the one the servo had that much earlier).
//!
//! The sensor itself (beam geometry with the mount, the range-noise profile, what a reading
//! is) is `pingcal_lrf::sensor`, the model the calibration uses; [`LrfConfig::sensor`] maps
//! the configuration onto it. This module adds what only a simulator needs: the scene, the
//! beam footprint, the reflectivity threshold and the servo. The CSV is written by
//! `pingcal_lrf::scan::ScanWriter`.

use crate::config::LrfConfig;
use crate::rng_for;
use crate::scene::{Object, TestField};
use nalgebra::Vector3;
use pingcal_geometry::from_opk;
use pingcal_geometry::Rigid3;
use pingcal_lrf::scan::ScanWriter;
use pingcal_lrf::sensor::{LrfSensor, ScannerPose};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

type V3 = Vector3<f64>;

/// One scan line as the LRF and servo report it, with the true servo angle kept for tests.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Time stamp (s).
    pub stamp_s: f64,
    /// Servo angle reported by the encoder (degrees), at the first beam.
    pub servo_deg: f64,
    /// In a continuous sweep, the reported servo angle at the last beam: the first beam's
    /// reading advanced at the commanded speed, as a reader that interpolates the servo's
    /// readings at each beam's time gets it. None: stop-and-go.
    pub servo_end_deg: Option<f64>,
    /// True servo angle (degrees), at the first beam.
    pub true_servo_deg: f64,
    /// Ranges in mm; 0 = no return.
    pub ranges_mm: Vec<u32>,
}

/// The true extrinsic as a pose LRF → main left camera: `p_camera = R·p_lrf + t`.
pub fn extrinsic(cfg: &LrfConfig) -> Rigid3 {
    let o = cfg.extrinsic_opk_deg_of_kind();
    Rigid3 {
        rotation: from_opk(o[0].to_radians(), o[1].to_radians(), o[2].to_radians()),
        translation: V3::from(cfg.extrinsic_t_mm),
    }
}

/// `lrf_from_world`, given the main left camera's `left_from_world`:
/// `lrf_from_left · left_from_world`.
pub fn lrf_from_world(left_from_world: &Rigid3, cfg: &LrfConfig) -> Rigid3 {
    extrinsic(cfg).inverse().compose(left_from_world)
}

/// Simulates the whole servo sweep; `scene_lrf` must already be in the LRF frame
/// (`scene.transformed(&lrf_from_world(..))`). Scans are independent (one random stream
/// each), computed in parallel, identical for the same seed.
pub fn simulate_scans(scene_lrf: &TestField, cfg: &LrfConfig, seed: u64) -> Vec<Scan> {
    let nscans = scans_per_pass(cfg) * cfg.servo_passes.max(1);
    let sensor = cfg.sensor();
    let caps = culling_caps(scene_lrf, cfg);
    (0..nscans)
        .into_par_iter()
        .map(|k| simulate_scan(scene_lrf, cfg, &sensor, &caps, seed, k))
        .collect()
}

/// The configuration of a fixed LRF's scans at one station as a "sweep" of
/// `scans_per_station` scans that stand at servo angle 0 (no servo noise, no motion): the
/// scans of [`simulate_scans`] are then the scanner's at that station.
pub fn fixed_config(cfg: &LrfConfig) -> LrfConfig {
    LrfConfig {
        servo_start_deg: 0.0,
        servo_end_deg: 0.0,
        servo_step_deg: 1.0,
        servo_sigma_deg: 0.0,
        servo_passes: cfg.scans_per_station.max(1),
        continuous_sweep: false,
        servo_time_offset_s: 0.0,
        ..cfg.clone()
    }
}

/// A fixed LRF's scans at each of `stations` (id, `left_from_world`) of the field `scene`
/// (world frame): the scanner at `lrf_from_world(station)`, each station's scans from their
/// own random stream (the seed and the station's place in the list).
pub fn simulate_fixed_scans(
    scene: &TestField,
    stations: &[(String, Rigid3)],
    cfg: &LrfConfig,
    seed: u64,
) -> Vec<(String, Vec<Scan>)> {
    let fixed = fixed_config(cfg);
    stations
        .iter()
        .enumerate()
        .map(|(k, (id, left_from_world))| {
            let lrf = lrf_from_world(left_from_world, cfg);
            let stream = seed ^ (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let scans = simulate_scans(&scene.transformed(&lrf), &fixed, stream);
            (id.clone(), scans)
        })
        .collect()
}

/// The scans of one pass of the servo from `servo_start_deg` to `servo_end_deg`.
fn scans_per_pass(cfg: &LrfConfig) -> usize {
    ((cfg.servo_end_deg - cfg.servo_start_deg) / cfg.servo_step_deg + 1e-9).floor() as usize + 1
}

/// Scan `k`'s commanded servo angle and the direction the servo turns (+1 forward, −1 on
/// the passes back).
fn commanded_deg(cfg: &LrfConfig, k: usize) -> (f64, f64) {
    let n = scans_per_pass(cfg);
    let (pass, i) = (k / n, k % n);
    if pass % 2 == 0 {
        (cfg.servo_start_deg + i as f64 * cfg.servo_step_deg, 1.0)
    } else {
        (
            cfg.servo_start_deg + (n - 1 - i) as f64 * cfg.servo_step_deg,
            -1.0,
        )
    }
}

/// An object's bounding cone seen from the LRF, widened by the beam footprint and the
/// mount offset: a beam whose direction is outside it cannot hit the object.
struct Cap {
    object: Object,
    /// Unit direction of the cone's axis.
    axis: V3,
    /// Cosine of the cone's half-angle.
    cos_max: f64,
}

/// The culling cones of the scene's targets and balls (with their stems).
fn culling_caps(scene_lrf: &TestField, cfg: &LrfConfig) -> Vec<Cap> {
    // Bounding spheres of the objects, for angular culling.
    let mut bounds: Vec<(Object, V3, f64)> = Vec::new();
    for (i, t) in scene_lrf.targets.iter().enumerate() {
        bounds.push((Object::Target(i as u32), t.centre, t.background));
    }
    for (i, b) in scene_lrf.balls.iter().enumerate() {
        let mid = b.foot + b.axis * (0.5 * b.stem_length);
        bounds.push((
            Object::Ball(i as u32),
            mid,
            0.5 * b.stem_length + b.radius + b.stem_radius,
        ));
    }
    let slack = V3::from(cfg.mount().offset_mm).norm() + 1.0;
    let half_beam = 0.5 * cfg.beam_width_deg.to_radians();
    bounds
        .iter()
        .map(|(o, c, r)| {
            let d = c.norm();
            let ang = if d <= r + slack {
                std::f64::consts::PI
            } else {
                ((r + slack) / d).asin()
            };
            Cap {
                object: *o,
                axis: c / d,
                cos_max: (ang + 2.0 * half_beam).min(std::f64::consts::PI).cos(),
            }
        })
        .collect()
}

/// Scan `k` of the sweep, from its own random stream: the servo's true and reported angle
/// (one draw when the servo is noisy), then the beams in order.
fn simulate_scan(
    scene_lrf: &TestField,
    cfg: &LrfConfig,
    sensor: &LrfSensor,
    caps: &[Cap],
    seed: u64,
    k: usize,
) -> Scan {
    let mut rng = rng_for(seed, "lrf-scan", k as u64);
    let (commanded, direction) = commanded_deg(cfg, k);
    let err: f64 = if cfg.noise && cfg.servo_sigma_deg > 0.0 {
        cfg.servo_sigma_deg * rng.sample::<f64, _>(StandardNormal)
    } else {
        0.0
    };
    let true_deg = commanded + err;
    // in a continuous sweep, the servo's advance from the first beam to beam i
    let speed = direction * cfg.servo_step_deg / cfg.scan_period_s;
    // the servo's stamps are late by servo_time_offset_s: at a beam's time a reader
    // interpolates the angle the servo had that much earlier (0 unless continuous)
    let lag = speed * cfg.servo_time_offset_s;
    let reported = ((true_deg - lag) / cfg.servo_resolution_deg).round() * cfg.servo_resolution_deg;
    let advance = |i: usize| {
        if cfg.continuous_sweep {
            speed * cfg.beam_time_s * i as f64
        } else {
            0.0
        }
    };
    let mut pose = sensor.scanner_at(true_deg);
    let mut objs: Vec<Object> = Vec::new();
    let ranges = (0..sensor.beams)
        .map(|i| {
            if cfg.continuous_sweep {
                pose = sensor.scanner_at(true_deg + advance(i));
            }
            let alpha = sensor.beam_angle(i);
            let centre_dir = pose.direction(alpha, 0.0);
            objs.clear();
            objs.extend(
                caps.iter()
                    .filter(|c| centre_dir.dot(&c.axis) >= c.cos_max)
                    .map(|c| c.object),
            );
            match footprint_range(scene_lrf, cfg, &pose, alpha, &objs) {
                Some(r_true) => sensor.read(r_true, &mut rng).map_or(0, |q| q as u32),
                None => 0,
            }
        })
        .collect();
    Scan {
        stamp_s: k as f64 * cfg.scan_period_s,
        servo_deg: reported,
        servo_end_deg: cfg
            .continuous_sweep
            .then(|| reported + advance(sensor.beams.saturating_sub(1))),
        true_servo_deg: true_deg,
        ranges_mm: ranges,
    }
}

/// The true range of one beam of angle `alpha` (radians): the power-weighted mean of the
/// ranges of five sub-rays over the footprint (weights reflectivity·cos i / r²), over the
/// surfaces bright enough to return; `None` when none does. `objs` are the objects the beam
/// may hit.
fn footprint_range(
    scene_lrf: &TestField,
    cfg: &LrfConfig,
    pose: &ScannerPose,
    alpha: f64,
    objs: &[Object],
) -> Option<f64> {
    let h = 0.5 * cfg.beam_width_deg.to_radians() * (2.0 / 3.0);
    let subs: [(f64, f64, f64); 5] = [
        (0.0, 0.0, 2.0),
        (h, 0.0, 1.0),
        (-h, 0.0, 1.0),
        (0.0, h, 1.0),
        (0.0, -h, 1.0),
    ];
    let origin = pose.origin();
    let (mut sw, mut swr) = (0.0, 0.0);
    for (da, dg, wt) in subs {
        let d = pose.direction(alpha + da, dg);
        if let Some(hit) = scene_lrf.cast(&origin, &d, Some(objs)) {
            let refl = scene_lrf.reflectivity(&hit);
            if refl >= cfg.min_reflectivity {
                let cos_i = d.dot(&hit.normal).abs().max(0.05);
                let w = wt * refl * cos_i / (hit.t * hit.t);
                sw += w;
                swr += w * hit.t;
            }
        }
    }
    (sw > 0.0).then(|| swr / sw)
}

/// Writes the scans as a `pingcal-scan` CSV through the calibration's own writer, with a
/// `# sensor=` line naming the simulator: v1 for stop-and-go, v2 (each scan's servo angle at
/// its first and last beam) for a continuous sweep.
pub fn write_scans_csv<W: std::io::Write>(
    out: W,
    scans: &[Scan],
    cfg: &LrfConfig,
) -> std::io::Result<W> {
    let sensor = cfg.sensor();
    let note = ["sensor=Hokuyo URG-04LX (simulated by pingcal simulate)"];
    let mut w = if cfg.continuous_sweep {
        ScanWriter::new_v2(out, &sensor.header, sensor.beams, &note)?
    } else {
        ScanWriter::new(out, &sensor.header, sensor.beams, &note)?
    };
    for sc in scans {
        let ranges = sc.ranges_mm.iter().copied();
        match sc.servo_end_deg {
            Some(end) => w.write_sweep_scan(sc.stamp_s, sc.servo_deg, end, ranges)?,
            None => w.write_scan(sc.stamp_s, sc.servo_deg, ranges)?,
        }
    }
    w.finish()
}
