//! The mount from the room: a rotating 2D LRF's mount and range errors self-calibrated from
//! the walls, floor and ceiling it sees, with no camera and no target.
//!
//! A full turn of the servo sees every wall twice, once from each half-sweep (β and
//! β + 180° with the beam angle mirrored). Through the true mount the two views of a plane
//! coincide; through a wrong one they are two planes at an angle or apart, and a range
//! offset bends every plane by `δ cos i` (i the incidence). So the mount is fitted so that
//! every beam of a plane lies on one plane (Kang & Doh, IEEE T-RO 32(5) 2016; Zeng et al.,
//! Sensors 18(2) 497, 2018).
//!
//! **Observation.** A beam (servo reading `s`, beam angle α, reported range `r`) through the
//! mount θ ([`MountModel::to_params`]) starts at `o = R_β offset` and points along
//! `u = R_β R_x(tilt_x) R_z(tilt_z) (cos α, sin α, 0)`, `β = (s − servo_zero)(1 +
//! servo_scale)` ([`crate::sensor`]). It meets the plane `n·x = d` at the true range
//! `t₀ = (d − n·o)/(n·u)`, at `h = o + t₀ u`. No wall is flat to the millimetre, so each plane
//! may bend smoothly: `n·x = d + b(x)`, `b = c_uu ũ² + c_vv ṽ² + c_uv ũ ṽ` in the plane's own
//! coordinates (`ũ = e₁·(x − c)/L`, `ṽ = e₂·(x − c)/L` about the centre `c` of its beams, `L`
//! their spread), each coefficient under a prior of [`FLATNESS_MM`]; the ray meets the bent
//! plane at `τ = t₀ + b(h)/(n·u)` (to first order in b). The residual is the range misfit,
//! `e = r − r̂`, `r̂ = τ (1 + range_scale) + range_offset`, of the sensor's σ at that range
//! (a residual in the cloud's millimetres instead would reward shrinking the cloud). Without
//! the bend a wall's unevenness of a few millimetres reads as a range offset: the range
//! offset's only signature in a plane is `δ cos i`, itself a smooth bend.
//!
//! The plane's normal is parametrised about a reference `n₀` with a tangent basis `e₁, e₂`:
//! `n = (n₀ + a e₁ + b e₂)/|n₀ + a e₁ + b e₂|`; its unknowns are `(a, b, d, c_uu, c_vv, c_uv)`.
//! Jacobians, with `s = n·u`: `∂t₀/∂θ = −(n·∂o + t₀ n·∂u)/s`, `∂t₀/∂n = −h/s`,
//! `∂t₀/∂d = 1/s`; `∂h = ∂o + t₀ ∂u + u ∂t₀`; `∂τ = ∂t₀ + ∇b·∂h/s − b ∂s/s²`, `∂τ/∂c_j =
//! basis_j/s`; `∂o/∂offset_j = R_β e_j`, `∂u/∂tilt = R_β ∂(R_x R_z) l`, `∂(o, u)/∂servo_scale =
//! Ṙ_β (s − servo_zero)(offset, R_x R_z l)`; `∂e/∂· = −(1 + range_scale) ∂τ/∂·`,
//! `∂e/∂range_offset = −1`, `∂e/∂range_scale = −τ` (checked against central differences in
//! the tests).
//!
//! **Association.** Each beam is assigned to the plane whose gate its range is in,
//! `|ρ − t₀| ≤ max(k σ(t₀), floor)` (`ρ` the reported range through the mount's range model),
//! with `|n·u|` at least [`RoomOptions::min_cos_incidence`] (beams that graze a wall carry
//! their footprint more than its distance); a ray that meets another plane within twice the
//! gates of it is an edge of the room and left out: decided on the rays alone, so that no
//! reading's noise decides which side of the cut it falls (such a cut biased the range
//! offset by 2σ). The first round's gate is wide ([`RoomOptions::first_gate_mm`]: a wrong
//! mount puts a wall's two views that far apart); later rounds re-decide every beam through
//! the mount the round before estimated, with the gate at [`GATE_K`] of its σ scaled by the
//! round's σ0. A plane keeps at most [`RoomOptions::max_beams_per_plane`] beams, taken evenly
//! in the order of the scans. Planes found twice (a wall's two half-sweeps under a wrong
//! mount, within [`MERGE_ANGLE_DEG`] and [`MERGE_DISTANCE_MM`]) are one.
//!
//! **Adjustment.** Levenberg–Marquardt on the free mount parameters and every plane's
//! unknowns, each mount parameter under a weak prior at the start ([`WEAK_PRIOR_SIGMA`]: far
//! wider than any real error, it only makes the normal equations regular); beams whose
//! standardised residual exceeds [`REJECT`] × max(σ0, 1) are removed and the adjustment run
//! again. Covariances are the inverse normal matrix times σ0².
//!
//! **What the room cannot fix.** The offset along the servo axis moves the whole cloud along
//! it, and the servo's zero turns the whole cloud about it: the planes take either up, so
//! neither is an unknown (the LRF frame is *defined* with its origin on the servo axis at the
//! scan plane, its zero at the given servo zero). A range scale scales the room, which the
//! planes take up too, unless the scanner's offset from the axis is large. Whatever else the
//! room leaves free is found from the data: a parameter whose σ exceeds
//! [`MAX_PRIOR_SHARE`] of its weak prior, or that is correlated with another unknown beyond
//! [`MAX_CORRELATION`], is held at its start and named with the reason, one at a time,
//! before the next association round.

use crate::ball_finder::{FinderOptions, RefusedPlane};
use crate::beam::{rot_x, rot_z, servo_rotation_dot};
use crate::cloud::{BeamReading, Cloud};
use crate::error::{LrfError, Result};
use crate::sensor::{servo_rotation, MountModel, MountParam, RangeNoise, MOUNT_PARAM_NAMES};
use crate::sweep::{vaguer_than_a_rig, Sweep, RIG_ERROR};
use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

type V3 = Vector3<f64>;

/// The residual group of beams on planes in an adjustment.
pub const PLANE_GROUP: &str = "planes";

/// σ of the weak prior on each mount parameter ([`MountModel::to_params`] units: mm, rad,
/// 1): far wider than any real error.
pub const WEAK_PRIOR_SIGMA: [f64; 8] = [100.0, 100.0, 100.0, 0.2, 0.2, 0.1, 100.0, 0.1];

/// How far a wall, floor or ceiling may depart from a plane (mm, σ of each bend
/// coefficient over the spread of its beams): building tolerances allow a few millimetres
/// over a few metres (DIN 18202: 3–5 mm over 1–2 m), and the simulator's walls bulge by up to 3 mm.
pub const FLATNESS_MM: f64 = 2.0;

/// Unknowns of a plane: the normal's two, the offset, the three bend coefficients.
pub const PLANE_UNKNOWNS: usize = 6;

/// A parameter whose σ is more than this share of its weak prior is not determined.
pub const MAX_PRIOR_SHARE: f64 = 0.2;

/// A parameter correlated with another unknown beyond this is held.
pub const MAX_CORRELATION: f64 = 0.999;

/// Beams whose standardised residual exceeds this × max(σ0, 1) are gross errors (α ≈ 0.1 %).
pub const REJECT: f64 = 3.29;

/// The gate of the later association rounds, in σ of a beam's range (× the round's σ0).
pub const GATE_K: f64 = 3.0;

/// Two planes within this angle…
pub const MERGE_ANGLE_DEG: f64 = 4.0;
/// …and this distance (of their offsets) are one wall seen twice.
pub const MERGE_DISTANCE_MM: f64 = 150.0;

/// A plane with fewer beams than this is not used.
pub const MIN_PLANE_BEAMS: usize = 100;

/// The smallest in-plane spread (mm, the smaller standard deviation of its points) of a
/// plane the mount from the room takes for a wall ([`room_finder`]). The ball finder asks
/// 250 mm, so that a table or a box side stays in the cloud beside the balls; to the mount
/// any flat surface is a plane, and a nod sees each wall as a band: ±18° at 1.2 m is a band
/// of 225 mm RMS, ±5° one of 60 mm.
pub const ROOM_PLANE_MIN_SPREAD_MM: f64 = 50.0;

/// The wall finder's options for the mount from the room: `base` with planes down to
/// [`ROOM_PLANE_MIN_SPREAD_MM`] across.
pub fn room_finder(base: FinderOptions) -> FinderOptions {
    FinderOptions {
        min_wall_spread_mm: ROOM_PLANE_MIN_SPREAD_MM,
        ..base
    }
}

