//! The rotating 2D LRF: a Hokuyo URG-04LX turned by a Dynamixel MX-28T servo.
//!
//! LRF frame (SPEC.md, paper eq. 2): origin at the scanner centre, Y along the servo shaft,
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
//!   frame (eq. 2 assumes zero; the default is zero).

use crate::config::LrfConfig;
use crate::rng_for;
use crate::scene::{Object, Scene};
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::pose::Pose;
use pingcal_ba::rotation::from_opk;
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;

type V3 = Vector3<f64>;

/// One scan line as the LRF and servo report it, with the true servo angle kept for tests.
#[derive(Debug, Clone, PartialEq)]
pub struct Scan {
    /// Time stamp (s).
    pub stamp_s: f64,
    /// Servo angle reported by the encoder (degrees).
    pub servo_deg: f64,
    /// True servo angle (degrees).
    pub true_servo_deg: f64,
    /// Ranges in mm; 0 = no return.
    pub ranges_mm: Vec<u32>,
}

/// `M(β)`: rotation about the shaft (Y) taking X to (cos β, 0, sin β).
pub fn servo_rotation(beta: f64) -> Matrix3<f64> {
    let (s, c) = beta.sin_cos();
    Matrix3::new(c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c)
}

/// Unit direction of beam angle α at servo angle β (radians), LRF frame (eq. 2).
pub fn beam_direction(alpha: f64, beta: f64) -> V3 {
    V3::new(
        alpha.cos() * beta.cos(),
        alpha.sin(),
        alpha.cos() * beta.sin(),
    )
}

/// The true extrinsic as a pose LRF → main left camera: `p_camera = R·p_lrf + t`.
pub fn extrinsic(cfg: &LrfConfig) -> Pose {
    let o = cfg.extrinsic_opk_deg;
    Pose {
        rotation: from_opk(o[0].to_radians(), o[1].to_radians(), o[2].to_radians()),
        translation: V3::from(cfg.extrinsic_t_mm),
    }
}

/// World → LRF frame, given the main left camera's pose (world → camera).
pub fn world_to_lrf(main_left: &Pose, cfg: &LrfConfig) -> Pose {
    extrinsic(cfg).inverse().compose(main_left)
}

/// The URG-04LX range noise σ at range `r` (mm).
pub fn range_sigma_mm(cfg: &LrfConfig, r: f64) -> f64 {
    cfg.range_sigma_mm(r)
}