/// Why the wall search found no plane in a cloud of `points` points, one line: the flat
/// surfaces it refused (`refused`, [`crate::ball_finder::find_walls_explained`]) and why,
/// or that none holds enough of the points.
pub fn why_no_walls(points: usize, refused: &[RefusedPlane], min_fraction: f64) -> String {
    let head = format!("no wall, floor or ceiling was found in the cloud's {points} points");
    if refused.is_empty() {
        return format!(
            "{head}: no flat surface holds {:.0} % of them; the mount cannot be found from the room",
            100.0 * min_fraction
        );
    }
    let reasons: Vec<String> = refused.iter().take(4).map(|r| r.reason()).collect();
    let scatter = refused
        .iter()
        .any(|r| r.core_fraction < crate::ball_finder::WALL_CORE_FRACTION);
    format!(
        "{head}: {} flat surface{} refused: {}{}; the mount cannot be found from the room",
        refused.len(),
        if refused.len() == 1 { " was" } else { "s were" },
        reasons.join("; "),
        if scatter {
            " (a scanner noisier than the noise profile scatters a wall so: give its profile)"
        } else {
            ""
        }
    )
}

/// A beam's point through a mount, its ray (origin and direction), and their derivatives
/// with respect to the mount parameters ([`MountModel::to_params`] order; see the module
/// doc).
#[derive(Clone, Copy, Debug)]
pub struct BeamPoint {
    /// The point (LRF frame, mm).
    pub point: V3,
    /// `∂p/∂θ_k`.
    pub d_mount: [V3; 8],
    /// Where the ray starts, `o = R_β offset`.
    pub origin: V3,
    /// `∂o/∂θ_k`.
    pub d_origin: [V3; 8],
    /// The ray's unit direction `u`.
    pub dir: V3,
    /// `∂u/∂θ_k`.
    pub d_dir: [V3; 8],
    /// `∂o/∂τ` and `∂u/∂τ`, τ the servo time offset (per second; zero at rest).
    pub d_time_offset: (V3, V3),
    /// The true range `ρ = (r − range_offset)/(1 + range_scale)` (mm).
    pub range: f64,
}

/// The point of `reading` through `mount` with its derivatives (see the module doc).
pub fn beam_point(reading: &BeamReading, mount: &MountModel) -> BeamPoint {
    let [ox, oy, oz, tilt_x, tilt_z, servo_scale, range_offset, range_scale] = mount.to_params();
    let servo_deg = reading.servo_deg_through(mount);
    let dbeta_dk = (servo_deg - mount.servo_zero_deg).to_radians();
    let dbeta_dtau = (reading.servo_rate_deg_s * (1.0 + servo_scale)).to_radians();
    let beta = mount.beta(servo_deg);
    let (rb, rb_dot) = (servo_rotation(beta), servo_rotation_dot(beta));
    let (rx, rx_dot) = rot_x(tilt_x);
    let (rz, rz_dot) = rot_z(tilt_z);
    let (sa, ca) = reading.alpha_rad.sin_cos();
    let l = V3::new(ca, sa, 0.0);
    let gain = 1.0 + range_scale;
    let rho = (reading.range_mm - range_offset) / gain;
    let off = V3::new(ox, oy, oz);
    let t = rx * (rz * l);
    let dir = rb * t;
    let origin = rb * off;
    let (mut d_origin, mut d_dir) = ([V3::zeros(); 8], [V3::zeros(); 8]);
    for (j, d) in d_origin.iter_mut().enumerate().take(3) {
        *d = rb.column(j).into_owned();
    }
    d_dir[3] = rb * (rx_dot * (rz * l));
    d_dir[4] = rb * (rx * (rz_dot * l));
    d_dir[5] = rb_dot * t * dbeta_dk;
    d_origin[5] = rb_dot * off * dbeta_dk;
    let mut d_mount: [V3; 8] = std::array::from_fn(|k| d_origin[k] + d_dir[k] * rho);
    d_mount[6] = -dir / gain;
    d_mount[7] = -dir * (rho / gain);
    BeamPoint {
        point: origin + dir * rho,
        d_mount,
        origin,
        d_origin,
        dir,
        d_dir,
        d_time_offset: (rb_dot * off * dbeta_dtau, rb_dot * t * dbeta_dtau),
        range: rho,
    }
}

/// A plane's reference frame: the normal `n₀` its local parameters turn, the tangent basis
/// `e₁, e₂` (also the axes of its bend), and the centre `c` and spread `L` of its beams that
/// scale the bend's coordinates (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneFrame {
    /// Reference unit normal `n₀`.
    pub normal: V3,
    /// First tangent direction.
    pub e1: V3,
    /// Second tangent direction.
    pub e2: V3,
    /// Centre of the plane's beams (mm).
    pub centre: V3,
    /// Spread of its beams (RMS distance from the centre, mm; at least 1).
    pub scale: f64,
}

impl PlaneFrame {
    /// The frame of unit normal `n` about `centre`, its bend coordinates scaled by `scale`.
    pub fn new(n: V3, centre: V3, scale: f64) -> Self {
        let n = n.normalize();
        let axis = if n.x.abs() < 0.6 { V3::x() } else { V3::y() };
        let e1 = n.cross(&axis).normalize();
        PlaneFrame {
            normal: n,
            e1,
            e2: n.cross(&e1),
            centre,
            scale: scale.max(1.0),
        }
    }

    /// The unit normal at local parameters `(a, b)` and its derivatives with respect to them.
    pub fn normal_at(&self, a: f64, b: f64) -> (V3, V3, V3) {
        let m = self.normal + self.e1 * a + self.e2 * b;
        let len = m.norm();
        let n = m / len;
        let da = (self.e1 - n * n.dot(&self.e1)) / len;
        let db = (self.e2 - n * n.dot(&self.e2)) / len;
        (n, da, db)
    }

    /// The bend's three basis functions at `x` (`ũ², ṽ², ũ ṽ`) and their gradients.
    fn bend_basis(&self, x: &V3) -> ([f64; 3], [V3; 3]) {
        let u = self.e1.dot(&(x - self.centre)) / self.scale;
        let v = self.e2.dot(&(x - self.centre)) / self.scale;
        let (gu, gv) = (self.e1 / self.scale, self.e2 / self.scale);
        (
            [u * u, v * v, u * v],
            [gu * (2.0 * u), gv * (2.0 * v), gu * v + gv * u],
        )
    }

    /// The frames of `planes` (unit normal, offset) about the beams `obs` assigned to them
    /// ([`associate`]) through `mount`: each frame's centre and spread are those of its
    /// beams' points.
    pub fn of_beams(
        readings: &[BeamReading],
        obs: &[PlaneObs],
        mount: &MountModel,
        planes: &[(V3, f64)],
    ) -> Vec<PlaneFrame> {
        let mut sum = vec![(V3::zeros(), 0.0f64, 0usize); planes.len()];
        let points: Vec<V3> = obs
            .iter()
            .map(|o| {
                let r = &readings[o.reading];
                mount
                    .scanner_at(r.servo_deg_through(mount))
                    .point(r.range_mm, r.alpha_rad)
            })
            .collect();
        for (o, p) in obs.iter().zip(&points) {
            sum[o.plane].0 += p;
            sum[o.plane].2 += 1;
        }
        let centres: Vec<V3> = sum.iter().map(|(s, _, n)| s / (*n).max(1) as f64).collect();
        for (o, p) in obs.iter().zip(&points) {
            sum[o.plane].1 += (p - centres[o.plane]).norm_squared();
        }
        planes
            .iter()
            .enumerate()
            .map(|(k, (n, _))| {
                let spread = (sum[k].1 / sum[k].2.max(1) as f64).sqrt();
                PlaneFrame::new(*n, centres[k], spread)
            })
            .collect()
    }
}

/// One beam on one plane of the room: an observation of an adjustment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneObs {
    /// Index of the reading (in the cloud's readings).
    pub reading: usize,
    /// Index of the plane.
    pub plane: usize,
    /// σ of its range (mm), at the range the plane predicts.
    pub sigma: f64,
}

/// A beam on a plane as an observation of a bundle adjustment ([`pingcal_ba::Residual`]):
/// the plane a vector parameter block of [`PLANE_UNKNOWNS`] about `frame`, the mount a vector
/// block of 8 ([`MountModel::to_params`]); residual `(r − r̂)/σ` (see the module doc).
#[derive(Clone, Debug)]
pub struct BeamOnPlane {
    /// The reading.
    pub reading: BeamReading,
    /// σ of the range (mm).
    pub sigma: f64,
    /// The servo's zero (degrees; not an unknown).
    pub servo_zero_deg: f64,
    /// The plane's reference frame.
    pub frame: PlaneFrame,
    /// The plane: a parameter block of [`PLANE_UNKNOWNS`].
    pub plane: pingcal_ba::ParameterKey,
    /// The mount: a parameter block of 8.
    pub mount: pingcal_ba::ParameterKey,
    /// The servo time offset: a parameter block of 1, or None (τ = 0; see
    /// [`crate::beam::BeamOnBall::time_offset`]).
    pub time_offset: Option<pingcal_ba::ParameterKey>,
}

/// A plane beam's residual and its derivatives: `e`, `∂e/∂plane`, `∂e/∂θ`, `∂e/∂τ`.
type PlaneResidual = (f64, [f64; PLANE_UNKNOWNS], [f64; 8], f64);

/// The residual of `reading` on the plane `plane` (its [`PLANE_UNKNOWNS`] about `frame`)
/// through the mount `theta` (see the module doc): `e = r − r̂`, with `∂e/∂plane` and
/// `∂e/∂θ`. NaN when the ray is parallel to the plane.
fn plane_residual(
    reading: &BeamReading,
    servo_zero_deg: f64,
    frame: &PlaneFrame,
    plane: &[f64],
    (theta, tau): (&[f64; 8], f64),
) -> PlaneResidual {
    let mount = MountModel {
        servo_time_offset_s: tau,
        ..MountModel::from_params(theta, servo_zero_deg)
    };
    let b = beam_point(reading, &mount);
    let (n, dn_a, dn_b) = frame.normal_at(plane[0], plane[1]);
    let s = n.dot(&b.dir);
    let t0 = (plane[2] - n.dot(&b.origin)) / s;
    let h = b.origin + b.dir * t0;
    let (basis, grads) = frame.bend_basis(&h);
    let c = [plane[3], plane[4], plane[5]];
    let bend: f64 = (0..3).map(|j| c[j] * basis[j]).sum();
    let grad_b: V3 = (0..3).map(|j| grads[j] * c[j]).sum();
    let tau = t0 + bend / s;
    let gain = 1.0 + theta[7];
    let e = reading.range_mm - (tau * gain + theta[6]);
    // ∂τ from ∂t₀, ∂h = ∂o + t₀ ∂u + u ∂t₀ and ∂s
    let d_tau = |dt0: f64, dh: V3, ds: f64| dt0 + grad_b.dot(&dh) / s - bend * ds / (s * s);
    let mut d_plane = [0.0; PLANE_UNKNOWNS];
    for (k, dn) in [dn_a, dn_b].iter().enumerate() {
        let dt0 = -dn.dot(&h) / s;
        d_plane[k] = -gain * d_tau(dt0, b.dir * dt0, dn.dot(&b.dir));
    }
    d_plane[2] = -gain * d_tau(1.0 / s, b.dir / s, 0.0);
    for j in 0..3 {
        d_plane[3 + j] = -gain * basis[j] / s;
    }
    // through the ray's origin and direction
    let d_ray = |dob: V3, dub: V3| {
        let dt0 = -(n.dot(&dob) + t0 * n.dot(&dub)) / s;
        let dh = dob + dub * t0 + b.dir * dt0;
        -gain * d_tau(dt0, dh, n.dot(&dub))
    };
    let mut d_mount = [0.0; 8];
    for (k, dm) in d_mount.iter_mut().enumerate().take(6) {
        *dm = d_ray(b.d_origin[k], b.d_dir[k]);
    }
    d_mount[6] = -1.0;
    d_mount[7] = -tau;
    let d_time_offset = d_ray(b.d_time_offset.0, b.d_time_offset.1);
    (e, d_plane, d_mount, d_time_offset)
}

impl BeamOnPlane {
    /// `e = r − r̂` (mm, not whitened) at these values (`tau`: the servo time offset, s);
    /// None when undefined.
    pub fn error(&self, plane: &[f64], theta: &[f64], tau: f64) -> Option<f64> {
        let th: [f64; 8] = theta.try_into().ok()?;
        (plane.len() == PLANE_UNKNOWNS)
            .then(|| {
                let at = (&th, tau);
                plane_residual(&self.reading, self.servo_zero_deg, &self.frame, plane, at).0
            })
            .filter(|e| e.is_finite())
    }
}

impl pingcal_ba::Residual for BeamOnPlane {
    fn dim(&self) -> usize {
        1
    }

    fn blocks(&self) -> Vec<pingcal_ba::Block> {
        let mut blocks = vec![
            pingcal_ba::Block::Parameter(self.plane),
            pingcal_ba::Block::Parameter(self.mount),
        ];
        blocks.extend(self.time_offset.map(pingcal_ba::Block::Parameter));
        blocks
    }

    fn evaluate(
        &self,
        values: &[pingcal_ba::Value],
        residual: &mut [f64],
        jacobians: pingcal_ba::Jacobians<'_>,
    ) -> bool {
        let (Some(plane), Some(theta)) = (values[0].vector(), values[1].vector()) else {
            return false;
        };
        let (Ok(th), PLANE_UNKNOWNS) = (<[f64; 8]>::try_from(theta), plane.len()) else {
            return false;
        };
        let tau = match self.time_offset {
            Some(_) => match values.get(2).and_then(|v| v.vector()) {
                Some(&[tau]) => tau,
                _ => return false,
            },
            None => 0.0,
        };
        let (e, dp, dm, dt) = plane_residual(
            &self.reading,
            self.servo_zero_deg,
            &self.frame,
            plane,
            (&th, tau),
        );
        if !e.is_finite() {
            return false;
        }
        let s = self.sigma;
        residual[0] = e / s;
        if let Some(j) = jacobians {
            for (k, v) in dp.iter().enumerate() {
                j[0][(0, k)] = v / s;
            }
            for (k, v) in dm.iter().enumerate() {
                j[1][(0, k)] = v / s;
            }
            if self.time_offset.is_some() {
                j[2][(0, 0)] = dt / s;
            }
        }
        true
    }

    fn group(&self) -> &str {
        PLANE_GROUP
    }
}

/// The flatness prior on a plane's bend: a [`pingcal_ba::ParameterPrior`] of σ
/// [`FLATNESS_MM`] at zero on the bend coefficients of parameter block `plane`.
pub fn flatness_prior(plane: pingcal_ba::ParameterKey) -> pingcal_ba::ParameterPrior {
    pingcal_ba::ParameterPrior {
        parameter: plane,
        components: vec![3, 4, 5],
        value: vec![0.0; 3],
        sigma: vec![FLATNESS_MM; 3],
    }
}

/// Options of [`mount_from_room`] and [`associate`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoomOptions {
    /// The range noise (σ of each range).
    pub noise: RangeNoise,
    /// A plane keeps at most this many beams (taken evenly in scan order).
    pub max_beams_per_plane: usize,
    /// Beams meeting a plane at a larger incidence (a smaller |n·u|) are not used.
    pub min_cos_incidence: f64,
    /// The first association's gate (mm): how far apart a wrong mount may put a wall's two
    /// half-sweeps.
    pub first_gate_mm: f64,
    /// The smallest gate of the later rounds (mm): a wall's unevenness.
    pub gate_floor_mm: f64,
    /// Association rounds (each beam re-decided through the mount the round before gave).
    pub rounds: usize,
    /// The mount parameters to estimate (offset_y is never estimated: see the module doc).
    pub estimate: [bool; 8],
}

impl Default for RoomOptions {
    fn default() -> Self {
        RoomOptions {
            noise: RangeNoise::default(),
            max_beams_per_plane: 4000,
            min_cos_incidence: 0.3,
            first_gate_mm: 60.0,
            gate_floor_mm: 5.0,
            rounds: 3,
            estimate: [true, false, true, true, true, true, true, true],
        }
    }
}

/// The gate of an association round: `first` (mm) in the first, else `k σ s0` (at least
/// `floor` mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gate {
    /// The first round's wide gate (mm).
    First(f64),
    /// A later round's: k, the round's σ0, the floor (mm).
    Sigma {
        /// Gate in σ.
        k: f64,
        /// σ0 of the round before (at least 1 is used).
        sigma0: f64,
        /// Smallest gate, mm.
        floor_mm: f64,
    },
}

/// What the association makes of one reading ([`associate`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Placed {
    /// Within the gate of no plane, or of two.
    Off,
    /// Within the gate of this plane, but another is met as near: an edge of the room.
    Edge,
    /// Within the gate of this plane, which it grazes.
    Grazing,
    /// On a plane.
    On(PlaneObs),
}