/// Simulates the whole servo sweep; `scene_lrf` must already be in the LRF frame
/// (`scene.transformed(&world_to_lrf(..))`). Scans are independent (one random stream
/// each), computed in parallel, identical for the same seed.
pub fn simulate_scans(scene_lrf: &Scene, cfg: &LrfConfig, seed: u64) -> Vec<Scan> {
    let nscans = ((cfg.servo_end_deg - cfg.servo_start_deg) / cfg.servo_step_deg + 1e-9).floor()
        as usize
        + 1;
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
    let off = V3::from(cfg.mount_offset_mm);
    let slack = off.norm() + 1.0;
    let half_beam = 0.5 * cfg.beam_width_deg.to_radians();
    let caps: Vec<(Object, V3, f64)> = bounds
        .iter()
        .map(|(o, c, r)| {
            let d = c.norm();
            let ang = if d <= r + slack {
                std::f64::consts::PI
            } else {
                ((r + slack) / d).asin()
            };
            (
                *o,
                c / d,
                (ang + 2.0 * half_beam).min(std::f64::consts::PI).cos(),
            )
        })
        .collect();
    (0..nscans)
        .into_par_iter()
        .map(|k| {
            let mut rng = rng_for(seed, "lrf-scan", k as u64);
            let commanded = cfg.servo_start_deg + k as f64 * cfg.servo_step_deg;
            let err: f64 = if cfg.noise && cfg.servo_sigma_deg > 0.0 {
                cfg.servo_sigma_deg * rng.sample::<f64, _>(StandardNormal)
            } else {
                0.0
            };
            let true_deg = commanded + err;
            let reported = (true_deg / cfg.servo_resolution_deg).round() * cfg.servo_resolution_deg;
            let beta = true_deg.to_radians();
            let m = servo_rotation(beta);
            let origin = m * off;
            let mut objs: Vec<Object> = Vec::new();
            let mut ranges = Vec::with_capacity(cfg.beams);
            for i in 0..cfg.beams {
                let alpha = (cfg.angle_min_deg + i as f64 * cfg.angle_increment_deg).to_radians();
                let centre_dir = m * V3::new(alpha.cos(), alpha.sin(), 0.0);
                objs.clear();
                for (o, dir, cosmax) in &caps {
                    if centre_dir.dot(dir) >= *cosmax {
                        objs.push(*o);
                    }
                }
                let h = half_beam * (2.0 / 3.0);
                let subs: [(f64, f64, f64); 5] = [
                    (0.0, 0.0, 2.0),
                    (h, 0.0, 1.0),
                    (-h, 0.0, 1.0),
                    (0.0, h, 1.0),
                    (0.0, -h, 1.0),
                ];
                let (mut sw, mut swr) = (0.0, 0.0);
                for (da, dg, wt) in subs {
                    let (a, g) = (alpha + da, dg);
                    let d = m * V3::new(a.cos() * g.cos(), a.sin() * g.cos(), g.sin());
                    if let Some(hit) = scene_lrf.cast(&origin, &d, Some(&objs)) {
                        let refl = scene_lrf.reflectivity(&hit);
                        if refl >= cfg.min_reflectivity {
                            let cos_i = d.dot(&hit.normal).abs().max(0.05);
                            let w = wt * refl * cos_i / (hit.t * hit.t);
                            sw += w;
                            swr += w * hit.t;
                        }
                    }
                }
                let r = if sw > 0.0 {
                    let r_true = swr / sw;
                    let noisy = if cfg.noise {
                        r_true + cfg.range_sigma_mm(r_true) * rng.sample::<f64, _>(StandardNormal)
                    } else {
                        r_true
                    };
                    let q = noisy.round();
                    if r_true > cfg.max_range_mm || q < cfg.min_range_mm || q > cfg.max_range_mm {
                        0
                    } else {
                        q as u32
                    }
                } else {
                    0
                };
                ranges.push(r);
            }
            Scan {
                stamp_s: k as f64 * cfg.scan_period_s,
                servo_deg: reported,
                true_servo_deg: true_deg,
                ranges_mm: ranges,
            }
        })
        .collect()
}

/// The scans as a `pingcal-scan` v1 CSV (SPEC.md).
pub fn scans_to_csv(scans: &[Scan], cfg: &LrfConfig) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    s.push_str("# pingcal-scan v1\n");
    let _ = writeln!(s, "# angle_min_deg={}", cfg.angle_min_deg);
    let _ = writeln!(s, "# angle_increment_deg={}", cfg.angle_increment_deg);
    s.push_str("# range_unit=mm\n");
    s.push_str("# sensor=Hokuyo URG-04LX (simulated by pingcal simulate)\n");
    s.push_str("stamp_s,servo_deg");
    for i in 0..cfg.beams {
        let _ = write!(s, ",r{i}");
    }
    s.push('\n');
    for sc in scans {
        let _ = write!(s, "{:.3},{:.6}", sc.stamp_s, sc.servo_deg);
        for r in &sc.ranges_mm {
            let _ = write!(s, ",{r}");
        }
        s.push('\n');
    }
    s
}

/// Turns one reading into a point of the eq. 2 frame (what a consumer of the CSV does).
pub fn point_from_reading(r_mm: f64, alpha_deg: f64, beta_deg: f64) -> V3 {
    beam_direction(alpha_deg.to_radians(), beta_deg.to_radians()) * r_mm
}