/// Reading `i` (`r`) against `planes` through `mount` (see the module doc).
fn place(
    (i, r): (usize, &BeamReading),
    mount: &MountModel,
    planes: &[(V3, f64)],
    gate: Gate,
    opts: &RoomOptions,
) -> Placed {
    let pose = mount.scanner_at(r.servo_deg_through(mount));
    let (o, u) = (pose.origin(), pose.direction(r.alpha_rad, 0.0));
    // the range at which the ray meets each plane, and the gate there (its σ at
    // that range: a σ that followed the reading's own noise would bias the fit)
    let meets: Vec<Option<(f64, f64)>> = planes
        .iter()
        .map(|(n, d)| {
            let t = (d - n.dot(&o)) / n.dot(&u);
            (t.is_finite() && t > 0.0).then(|| {
                let sigma = opts.noise.sigma(t).max(0.5);
                let g = match gate {
                    Gate::First(mm) => mm.max(3.0 * sigma),
                    Gate::Sigma {
                        k,
                        sigma0,
                        floor_mm,
                    } => (k * sigma * sigma0.max(1.0)).max(floor_mm),
                };
                (t, g)
            })
        })
        .collect();
    // the reading within the gate of one plane: its range misfit r̂ − r at most g
    let r_true = (r.range_mm - mount.range_offset_mm) / (1.0 + mount.range_scale);
    let mut hits =
        (0..planes.len()).filter(|&k| meets[k].is_some_and(|(t, g)| (r_true - t).abs() <= g));
    let (Some(k), None) = (hits.next(), hits.next()) else {
        return Placed::Off;
    };
    let (t, g) = meets[k].expect("a hit meets its plane");
    // an edge of the room, judged on the rays alone (the noise must not decide which
    // side of the cut a reading falls): another plane met within twice the gates
    let edge = (0..planes.len())
        .any(|j| j != k && meets[j].is_some_and(|(tj, gj)| (tj - t).abs() <= 2.0 * g.max(gj)));
    if edge {
        Placed::Edge
    } else if planes[k].0.dot(&u).abs() < opts.min_cos_incidence {
        Placed::Grazing
    } else {
        Placed::On(PlaneObs {
            reading: i,
            plane: k,
            sigma: opts.noise.sigma(t).max(0.5),
        })
    }
}

/// The beams of `readings` on `planes` through `mount` (see the module doc), at most
/// `opts.max_beams_per_plane` per plane, in reading order within each plane.
pub fn associate(
    readings: &[BeamReading],
    mount: &MountModel,
    planes: &[(V3, f64)],
    gate: Gate,
    opts: &RoomOptions,
) -> Vec<PlaneObs> {
    let per: Vec<Option<PlaneObs>> = readings
        .par_iter()
        .enumerate()
        .map(|ir| match place(ir, mount, planes, gate, opts) {
            Placed::On(o) => Some(o),
            _ => None,
        })
        .collect();
    let mut by_plane: Vec<Vec<PlaneObs>> = vec![Vec::new(); planes.len()];
    for o in per.into_iter().flatten() {
        by_plane[o.plane].push(o);
    }
    let mut out = Vec::new();
    for obs in by_plane {
        let stride = obs.len().div_ceil(opts.max_beams_per_plane.max(1)).max(1);
        out.extend(obs.into_iter().step_by(stride));
    }
    out
}

/// Why no plane kept [`MIN_PLANE_BEAMS`] beams ([`associate`] through `mount` with `gate`):
/// one line with the beams within a gate, those at an edge or grazing, and the most any
/// plane kept.
fn why_no_plane(
    readings: &[BeamReading],
    mount: &MountModel,
    planes: &[(V3, f64)],
    gate: Gate,
    opts: &RoomOptions,
) -> String {
    let placed: Vec<Placed> = readings
        .par_iter()
        .enumerate()
        .map(|ir| place(ir, mount, planes, gate, opts))
        .collect();
    let count = |f: &dyn Fn(&Placed) -> bool| placed.iter().filter(|p| f(p)).count();
    let mut per = vec![0usize; planes.len()];
    for p in &placed {
        if let Placed::On(o) = p {
            per[o.plane] += 1;
        }
    }
    let (edge, grazing) = (
        count(&|p| *p == Placed::Edge),
        count(&|p| *p == Placed::Grazing),
    );
    let on = count(&|p| matches!(p, Placed::On(_)));
    let gate_text = match gate {
        Gate::First(mm) => format!("{mm:.0} mm (or 3σ)"),
        Gate::Sigma { k, .. } => format!("{k}σ"),
    };
    format!(
        "{} plane{} found in the cloud's {} beams, but none has {MIN_PLANE_BEAMS} beams on it through the mount: {} beams are within {gate_text} of one plane ({} at most on one), {edge} more lie where two planes meet (an edge of the room) and {grazing} more graze their plane (incidence over {:.0}°); the mount cannot be found from the room",
        planes.len(),
        if planes.len() == 1 { " was" } else { "s were" },
        readings.len(),
        on,
        per.iter().max().copied().unwrap_or(0),
        opts.min_cos_incidence.acos().to_degrees()
    )
}

/// The planes of `planes` with at least [`MIN_PLANE_BEAMS`] beams in `obs`; the beams of the
/// others are removed from `obs` and the rest renumbered.
pub fn drop_thin_planes(obs: &mut Vec<PlaneObs>, planes: &[(V3, f64)]) -> Vec<(V3, f64)> {
    let mut count = vec![0usize; planes.len()];
    for o in obs.iter() {
        count[o.plane] += 1;
    }
    let mut new_index = vec![usize::MAX; planes.len()];
    let mut kept = Vec::new();
    for (k, p) in planes.iter().enumerate() {
        if count[k] >= MIN_PLANE_BEAMS {
            new_index[k] = kept.len();
            kept.push(*p);
        }
    }
    obs.retain(|o| new_index[o.plane] != usize::MAX);
    for o in obs.iter_mut() {
        o.plane = new_index[o.plane];
    }
    kept
}

/// Planes of `planes` merged where two are one wall seen twice (see the module doc): the
/// first of each group is kept.
pub fn merge_planes(planes: &[(V3, f64)]) -> Vec<(V3, f64)> {
    let cos_max = MERGE_ANGLE_DEG.to_radians().cos();
    let mut out: Vec<(V3, f64)> = Vec::new();
    for &(n, d) in planes {
        let (n, d) = if d < 0.0 { (-n, -d) } else { (n, d) };
        let twin = out
            .iter()
            .any(|(m, e)| n.dot(m) >= cos_max && (d - e).abs() <= MERGE_DISTANCE_MM);
        if !twin {
            out.push((n, d));
        }
    }
    out
}

/// One mount parameter of [`RoomMount`].
#[derive(Clone, Debug, PartialEq)]
pub struct RoomParameter {
    /// Its name ([`MOUNT_PARAM_NAMES`]).
    pub name: &'static str,
    /// Value: mm for offsets and the range offset, degrees for the tilts, 1 for the scales.
    pub value: f64,
    /// Its σ (same unit); None when held.
    pub sigma: Option<f64>,
    /// Why it was held (None: estimated).
    pub held: Option<String>,
}

/// A plane of the room as the estimate sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct RoomPlane {
    /// Unit normal (pointing away from the LRF: `offset_mm` ≥ 0).
    pub normal: V3,
    /// Offset: `normal · x = offset_mm`.
    pub offset_mm: f64,
    /// Beams used.
    pub beams: usize,
    /// RMS of their range misfits (mm).
    pub rms_mm: f64,
    /// The largest bend over its beams (mm, signed: along the normal).
    pub bend_mm: f64,
}

/// The mount estimated from the room ([`mount_from_room`]).
#[derive(Clone, Debug)]
pub struct RoomMount {
    /// The estimated mount (held parameters at their start).
    pub mount: MountModel,
    /// Every parameter of [`MOUNT_PARAM_NAMES`]: estimated with σ, or held with the reason.
    pub parameters: Vec<RoomParameter>,
    /// Covariance of the mount parameters ([`MountModel::to_params`] units; zero rows for
    /// held ones).
    pub covariance: DMatrix<f64>,
    /// The planes.
    pub planes: Vec<RoomPlane>,
    /// σ0 of the adjustment (1: the beams scatter about their planes as the noise profile says).
    pub sigma0: f64,
    /// Redundancy.
    pub redundancy: usize,
    /// Beams used.
    pub beams: usize,
    /// Beams removed as gross errors.
    pub rejected: usize,
    /// Association rounds run.
    pub rounds: usize,
    /// Searches for the walls (1: the walls as given; more: found again through the
    /// estimate, see [`mount_from_room_refinding`]).
    pub wall_searches: usize,
    /// The servo angles the scans span.
    pub sweep: Sweep,
}

/// The unit of parameter `k` in reports (degrees for the tilts).
fn to_unit(k: usize, v: f64) -> f64 {
    MountParam::at(k).in_report_unit(v)
}

/// The planes of an adjustment: each one's frame (fixed while it runs) and unknowns.
#[derive(Clone, Debug)]
struct Planes {
    frames: Vec<PlaneFrame>,
    values: Vec<[f64; PLANE_UNKNOWNS]>,
}

impl Planes {
    /// The planes (unit normal, offset) with frames about their beams, flat.
    fn new(frames: Vec<PlaneFrame>, planes: &[(V3, f64)]) -> Self {
        let values = planes
            .iter()
            .map(|(_, d)| [0.0, 0.0, *d, 0.0, 0.0, 0.0])
            .collect();
        Planes { frames, values }
    }

    /// Unit normal and offset of each plane.
    fn flat(&self) -> Vec<(V3, f64)> {
        (self.frames.iter().zip(&self.values))
            .map(|(f, v)| (f.normal_at(v[0], v[1]).0, v[2]))
            .collect()
    }

    /// Moved by the plane part of a step (from index 8 on).
    fn stepped(&self, delta: &DVector<f64>) -> Self {
        let values = (self.values.iter().enumerate())
            .map(|(k, v)| std::array::from_fn(|j| v[j] + delta[8 + PLANE_UNKNOWNS * k + j]))
            .collect();
        Planes {
            frames: self.frames.clone(),
            values,
        }
    }
}

/// A solved adjustment of the mount and the planes.
struct Solution {
    theta: [f64; 8],
    planes: Planes,
    /// Inverse of the normal matrix (cofactors) at the solution: 8 mount rows, then
    /// [`PLANE_UNKNOWNS`] per plane.
    cofactors: DMatrix<f64>,
    sigma0: f64,
    redundancy: usize,
    /// Per observation: kept (not a gross error).
    kept: Vec<bool>,
    /// Per observation: its residual e (mm).
    errors: Vec<f64>,
}

/// What an adjustment holds fixed: the readings, their planes, the servo zero, the free
/// mount components and where their weak priors sit.
struct Fixed<'a> {
    readings: &'a [BeamReading],
    obs: &'a [PlaneObs],
    zero: f64,
    free: &'a [bool; 8],
    prior_at: [f64; 8],
    /// σ of each free component's prior ([`WEAK_PRIOR_SIGMA`], or a real rig's error for
    /// what a partial sweep does not determine).
    prior_sigma: [f64; 8],
}

/// The normal equations of the whitened residuals at `theta` and `planes`, with the weak
/// priors on the free mount components and the flatness priors; fixed components get a
/// unit diagonal. Returns (N, g, ½χ², e per observation).
fn normal_equations(
    f: &Fixed,
    kept: &[bool],
    theta: &[f64; 8],
    planes: &Planes,
) -> (DMatrix<f64>, DVector<f64>, f64, Vec<f64>) {
    let m = 8 + PLANE_UNKNOWNS * planes.values.len();
    let mut nm = DMatrix::<f64>::zeros(m, m);
    let mut g = DVector::<f64>::zeros(m);
    let mut cost = 0.0;
    let mut errors = Vec::with_capacity(f.obs.len());
    let (mut idx, mut jac) = ([0usize; 8 + PLANE_UNKNOWNS], [0.0f64; 8 + PLANE_UNKNOWNS]);
    for (o, &keep) in f.obs.iter().zip(kept) {
        let k = o.plane;
        // the room alone does not estimate the servo's timing (τ = 0)
        let (e, dp, dm, _) = plane_residual(
            &f.readings[o.reading],
            f.zero,
            &planes.frames[k],
            &planes.values[k],
            (theta, 0.0),
        );
        errors.push(e);
        if !keep || !e.is_finite() {
            continue;
        }
        let w = 1.0 / o.sigma;
        let mut n = 0;
        for j in (0..8).filter(|&j| f.free[j]) {
            (idx[n], jac[n]) = (j, dm[j] * w);
            n += 1;
        }
        for (j, v) in dp.iter().enumerate() {
            (idx[n], jac[n]) = (8 + PLANE_UNKNOWNS * k + j, v * w);
            n += 1;
        }
        let r = e * w;
        cost += 0.5 * r * r;
        for a in 0..n {
            g[idx[a]] += jac[a] * r;
            for b in 0..n {
                nm[(idx[a], idx[b])] += jac[a] * jac[b];
            }
        }
    }
    let mut prior = |i: usize, value: f64, sigma: f64| {
        let r = value / sigma;
        cost += 0.5 * r * r;
        g[i] += r / sigma;
        nm[(i, i)] += 1.0 / (sigma * sigma);
    };
    for (j, &t) in theta.iter().enumerate().filter(|(j, _)| f.free[*j]) {
        prior(j, t - f.prior_at[j], f.prior_sigma[j]);
    }
    for (k, v) in planes.values.iter().enumerate() {
        for (j, &vj) in v.iter().enumerate().take(PLANE_UNKNOWNS).skip(3) {
            prior(8 + PLANE_UNKNOWNS * k + j, vj, FLATNESS_MM);
        }
    }
    for j in (0..8).filter(|&j| !f.free[j]) {
        nm[(j, j)] = 1.0;
    }
    (nm, g, cost, errors)
}

/// Levenberg–Marquardt from `theta` and `planes` until the cost stops falling.
fn minimise(
    f: &Fixed,
    kept: &[bool],
    mut theta: [f64; 8],
    mut planes: Planes,
) -> Option<([f64; 8], Planes)> {
    let mut lambda = 1e-3;
    for _ in 0..100 {
        let (nm, g, cost, _) = normal_equations(f, kept, &theta, &planes);
        let mut damped = nm;
        for k in 0..damped.nrows() {
            damped[(k, k)] *= 1.0 + lambda;
        }
        let delta = -damped.cholesky()?.solve(&g);
        let mut th2 = theta;
        for k in (0..8).filter(|&k| f.free[k]) {
            th2[k] += delta[k];
        }
        let pl2 = planes.stepped(&delta);
        let (_, _, cost2, _) = normal_equations(f, kept, &th2, &pl2);
        if cost2 <= cost {
            (theta, planes) = (th2, pl2);
            lambda = (lambda * 0.1).max(1e-9);
            if cost - cost2 <= 1e-10 * cost.max(1.0) {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e8 {
                break;
            }
        }
    }
    Some((theta, planes))
}

/// The adjustment of the mount's free parameters and the planes from `start` (see the
/// module doc), with rounds of gross error removal. None when the normal matrix is singular.
fn adjust(
    readings: &[BeamReading],
    obs: &[PlaneObs],
    start: &MountModel,
    planes: &Planes,
    free: &[bool; 8],
) -> Option<Solution> {
    adjust_with(readings, obs, (start, &WEAK_PRIOR_SIGMA), planes, free)
}

/// [`adjust`] with the free components' priors of σ `prior_sigma` at `start`.
fn adjust_with(
    readings: &[BeamReading],
    obs: &[PlaneObs],
    (start, prior_sigma): (&MountModel, &[f64; 8]),
    planes: &Planes,
    free: &[bool; 8],
) -> Option<Solution> {
    let f = Fixed {
        readings,
        obs,
        zero: start.servo_zero_deg,
        free,
        prior_at: start.to_params(),
        prior_sigma: *prior_sigma,
    };
    let (mut theta, mut planes) = (f.prior_at, planes.clone());
    let mut kept = vec![true; obs.len()];
    let unknowns = free.iter().filter(|f| **f).count() + PLANE_UNKNOWNS * planes.values.len();
    for round in 0..=3 {
        (theta, planes) = minimise(&f, &kept, theta, planes)?;
        let (nm, _, cost, errors) = normal_equations(&f, &kept, &theta, &planes);
        let n = kept.iter().filter(|k| **k).count();
        let redundancy = n.saturating_sub(unknowns).max(1);
        let sigma0 = (2.0 * cost / redundancy as f64).sqrt();
        let limit = REJECT * sigma0.max(1.0);
        let bad: Vec<usize> = (0..obs.len())
            .filter(|&i| kept[i] && !(errors[i].abs() / obs[i].sigma <= limit))
            .collect();
        if bad.is_empty() || round == 3 {
            return Some(Solution {
                theta,
                planes,
                cofactors: nm.try_inverse()?,
                sigma0,
                redundancy,
                kept,
                errors,
            });
        }
        for i in bad {
            kept[i] = false;
        }
    }
    None
}

/// Why mount parameter `k` is not determined by the solution's cofactors (with the weak
/// priors), if it is not; the first value ranks how badly.
fn not_determined(
    k: usize,
    q: &DMatrix<f64>,
    free: &[bool; 8],
    sweep: &Sweep,
) -> Option<(f64, String)> {
    let sd = q[(k, k)].max(0.0).sqrt();
    let share = sd / WEAK_PRIOR_SIGMA[k];
    let u = MountParam::at(k).unit();
    // a full turn's words are the room's; a partial sweep's name the sweep and what to do
    let partial = |why: String| match sweep.is_full_turn() {
        true => why,
        false => format!(
            "the sweep is {}: {}; {}",
            sweep.describe(),
            why.replacen("the room does not", "it does not", 1)
                .replacen(
                    "the room cannot tell them apart",
                    "it cannot tell them apart",
                    1
                ),
            sweep.advice(k)
        ),
    };
    if !(share <= MAX_PRIOR_SHARE) {
        return Some((
            1e6 + share,
            partial(format!(
                "the room does not determine it (σ {:.4}{u} against a prior of {:.4}{u})",
                to_unit(k, sd),
                to_unit(k, WEAK_PRIOR_SIGMA[k])
            )),
        ));
    }
    for j in 0..q.nrows() {
        if j == k || (j < 8 && !free[j]) {
            continue;
        }
        let r = q[(k, j)] / (q[(k, k)] * q[(j, j)]).sqrt();
        if r.abs() > MAX_CORRELATION {
            let other = if j < 8 {
                MOUNT_PARAM_NAMES[j].to_string()
            } else {
                let what = ["normal", "normal", "offset", "bend", "bend", "bend"];
                format!(
                    "plane {}'s {}",
                    (j - 8) / PLANE_UNKNOWNS + 1,
                    what[(j - 8) % PLANE_UNKNOWNS]
                )
            };
            return Some((
                r.abs(),
                partial(format!(
                    "it is correlated with {other} at ρ = {r:.4}: the room cannot tell them apart"
                )),
            ));
        }
    }
    None
}

/// The mount of a rotating LRF from the planes of the room it scanned (see the module
/// doc): `cloud` must carry its readings (scan files, not a PLY), `walls` are the room's
/// planes as found in `cloud` through `start` (e.g. [`crate::ball_finder::find_walls`]), and
/// `start` is the mount to start from (held parameters stay at its values).
pub fn mount_from_room(
    cloud: &Cloud,
    walls: &[(V3, f64)],
    start: &MountModel,
    opts: &RoomOptions,
) -> Result<RoomMount> {
    mount_from_room_at(cloud, walls, start, start, opts)
}

/// [`mount_from_room`], then the walls found again (`find`, e.g.
/// [`crate::ball_finder::find_walls`]) in `cloud` through the mount it estimated, and the
/// mount estimated again from those, as long as they are more planes than it used (at most
/// [`WALL_SEARCHES`] searches in all). Under a wrong mount a wall's two half-sweeps are
/// two planes at an angle, which a wall finder may take for clutter and leave out; a room
/// short of a wall then gives σ's half the real errors, its beams near the missing wall's
/// edges read as beams of the walls that meet it. The priors and held values stay at
/// `start`; [`RoomMount::wall_searches`] says how many searches were run.
pub fn mount_from_room_refinding(
    cloud: &Cloud,
    walls: &[(V3, f64)],
    start: &MountModel,
    opts: &RoomOptions,
    find: impl Fn(&Cloud) -> Vec<(V3, f64)>,
) -> Result<RoomMount> {
    let mut best = mount_from_room(cloud, walls, start, opts)?;
    for search in 2..=WALL_SEARCHES {
        let Some(through) = cloud.through(&best.mount) else {
            break;
        };
        let again = find(&through);
        if merge_planes(&again).len() <= best.planes.len() {
            break;
        }
        match mount_from_room_at(cloud, &again, start, &best.mount, opts) {
            Ok(r) if r.planes.len() > best.planes.len() => {
                best = RoomMount {
                    wall_searches: search,
                    ..r
                };
            }
            _ => break,
        }
    }
    Ok(best)
}

/// Wall searches of [`mount_from_room_refinding`] at most (the first through the start).
pub const WALL_SEARCHES: usize = 3;

/// [`mount_from_room`] from the mount `from` (the cloud of `walls` made through it), the
/// priors and held values at `start`.
fn mount_from_room_at(
    cloud: &Cloud,
    walls: &[(V3, f64)],
    start: &MountModel,
    from: &MountModel,
    opts: &RoomOptions,
) -> Result<RoomMount> {
    let readings = cloud.readings.as_ref().ok_or_else(|| {
        LrfError::Invalid(
            "the mount from the room needs the scans' readings (pingcal-scan files), not a point cloud"
                .into(),
        )
    })?;
    let mut planes = merge_planes(walls);
    if planes.is_empty() {
        return Err(LrfError::Degenerate(
            "no wall, floor or ceiling was found in the cloud: the mount cannot be found from the room".into(),
        ));
    }
    let mut free = opts.estimate;
    let origin = MountParam::OffsetY.index();
    free[origin] = false;
    let mut held: [Option<String>; 8] = Default::default();
    held[origin] = Some("it moves the whole cloud along the servo axis, which the planes take up: the LRF frame's origin along it is defined, not estimated".into());
    for k in 0..8 {
        if held[k].is_none() && !free[k] {
            held[k] = Some("not asked for: held at its start".into());
        }
    }
    let mut mount = mount_with(start, from, &free);
    let mut gate = Gate::First(opts.first_gate_mm);
    let sweep = Sweep::of(readings).unwrap_or(Sweep {
        min_deg: -180.0,
        max_deg: 180.0,
    });
    let (mut sol, mut obs, mut rounds) = (None, Vec::new(), 0);
    for _ in 0..opts.rounds.max(1) {
        rounds += 1;
        obs = associate(readings, &mount, &planes, gate, opts);
        let found = planes.clone();
        planes = drop_thin_planes(&mut obs, &planes);
        if planes.is_empty() {
            let why = why_no_plane(readings, &mount, &found, gate, opts);
            return Err(LrfError::Degenerate(why));
        }
        let frames = PlaneFrame::of_beams(readings, &obs, &mount, &planes);
        let at = mount_with(start, &mount, &free);
        let pl = Planes::new(frames, &planes);
        let first = adjust(readings, &obs, &at, &pl, &free).ok_or_else(singular)?;
        // held before the next association, so that no undetermined parameter wanders
        // and moves the gates; then those that a real error in the held ones would move
        let fh = (&mut free, &mut held);
        let s = hold_undetermined(readings, &obs, start, &pl, fh, first, &sweep)?;
        let weak: [bool; 8] = std::array::from_fn(|k| opts.estimate[k] && k != origin && !free[k]);
        let fh = (&mut free, &mut held);
        let s = match sweep.is_full_turn() {
            true => s,
            false => soften_held(readings, &obs, start, &pl, fh, weak, s, &sweep)?,
        };
        mount = MountModel::from_params(&s.theta, start.servo_zero_deg);
        planes = s.planes.flat();
        gate = Gate::Sigma {
            k: GATE_K,
            sigma0: s.sigma0,
            floor_mm: opts.gate_floor_mm,
        };
        sol = Some(s);
    }
    let s = sol.expect("at least one round");
    let mut out = summarise(&s, &obs, readings, start, held);
    out.rounds = rounds;
    out.sweep = sweep;
    Ok(out)
}

fn singular() -> LrfError {
    LrfError::Degenerate("the room's planes leave the mount singular".into())
}

/// What the room does not determine in the solution `s` held, one at a time, and the rest
/// adjusted again each time (see the module doc).
fn hold_undetermined(
    readings: &[BeamReading],
    obs: &[PlaneObs],
    start: &MountModel,
    planes: &Planes,
    (free, held): (&mut [bool; 8], &mut [Option<String>; 8]),
    mut s: Solution,
    sweep: &Sweep,
) -> Result<Solution> {
    loop {
        let worst = (0..8)
            .filter(|&k| free[k])
            .filter_map(|k| {
                not_determined(k, &s.cofactors, free, sweep).map(|(rank, why)| (rank, k, why))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, k, why)) = worst else {
            return Ok(s);
        };
        free[k] = false;
        held[k] = Some(why);
        let at = mount_with(
            start,
            &MountModel::from_params(&s.theta, start.servo_zero_deg),
            free,
        );
        s = adjust(readings, obs, &at, planes, free).ok_or_else(singular)?;
    }
}

/// A partial sweep's last adjustment ([`crate::sweep`]): the parameters held for want of
/// data (`weak`) free again under priors of a real rig's error ([`RIG_ERROR`]) at their
/// start, so that what is estimated carries their uncertainty in its σ; an estimated
/// parameter whose σ is then more than a real rig's error is held too (the worst first,
/// one at a time), the sweep telling no more of it than a rig's tolerance does.
#[allow(clippy::too_many_arguments)]
fn soften_held(
    readings: &[BeamReading],
    obs: &[PlaneObs],
    start: &MountModel,
    planes: &Planes,
    (free, held): (&mut [bool; 8], &mut [Option<String>; 8]),
    mut weak: [bool; 8],
    s: Solution,
    sweep: &Sweep,
) -> Result<Solution> {
    if !weak.iter().any(|&w| w) {
        return Ok(s);
    }
    let current = MountModel::from_params(&s.theta, start.servo_zero_deg);
    loop {
        let open: [bool; 8] = std::array::from_fn(|k| free[k] || weak[k]);
        let sigma: [f64; 8] = std::array::from_fn(|k| {
            if weak[k] {
                RIG_ERROR[k]
            } else {
                WEAK_PRIOR_SIGMA[k]
            }
        });
        let at = mount_with(start, &current, free);
        let soft = adjust_with(readings, obs, (&at, &sigma), planes, &open).ok_or_else(singular)?;
        let sd = |k: usize| soft.cofactors[(k, k)].max(0.0).sqrt() * soft.sigma0;
        let worst = (0..8)
            .filter(|&k| free[k] && sd(k) > RIG_ERROR[k])
            .max_by(|&a, &b| (sd(a) / RIG_ERROR[a]).total_cmp(&(sd(b) / RIG_ERROR[b])));
        let Some(k) = worst else {
            for j in (0..8).filter(|&j| weak[j]) {
                let p = MountParam::at(j);
                let kept = "kept within a real rig's error";
                if let Some(why) = held[j].as_mut().filter(|w| !w.contains(kept)) {
                    why.push_str(&format!(
                        " ({kept}, {:.3}{}, of its start)",
                        p.in_report_unit(RIG_ERROR[j]),
                        p.unit()
                    ));
                }
            }
            return Ok(soft);
        };
        let weak_names: Vec<usize> = (0..8).filter(|&j| weak[j]).collect();
        held[k] = Some(vaguer_than_a_rig(k, sd(k), &weak_names, sweep));
        (free[k], weak[k]) = (false, true);
    }
}

/// `current` with the parameters not `free` put back at their values in `start`.
fn mount_with(start: &MountModel, current: &MountModel, free: &[bool; 8]) -> MountModel {
    let (a, b) = (start.to_params(), current.to_params());
    let th: [f64; 8] = std::array::from_fn(|k| if free[k] { b[k] } else { a[k] });
    MountModel::from_params(&th, start.servo_zero_deg)
}

fn summarise(
    s: &Solution,
    obs: &[PlaneObs],
    readings: &[BeamReading],
    start: &MountModel,
    held: [Option<String>; 8],
) -> RoomMount {
    let s02 = s.sigma0 * s.sigma0;
    let mut covariance = DMatrix::zeros(8, 8);
    for a in 0..8 {
        for b in 0..8 {
            if held[a].is_none() && held[b].is_none() {
                covariance[(a, b)] = s.cofactors[(a, b)] * s02;
            }
        }
    }
    let parameters = (0..8)
        .map(|k| RoomParameter {
            name: MOUNT_PARAM_NAMES[k],
            value: to_unit(k, s.theta[k]),
            sigma: held[k]
                .is_none()
                .then(|| to_unit(k, covariance[(k, k)].max(0.0).sqrt())),
            held: held[k].clone(),
        })
        .collect();
    let mount = MountModel::from_params(&s.theta, start.servo_zero_deg);
    let flat = s.planes.flat();
    let mut stats = vec![(0usize, 0.0f64, 0.0f64); flat.len()];
    for ((o, e), _) in obs.iter().zip(&s.errors).zip(&s.kept).filter(|(_, k)| **k) {
        let (frame, v) = (&s.planes.frames[o.plane], &s.planes.values[o.plane]);
        let r = &readings[o.reading];
        let p = mount
            .scanner_at(r.servo_deg_through(&mount))
            .point(r.range_mm, r.alpha_rad);
        let (basis, _) = frame.bend_basis(&p);
        let bend: f64 = (0..3).map(|j| v[3 + j] * basis[j]).sum();
        let st = &mut stats[o.plane];
        st.0 += 1;
        st.1 += e * e;
        if bend.abs() > st.2.abs() {
            st.2 = bend;
        }
    }
    let planes = (flat.iter().zip(&stats))
        .map(|(&(n, d), &(c, ss, bend))| {
            let (n, d, bend) = if d < 0.0 {
                (-n, -d, -bend)
            } else {
                (n, d, bend)
            };
            RoomPlane {
                normal: n,
                offset_mm: d,
                beams: c,
                rms_mm: (ss / c.max(1) as f64).sqrt(),
                bend_mm: bend,
            }
        })
        .collect();
    let kept = s.kept.iter().filter(|k| **k).count();
    RoomMount {
        mount,
        parameters,
        covariance,
        planes,
        sigma0: s.sigma0,
        redundancy: s.redundancy,
        beams: kept,
        rejected: obs.len() - kept,
        rounds: 0,
        wall_searches: 1,
        sweep: Sweep {
            min_deg: -180.0,
            max_deg: 180.0,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{LrfScene, SimulatedLrf};
    use pingcal_geometry::consensus::rng;
    use rand::Rng;

    fn random_case(g: &mut impl Rng) -> (BeamReading, MountModel) {
        let mount = crate::sensor::tests::random_mount(g);
        let reading = BeamReading {
            servo_deg: g.random_range(-180.0..180.0),
            alpha_rad: g.random_range(-2.0f64..2.0),
            range_mm: g.random_range(500.0..4000.0),
            servo_rate_deg_s: g.random_range(-60.0..60.0),
        };
        (reading, mount)
    }

    /// The mount of parameters `t`, servo zero `z` and servo time offset `tau`.
    fn with(t: &[f64; 8], z: f64, tau: f64) -> MountModel {
        MountModel {
            servo_time_offset_s: tau,
            ..MountModel::from_params(t, z)
        }
    }

    fn central(h: f64, f: impl Fn(f64) -> f64) -> f64 {
        (f(h) - f(-h)) / (2.0 * h)
    }

    /// The point's and the ray's derivatives, and the plane residual's, against central
    /// differences.
    #[test]
    fn jacobians_match_central_differences() {
        let mut g = rng(5);
        let steps = [1e-3, 1e-3, 1e-3, 1e-6, 1e-6, 1e-6, 1e-3, 1e-6];
        for _ in 0..100 {
            let (reading, mount) = random_case(&mut g);
            let th = mount.to_params();
            let (z, tau) = (mount.servo_zero_deg, mount.servo_time_offset_s);
            let bp = beam_point(&reading, &mount);
            // the point is the cloud's
            let pose = mount.scanner_at(reading.servo_deg_through(&mount));
            assert!((bp.point - pose.point(reading.range_mm, reading.alpha_rad)).norm() < 1e-9);
            for k in 0..8 {
                let at = |s: f64| {
                    let mut t = th;
                    t[k] += s;
                    let b = beam_point(&reading, &with(&t, z, tau));
                    [b.point, b.origin, b.dir]
                };
                let (hi, lo) = (at(steps[k]), at(-steps[k]));
                let want = [bp.d_mount[k], bp.d_origin[k], bp.d_dir[k]];
                for q in 0..3 {
                    let num = (hi[q] - lo[q]) / (2.0 * steps[k]);
                    let err = (num - want[q]).norm();
                    assert!(
                        err <= 1e-6 * (1.0 + num.norm()),
                        "mount {k} part {q}: {num} vs {}",
                        want[q]
                    );
                }
            }
            // the servo time offset (1e-5 s: up to 6e-4° of servo)
            let at = |s: f64| {
                let b = beam_point(&reading, &with(&th, z, tau + s));
                (b.origin, b.dir)
            };
            let ((oh, dh), (ol, dl)) = (at(1e-5), at(-1e-5));
            let (num_o, num_d) = ((oh - ol) / 2e-5, (dh - dl) / 2e-5);
            let (want_o, want_d) = bp.d_time_offset;
            assert!((num_o - want_o).norm() <= 1e-6 * (1.0 + num_o.norm()));
            assert!((num_d - want_d).norm() <= 1e-6 * (1.0 + num_d.norm()));
            let n = V3::new(g.random_range(-1.0..1.0), g.random_range(-1.0..1.0), 0.7).normalize();
            let frame = PlaneFrame::new(n, bp.point + V3::new(300.0, -200.0, 100.0), 900.0);
            let plane = [
                g.random_range(-0.1..0.1),
                g.random_range(-0.1..0.1),
                n.dot(&bp.point) + g.random_range(-50.0..50.0),
                g.random_range(-3.0..3.0),
                g.random_range(-3.0..3.0),
                g.random_range(-3.0..3.0),
            ];
            let (e, dp, dm, dt) = plane_residual(&reading, z, &frame, &plane, (&th, tau));
            if !e.is_finite() || n.dot(&bp.dir).abs() < 0.2 {
                continue;
            }
            for k in 0..PLANE_UNKNOWNS {
                let h = [1e-6, 1e-6, 1e-3, 1e-3, 1e-3, 1e-3][k];
                let num = central(h, |s| {
                    let mut p = plane;
                    p[k] += s;
                    plane_residual(&reading, z, &frame, &p, (&th, tau)).0
                });
                assert!(
                    (num - dp[k]).abs() <= 1e-5 * (1.0 + num.abs()),
                    "plane {k}: {num} vs {}",
                    dp[k]
                );
            }
            for k in 0..8 {
                let num = central(steps[k], |s| {
                    let mut t = th;
                    t[k] += s;
                    plane_residual(&reading, z, &frame, &plane, (&t, tau)).0
                });
                assert!(
                    (num - dm[k]).abs() <= 1e-5 * (1.0 + num.abs()),
                    "mount {k}: {num} vs {}",
                    dm[k]
                );
            }
            let num = central(1e-5, |s| {
                plane_residual(&reading, z, &frame, &plane, (&th, tau + s)).0
            });
            assert!(
                (num - dt).abs() <= 1e-5 * (1.0 + num.abs()),
                "time offset: {num} vs {dt}"
            );
        }
    }

    /// The bundle-adjustment form against the solver's own central differences.
    #[test]
    fn the_plane_residual_of_a_bundle_has_the_jacobian_of_central_differences() {
        use pingcal_ba::{residual::check_residual_jacobians, Value};
        let mut g = rng(9);
        let mut checked = 0;
        for _ in 0..50 {
            let (reading, mount) = random_case(&mut g);
            let bp = beam_point(&reading, &mount);
            let n = V3::new(0.2, -0.4, 1.0).normalize();
            if n.dot(&bp.dir).abs() < 0.2 {
                continue;
            }
            let r = BeamOnPlane {
                reading,
                sigma: 7.0,
                servo_zero_deg: mount.servo_zero_deg,
                frame: PlaneFrame::new(n, bp.point, 1200.0),
                plane: pingcal_ba::ParameterKey(0),
                mount: pingcal_ba::ParameterKey(1),
                time_offset: Some(pingcal_ba::ParameterKey(2)),
            };
            let plane = vec![0.05, -0.02, n.dot(&bp.point) + 20.0, 1.5, -2.0, 0.7];
            let th = mount.to_params();
            let tau = [mount.servo_time_offset_s];
            let values = [
                Value::Vector(&plane),
                Value::Vector(&th),
                Value::Vector(&tau),
            ];
            let worst = check_residual_jacobians(&r, &values, 1e-6).expect("defined");
            assert!(worst < 1e-5, "worst relative difference {worst:e}");
            checked += 1;
        }
        assert!(checked > 20, "{checked}");
    }

    /// A room of five planes (a corner, the opposite wall and the ceiling) swept by a full
    /// turn through a mount with offsets, tilts and a range offset: every estimated
    /// parameter within 3σ of the truth (and the offsets within 2 mm), offset_y and the
    /// range scale held and named.
    #[test]
    fn the_mount_comes_back_from_a_simulated_room() {
        let (truth, cloud) = five_plane_room();
        let walls =
            crate::ball_finder::find_walls(&cloud, &crate::ball_finder::FinderOptions::default());
        let start = MountModel::default();
        let est = mount_from_room(&cloud, &walls, &start, &RoomOptions::default()).unwrap();
        assert_within_3_sigma(&est, &truth);
        for k in [0, 2, 3, 4, 5, 6] {
            assert!(
                est.parameters[k].sigma.is_some(),
                "{} held: {:?}",
                MOUNT_PARAM_NAMES[k],
                est.parameters[k].held
            );
        }
        assert!(est.parameters[1].held.is_some() && est.parameters[7].held.is_some());
        assert!(
            (est.mount.offset_mm[0] - 10.0).abs() < 2.0
                && (est.mount.offset_mm[2] - 20.0).abs() < 2.0
        );
        assert!(est.planes.len() == 5, "{:?}", est.planes);
        assert_eq!(est.wall_searches, 1);
    }

    /// A wall the finder missed under the start's mount (as a wrong mount's two half-sweeps
    /// can make it): given the walls without it, the plain estimate uses four planes; the
    /// one that searches the walls again through its estimate finds all five and every
    /// parameter within 3σ of the truth.
    #[test]
    fn a_wall_missed_at_the_start_is_found_through_the_estimate() {
        let (truth, cloud) = five_plane_room();
        let finder = crate::ball_finder::FinderOptions::default();
        let walls = crate::ball_finder::find_walls(&cloud, &finder);
        assert_eq!(merge_planes(&walls).len(), 5, "{walls:?}");
        let short: Vec<(V3, f64)> = merge_planes(&walls).into_iter().skip(1).collect();
        let start = MountModel::default();
        let opts = RoomOptions::default();
        let plain = mount_from_room(&cloud, &short, &start, &opts).unwrap();
        assert_eq!(plain.planes.len(), 4);
        let find = |c: &Cloud| crate::ball_finder::find_walls(c, &finder);
        let est = mount_from_room_refinding(&cloud, &short, &start, &opts, find).unwrap();
        assert_eq!(est.planes.len(), 5, "{:?}", est.planes);
        assert_eq!(est.wall_searches, 2);
        assert_within_3_sigma(&est, &truth);
    }

    /// The refusals name what the data lack: a plane given where the room has none (5 m
    /// off, behind a wall) keeps no beam, and the message says so with the counts; a wall search that
    /// refused what it found names each surface and why.
    #[test]
    fn refusals_name_the_planes_and_the_beams_they_lack() {
        let (_, cloud) = five_plane_room();
        let start = MountModel::default();
        let opts = RoomOptions::default();
        let off = [(V3::new(1.0, 0.0, 0.0), 5000.0)];
        let e = mount_from_room(&cloud, &off, &start, &opts)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("1 plane was found in the cloud's")
                && e.contains("none has 100 beams on it through the mount: 0 beams are within 60 mm (or 3σ) of one plane"),
            "{e}"
        );
        let e = mount_from_room(&cloud, &[], &start, &opts)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("no wall, floor or ceiling was found"), "{e}");
        let refused = [
            RefusedPlane {
                points: 900,
                core_fraction: 0.41,
                spread_mm: 800.0,
                min_spread_mm: 50.0,
            },
            RefusedPlane {
                points: 700,
                core_fraction: 0.7,
                spread_mm: 30.0,
                min_spread_mm: 50.0,
            },
        ];
        let w = why_no_walls(20_000, &refused, 0.03);
        assert_eq!(
            w,
            "no wall, floor or ceiling was found in the cloud's 20000 points: 2 flat surfaces were refused: 900 points scattered about it unlike range noise (41 % within 1σ, 55 % needed); 700 points 30 mm across, under the 50 mm a wall needs (a scanner noisier than the noise profile scatters a wall so: give its profile); the mount cannot be found from the room"
        );
        assert!(why_no_walls(5, &[], 0.03).contains("no flat surface holds 3 % of them"));
    }

    fn assert_within_3_sigma(est: &RoomMount, truth: &MountModel) {
        let t = truth.to_params();
        for (k, p) in est.parameters.iter().enumerate() {
            match p.sigma {
                Some(s) => {
                    let z = (p.value - to_unit(k, t[k])) / s;
                    assert!(
                        z.abs() < 3.0,
                        "{}: {} ± {s} against {} (z {z:.2})",
                        p.name,
                        p.value,
                        to_unit(k, t[k])
                    );
                }
                None => assert!(p.held.is_some()),
            }
        }
    }

    /// The five-plane room of the tests swept by a full turn through a mount with offsets,
    /// tilts and a range offset: the true mount and the cloud through the nominal one.
    fn five_plane_room() -> (MountModel, Cloud) {
        let truth = MountModel {
            offset_mm: [10.0, 5.0, 20.0],
            tilt_x_deg: 0.8,
            tilt_z_deg: -0.6,
            servo_zero_deg: 0.0,
            servo_scale: 0.0,
            range_offset_mm: 20.0,
            range_scale: 0.0,
            servo_time_offset_s: 0.0,
        };
        let scene = LrfScene {
            planes: vec![
                (V3::new(1.0, 0.0, 0.0), -1450.0),
                (V3::new(1.0, 0.0, 0.0), 2100.0),
                (V3::new(0.0, 1.0, 0.0), 1800.0),
                (V3::new(0.0, 0.0, 1.0), -900.0),
                (V3::new(0.0, 0.0, 1.0), 1600.0),
            ],
            ..LrfScene::default()
        };
        let mut lrf = SimulatedLrf::default();
        lrf.sensor.mount = truth;
        let servo: Vec<f64> = (0..360).map(|k| -180.0 + k as f64).collect();
        let mut g = rng(21);
        let scans = scene.scan(&servo, &lrf, &mut g);
        let cloud = Cloud::from_scans(
            &crate::scan::ScanHeader::URG_04LX,
            scans.into_iter().map(Ok),
            &MountModel::default(),
        )
        .unwrap();
        (truth, cloud)
    }
}
