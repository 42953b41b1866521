//! One LRF beam against a sphere of known radius: the observation the joint adjustment
//! adds for every beam that hit a ball.
//!
//! For a reading (servo angle `s`, beam angle α, reported range `r`) through the mount
//! θ ([`MountModel::to_params`]) the beam starts at `o = R_β · offset` and points along
//! `d = R_β R_x(tilt_x) R_z(tilt_z) (cos α, sin α, 0)`, `β = (s − servo_zero)(1 + servo_scale)`
//! ([`crate::sensor`]). With `q = c − o`, `t = d·q` and `h² = |q|² − t²` (the ray's distance
//! from the centre `c`, squared), it meets the sphere of radius ρ first at
//! `r_pred = t − √(ρ² − h²)`, and the sensor should report `r̂ = r_pred (1 + range_scale) +
//! range_offset`. The residual is `e = r − r̂` (mm, not whitened: the caller divides by the
//! sensor's σ(r)).
//!
//! **Grazing beams.** Where the ray passes the centre at more than `√(1 − κ²) ρ` (κ =
//! [`GRAZING_KAPPA`], or misses the sphere), the root is clamped at κρ: the function stays
//! continuous, its Jacobian is that of the clamped function, and [`BeamResidual::grazing`]
//! says so, so that callers can leave such beams out (their range is a footprint effect).
//!
//! **Beams at the silhouette.** A beam is not a line but a footprint of half-width
//! `w = a + b·r` ([`crate::sphere_fit::FitOptions::beam_half_width`]); where the ray passes
//! within `w` of the silhouette (`ρ − h < w`, [`BeamResidual::margin_mm`]), part of the
//! footprint lies on the background and the reading mixes the two (a mixed pixel: longer
//! than the sphere's range by a fraction of the gap behind the ball). Such beams are biased
//! the same way at every ball, by up to a few σ each, so a residual test does not remove
//! them; [`BeamOnBall::at_silhouette`] names them, and callers leave them out as the sphere
//! fits do.
//!
//! **Jacobians**, with `g_q = ∂r_pred/∂q = d + (q − t d)/√(ρ² − h²)` and
//! `g_d = ∂r_pred/∂d = q − t q/√(ρ² − h²)` (the second terms vanish when clamped):
//! `∂e/∂c = −(1 + range_scale) g_q`; for an offset component `∂o = R_β e_j`, for a tilt or
//! the servo scale `∂d` (and `∂o`) through the derivative of the elementary rotation, and
//! `∂e/∂θ = −(1 + range_scale)(g_d · ∂d − g_q · ∂o)`; `∂e/∂range_offset = −1`,
//! `∂e/∂range_scale = −r_pred`. Checked against central differences in the tests.
//!
//! **A sphere fitted to beams.** [`fit_sphere_to_beams`] fits the centre of a ball of known
//! radius to its beams through a given mount, on these residuals weighted by the sensor's
//! σ(r), leaving out the grazing beams and those at the silhouette: how the joint adjustment
//! measures its check balls' LRF side through the mount it estimated.
//!
//! **Servo timing.** In a continuous sweep the reading's servo angle is taken at
//! `s + ṡ τ` ([`BeamReading::servo_deg_through`]: `ṡ` the servo's rate at the beam, τ the
//! servo time offset), so `∂e/∂τ = ṡ ∂e/∂s` with `∂β/∂s = (1 + servo_scale)` (in radians per
//! degree): the same derivative of `R_β` as the servo scale's, per second.

use crate::cloud::BeamReading;
use crate::sensor::{servo_rotation, MountModel, RangeNoise};
use crate::sphere_fit::FitOptions;
use nalgebra::{Matrix3, Vector3};
use pingcal_geometry::least_squares::{minimize, Normal, Options, Strategy};

/// The clamp of grazing beams: the root `√(ρ² − h²)` is held at least κρ.
pub const GRAZING_KAPPA: f64 = 0.3;

/// A beam's residual against a sphere and its Jacobians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamResidual {
    /// `e = reported − predicted` range, mm.
    pub e: f64,
    /// `∂e/∂c`.
    pub d_centre: [f64; 3],
    /// `∂e/∂θ` in the order of [`MountModel::to_params`] (tilts per radian).
    pub d_mount: [f64; 8],
    /// `∂e/∂τ`, τ the servo time offset ([`MountModel::servo_time_offset_s`]; per second):
    /// the servo rate times `∂e/∂servo`. Zero in a stop-and-go sweep.
    pub d_time_offset: f64,
    /// The ray grazes (or misses) the sphere: the root was clamped.
    pub grazing: bool,
    /// How far inside the silhouette the ray passes, `ρ − h` (mm; negative: it misses).
    pub margin_mm: f64,
}

impl BeamResidual {
    /// The beam grazes the sphere or passes within `half_width_mm` (its footprint's
    /// half-width) of its silhouette: a mixed pixel, left out of sphere fits (as is a beam
    /// whose margin is not a number).
    pub fn at_silhouette(&self, half_width_mm: f64) -> bool {
        self.grazing || !(self.margin_mm >= half_width_mm)
    }
}

/// Derivative of [`servo_rotation`] with respect to β.
pub(crate) fn servo_rotation_dot(beta: f64) -> Matrix3<f64> {
    let (s, c) = beta.sin_cos();
    Matrix3::new(-s, 0.0, -c, 0.0, 0.0, 0.0, c, 0.0, -s)
}

/// The rotation about X by `a` (radians) and its derivative.
pub(crate) fn rot_x(a: f64) -> (Matrix3<f64>, Matrix3<f64>) {
    let (s, c) = a.sin_cos();
    (
        Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s),
    )
}

/// The rotation about Z by `a` (radians) and its derivative.
pub(crate) fn rot_z(a: f64) -> (Matrix3<f64>, Matrix3<f64>) {
    let (s, c) = a.sin_cos();
    (
        Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
        Matrix3::new(-s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0),
    )
}

/// The residual of `reading` against the sphere of `radius` centred at `centre` (LRF
/// frame, mm), through `mount` (see the module doc).
pub fn beam_range_residual(
    reading: &BeamReading,
    mount: &MountModel,
    centre: &Vector3<f64>,
    radius: f64,
) -> BeamResidual {
    let [ox, oy, oz, tilt_x, tilt_z, servo_scale, range_offset, range_scale] = mount.to_params();
    let servo_deg = reading.servo_deg_through(mount);
    let dbeta_dk = (servo_deg - mount.servo_zero_deg).to_radians();
    // ∂β/∂τ: the rate (degrees per second) through β's scale
    let dbeta_dtau = (reading.servo_rate_deg_s * (1.0 + servo_scale)).to_radians();
    let beta = mount.beta(servo_deg);
    let (rb, rb_dot) = (servo_rotation(beta), servo_rotation_dot(beta));
    let (rx, rx_dot) = rot_x(tilt_x);
    let (rz, rz_dot) = rot_z(tilt_z);
    let (sa, ca) = reading.alpha_rad.sin_cos();
    let l = Vector3::new(ca, sa, 0.0);
    let off = Vector3::new(ox, oy, oz);
    let d = rb * (rx * (rz * l));
    let o = rb * off;
    let q = centre - o;
    let t = d.dot(&q);
    // |q|² − t² cancels catastrophically at 1 m; the perpendicular part does not
    let perp = q - d * t;
    let h2 = perp.norm_squared();
    let floor = (GRAZING_KAPPA * radius).powi(2);
    let u = radius * radius - h2;
    let grazing = u < floor;
    let root = u.max(floor).sqrt();
    let r_pred = t - root;
    let (g_q, g_d) = if grazing {
        (d, q)
    } else {
        (d + perp / root, q - q * (t / root))
    };
    let gain = 1.0 + range_scale;
    let e = reading.range_mm - (r_pred * gain + range_offset);
    let d_centre = (-gain * g_q).into();
    let along = |dd: Vector3<f64>, doo: Vector3<f64>| -gain * (g_d.dot(&dd) - g_q.dot(&doo));
    let z = Vector3::zeros();
    let mut d_mount = [0.0; 8];
    for (j, dm) in d_mount.iter_mut().enumerate().take(3) {
        *dm = along(z, rb.column(j).into_owned());
    }
    d_mount[3] = along(rb * (rx_dot * (rz * l)), z);
    d_mount[4] = along(rb * (rx * (rz_dot * l)), z);
    d_mount[5] = along(rb_dot * (rx * (rz * l)) * dbeta_dk, rb_dot * off * dbeta_dk);
    d_mount[6] = -1.0;
    d_mount[7] = -r_pred;
    let d_time_offset = along(
        rb_dot * (rx * (rz * l)) * dbeta_dtau,
        rb_dot * off * dbeta_dtau,
    );
    BeamResidual {
        e,
        d_centre,
        d_mount,
        d_time_offset,
        grazing,
        margin_mm: radius - h2.sqrt(),
    }
}

/// One beam on a ball as an observation of a bundle adjustment
/// ([`pingcal_ba::Residual`]): the ball's centre `X` in the photogrammetric frame (a point of
/// the bundle), the extrinsic `camera_from_lrf` (a pose parameter block, left-perturbed like
/// the image poses) and the mount θ (a vector parameter block in [`MountModel::to_params`]
/// order). With `c = camera_from_lrf⁻¹ · X = Rᵀ (X − t)` and `e` of [`beam_range_residual`],
/// the residual is `e / σ`. With `g = R ∂e/∂c` and `v = X − t`: `∂e/∂X = gᵀ`;
/// `c(δ) = Rᵀ exp(−[δω]×)(v − δt)` gives `∂e/∂δω = ([v]×ᵀ g)ᵀ` and `∂e/∂δt = −gᵀ`;
/// and `∂e/∂θ` as [`BeamResidual::d_mount`]. Each divided by σ.
#[derive(Clone, Debug)]
pub struct BeamOnBall {
    /// The reading.
    pub reading: BeamReading,
    /// The balls' radius (mm).
    pub radius: f64,
    /// The sensor's σ of this range (mm).
    pub sigma: f64,
    /// The servo's zero of the LRF frame (degrees; not an unknown).
    pub servo_zero_deg: f64,
    /// The ball: a point of the problem.
    pub ball: pingcal_ba::PointKey,
    /// The extrinsic: a pose parameter block of the problem.
    pub extrinsic: pingcal_ba::ParameterKey,
    /// The mount: a vector parameter block of 8.
    pub mount: pingcal_ba::ParameterKey,
    /// The servo time offset τ ([`MountModel::servo_time_offset_s`]): a vector parameter
    /// block of 1, or None where the sweep has none (τ = 0).
    pub time_offset: Option<pingcal_ba::ParameterKey>,
    /// Half-width of the beam's footprint at its range (mm): a beam that passes closer than
    /// this to the silhouette is a mixed pixel ([`BeamOnBall::at_silhouette`]).
    pub half_width_mm: f64,
}

impl BeamOnBall {
    /// `e` (mm, not whitened), the residual's parts and `g = R ∂e/∂c`, at these values
    /// (`tau`: the servo time offset, seconds).
    fn at(
        &self,
        x: &Vector3<f64>,
        pose: &pingcal_geometry::Rigid3,
        theta: &[f64],
        tau: f64,
    ) -> Option<(BeamResidual, Vector3<f64>, Vector3<f64>)> {
        let th: [f64; 8] = theta.try_into().ok()?;
        let mount = MountModel {
            servo_time_offset_s: tau,
            ..MountModel::from_params(&th, self.servo_zero_deg)
        };
        let v = x - pose.translation;
        let c = pose.rotation.transpose() * v;
        let r = beam_range_residual(&self.reading, &mount, &c, self.radius);
        let g = pose.rotation * Vector3::from(r.d_centre);
        r.e.is_finite().then_some((r, g, v))
    }

    /// `e` (reported − predicted range, mm) at these values; None where undefined.
    pub fn range_error(
        &self,
        x: &Vector3<f64>,
        pose: &pingcal_geometry::Rigid3,
        theta: &[f64],
        tau: f64,
    ) -> Option<f64> {
        self.at(x, pose, theta, tau).map(|(r, _, _)| r.e)
    }

    /// Whether the beam grazes the ball at these values (see [`GRAZING_KAPPA`]).
    pub fn grazing(
        &self,
        x: &Vector3<f64>,
        pose: &pingcal_geometry::Rigid3,
        theta: &[f64],
        tau: f64,
    ) -> bool {
        self.at(x, pose, theta, tau)
            .is_none_or(|(r, _, _)| r.grazing)
    }

    /// Whether the beam's footprint reaches the ball's silhouette at these values (the ray
    /// passes within `half_width_mm` of it, or misses): its range mixes ball and background.
    /// Every grazing beam is also at the silhouette when the half-width is at least
    /// `(1 − √(1 − κ²)) ρ`.
    pub fn at_silhouette(
        &self,
        x: &Vector3<f64>,
        pose: &pingcal_geometry::Rigid3,
        theta: &[f64],
        tau: f64,
    ) -> bool {
        self.at(x, pose, theta, tau)
            .is_none_or(|(r, _, _)| r.at_silhouette(self.half_width_mm))
    }
}

impl pingcal_ba::Residual for BeamOnBall {
    fn dim(&self) -> usize {
        1
    }

    fn blocks(&self) -> Vec<pingcal_ba::Block> {
        use pingcal_ba::Block;
        let mut blocks = vec![
            Block::Point(self.ball),
            Block::Parameter(self.extrinsic),
            Block::Parameter(self.mount),
        ];
        blocks.extend(self.time_offset.map(Block::Parameter));
        blocks
    }

    fn evaluate(
        &self,
        values: &[pingcal_ba::Value],
        residual: &mut [f64],
        jacobians: pingcal_ba::Jacobians<'_>,
    ) -> bool {
        let (Some(x), Some(pose), Some(theta)) =
            (values[0].point(), values[1].pose(), values[2].vector())
        else {
            return false;
        };
        let tau = match self.time_offset {
            Some(_) => match values.get(3).and_then(|v| v.vector()) {
                Some(&[tau]) => tau,
                _ => return false,
            },
            None => 0.0,
        };
        let Some((r, g, v)) = self.at(x, pose, theta, tau) else {
            return false;
        };
        let s = self.sigma;
        residual[0] = r.e / s;
        if let Some(j) = jacobians {
            let jw = pingcal_geometry::skew(&v).transpose() * g;
            for k in 0..3 {
                j[0][(0, k)] = g[k] / s;
                j[1][(0, k)] = jw[k] / s;
                j[1][(0, 3 + k)] = -g[k] / s;
            }
            for k in 0..8 {
                j[2][(0, k)] = r.d_mount[k] / s;
            }
            if self.time_offset.is_some() {
                j[3][(0, 0)] = r.d_time_offset / s;
            }
        }
        true
    }

    fn group(&self) -> &str {
        "beams"
    }
}

/// The centre of a sphere of `radius` fitted to `readings` through `mount` (Gauss–Newton on
/// the beam-range residuals from `start`), with its covariance (scaled by σ0² when σ0 > 1).
/// Grazing beams and beams at the silhouette are left out: the set is chosen at the start,
/// the fit converged on it, and the set chosen again at the solution until it no longer
/// changes (at most [`REFIT_ROUNDS`] times). Choosing it at every step instead let the
/// mixed pixels just inside the gate, many mm long, push the centre about and in and out
/// of the set. None when fewer than four beams are left, the normal matrix is singular or
/// the centre is not finite.
pub fn fit_sphere_to_beams(
    readings: &[BeamReading],
    mount: &MountModel,
    radius: f64,
    start: &Vector3<f64>,
    noise: &RangeNoise,
) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    // the ball finder's footprint: beams at the silhouette are left out as the sphere fits
    // and the joint adjustment leave them out
    let fit = FitOptions::default();
    let chosen = |c: &Vector3<f64>| -> Vec<BeamReading> {
        (readings.iter())
            .filter(|r| {
                !beam_range_residual(r, mount, c, radius)
                    .at_silhouette(fit.beam_half_width(r.range_mm))
            })
            .copied()
            .collect()
    };
    let mut set = chosen(start);
    let mut c = *start;
    for _ in 0..REFIT_ROUNDS {
        let solved = fit_on(&set, c, (mount, radius, noise))?;
        c = solved.0;
        let again = chosen(&c);
        if again == set {
            return Some(solved);
        }
        set = again;
    }
    fit_on(&set, c, (mount, radius, noise))
}

/// Rounds of choosing the beams of [`fit_sphere_to_beams`].
pub const REFIT_ROUNDS: usize = 5;

/// [`fit_sphere_to_beams`] on a fixed set of beams, from `start`: Gauss–Newton on the
/// ranges weighted by their σ (at most 20 steps, until one is under 1e-6 mm); the covariance
/// from the normal matrix of the last step, scaled by σ₀² when σ₀ > 1. `None` with fewer
/// than 4 beams, a singular normal matrix or a centre that is not finite.
fn fit_on(
    readings: &[BeamReading],
    start: Vector3<f64>,
    (mount, radius, noise): (&MountModel, f64, &RangeNoise),
) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    let n = readings.len();
    if n < 4 {
        return None;
    }
    let mut normal = |c: &Vector3<f64>| {
        let (mut h, mut g, mut chi2) = (Matrix3::zeros(), Vector3::zeros(), 0.0);
        for r in readings {
            let b = beam_range_residual(r, mount, c, radius);
            let s = noise.sigma(r.range_mm).max(1e-3);
            let j = Vector3::from(b.d_centre) / s;
            h += j * j.transpose();
            g += j * (b.e / s);
            chi2 += (b.e / s).powi(2);
        }
        Some(Normal {
            matrix: h,
            gradient: g,
            cost: chi2,
        })
    };
    let options = Options {
        strategy: Strategy::GaussNewton,
        max_iterations: 20,
        small_step: |s| s.length < 1e-6,
        cost_tolerance: 0.0,
    };
    let solved = minimize(start, &options, &mut normal)?;
    let s0 = (solved.normal.cost / (n as f64 - 3.0).max(1.0)).sqrt();
    Some((
        solved.x,
        solved.normal.matrix.try_inverse()? * s0.max(1.0).powi(2),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{room_corner_scene, Footprint, SimulatedLrf};
    use pingcal_ba::{ParameterKey, PointKey};
    use pingcal_geometry::consensus::rng;
    use rand::Rng;

    fn random_case(g: &mut impl Rng) -> (BeamReading, MountModel, Vector3<f64>) {
        let mount = crate::sensor::tests::random_mount(g);
        let reading = BeamReading {
            servo_deg: g.random_range(-80.0..80.0),
            alpha_rad: g.random_range(-1.5f64..1.5),
            range_mm: g.random_range(800.0..2000.0),
            servo_rate_deg_s: g.random_range(-60.0..60.0),
        };
        // a centre near the beam, inside the non-grazing zone
        let pose = mount.scanner_at(reading.servo_deg_through(&mount));
        let dir = pose.direction(reading.alpha_rad, 0.0);
        let side = dir.cross(&Vector3::new(0.3, 1.0, -0.2)).normalize();
        let c = pose.origin() + dir * (reading.range_mm + 5.0) + side * g.random_range(0.0..10.0);
        (reading, mount, c)
    }

    /// The five-point central difference (error O(h⁴)): the root's high derivatives in the
    /// ray's distance from the centre make the three-point one too coarse at 1e-6.
    fn five_point(h: f64, f: impl Fn(f64) -> f64) -> f64 {
        (f(-2.0 * h) - 8.0 * f(-h) + 8.0 * f(h) - f(2.0 * h)) / (12.0 * h)
    }

    fn residual_at(
        reading: &BeamReading,
        (th, tau): (&[f64; 8], f64),
        zero: f64,
        c: &Vector3<f64>,
    ) -> f64 {
        let mount = MountModel {
            servo_time_offset_s: tau,
            ..MountModel::from_params(th, zero)
        };
        beam_range_residual(reading, &mount, c, 20.0).e
    }

    /// Every analytic derivative against central differences (relative 1e-6).
    #[test]
    fn jacobians_match_central_differences() {
        let mut g = rng(7);
        let mut checked = 0;
        for _ in 0..200 {
            let (reading, mount, c) = random_case(&mut g);
            let b = beam_range_residual(&reading, &mount, &c, 20.0);
            if b.grazing {
                continue;
            }
            checked += 1;
            let th = mount.to_params();
            let (z, tau) = (mount.servo_zero_deg, mount.servo_time_offset_s);
            for k in 0..3 {
                let num = five_point(1e-2, |h| {
                    let mut cp = c;
                    cp[k] += h;
                    residual_at(&reading, (&th, tau), z, &cp)
                });
                assert!(
                    (num - b.d_centre[k]).abs() <= 1e-6 * (1.0 + num.abs()),
                    "centre {k}: {num} vs {}",
                    b.d_centre[k]
                );
            }
            for k in 0..8 {
                // steps that move the ray by about 1e-2 mm at 1 m (e carries ~1e-10 mm of
                // rounding noise, the five-point truncation is far below)
                let step = [1e-2, 1e-2, 1e-2, 1e-5, 1e-5, 1e-5, 1e-2, 1e-5][k];
                let num = five_point(step, |h| {
                    let mut tp = th;
                    tp[k] += h;
                    residual_at(&reading, (&tp, tau), z, &c)
                });
                let scale = 1.0 + num.abs().max(b.d_mount[k].abs());
                assert!(
                    (num - b.d_mount[k]).abs() <= 1e-6 * scale,
                    "mount {k}: {num} vs {}",
                    b.d_mount[k]
                );
            }
            // the servo time offset: 1e-5 s moves the servo by up to 6e-4° here
            let num = five_point(1e-5, |h| residual_at(&reading, (&th, tau + h), z, &c));
            let scale = 1.0 + num.abs().max(b.d_time_offset.abs());
            assert!(
                (num - b.d_time_offset).abs() <= 1e-6 * scale,
                "time offset: {num} vs {}",
                b.d_time_offset
            );
        }
        assert!(checked > 100, "{checked}");
    }

    /// The bundle-adjustment form of a beam (ball centre in the camera frame, the extrinsic
    /// and the mount as blocks) against central differences through the solver's updates.
    #[test]
    fn the_beam_as_a_bundle_residual_has_the_jacobian_of_central_differences() {
        use pingcal_ba::{residual::check_residual_jacobians, Value};
        let mut g = rng(11);
        let mut checked = 0;
        for _ in 0..100 {
            let (reading, mount, c) = random_case(&mut g);
            if beam_range_residual(&reading, &mount, &c, 20.0).grazing {
                continue;
            }
            let camera_from_lrf = pingcal_geometry::Rigid3::new(
                pingcal_geometry::from_opk_deg([
                    g.random_range(-180.0..180.0),
                    g.random_range(-80.0..80.0),
                    g.random_range(-180.0..180.0),
                ]),
                Vector3::new(
                    g.random_range(-300.0..300.0),
                    g.random_range(-300.0..300.0),
                    g.random_range(-300.0..300.0),
                ),
            );
            let x = camera_from_lrf.transform(&c);
            let beam = BeamOnBall {
                reading,
                radius: 20.0,
                sigma: 10.0,
                servo_zero_deg: mount.servo_zero_deg,
                ball: PointKey(0),
                extrinsic: ParameterKey(0),
                mount: ParameterKey(1),
                time_offset: Some(ParameterKey(2)),
                half_width_mm: 3.0,
            };
            let th = mount.to_params();
            let tau = [mount.servo_time_offset_s];
            let values = [
                Value::Point(&x),
                Value::Pose(&camera_from_lrf),
                Value::Vector(&th),
                Value::Vector(&tau),
            ];
            let worst = check_residual_jacobians(&beam, &values, 1e-6).expect("defined");
            assert!(worst < 1e-6, "worst relative difference {worst:e}");
            checked += 1;
        }
        assert!(checked > 50, "{checked}");
    }

    /// An exact reading of a sphere, made through the same mount, has no residual; through
    /// another mount it has.
    #[test]
    fn an_exact_reading_has_no_residual() {
        let mut g = rng(3);
        for _ in 0..50 {
            let (mut reading, mount, c) = random_case(&mut g);
            let pose = mount.scanner_at(reading.servo_deg_through(&mount));
            let (o, d) = (pose.origin(), pose.direction(reading.alpha_rad, 0.0));
            let q = c - o;
            let t = d.dot(&q);
            let u = 400.0 - (q.norm_squared() - t * t);
            if u < (GRAZING_KAPPA * 20.0).powi(2) {
                continue;
            }
            reading.range_mm = mount.reported_range(t - u.sqrt());
            let b = beam_range_residual(&reading, &mount, &c, 20.0);
            assert!(b.e.abs() < 1e-9 && !b.grazing, "{}", b.e);
            // and the cloud puts the point on the sphere
            let p = pose.point(reading.range_mm, reading.alpha_rad);
            assert!(((p - c).norm() - 20.0).abs() < 1e-9);
            let other = MountModel {
                range_offset_mm: mount.range_offset_mm + 5.0,
                ..mount
            };
            assert!((beam_range_residual(&reading, &other, &c, 20.0).e + 5.0).abs() < 1e-9);
        }
    }

    /// Across the clamp the residual is continuous, and a miss is grazing.
    #[test]
    fn the_clamp_is_continuous() {
        let mount = MountModel::default();
        let reading = BeamReading::at_rest(0.0, 0.0, 1000.0);
        let h_edge = 20.0 * (1.0 - GRAZING_KAPPA * GRAZING_KAPPA).sqrt();
        let at =
            |h: f64| beam_range_residual(&reading, &mount, &Vector3::new(1000.0, h, 0.0), 20.0);
        let (a, b) = (at(h_edge - 1e-9), at(h_edge + 1e-9));
        assert!(!a.grazing && b.grazing);
        assert!((a.e - b.e).abs() < 1e-6, "{} {}", a.e, b.e);
        assert!(at(30.0).grazing && at(30.0).e.is_finite());
    }

    /// The beams at a ball's silhouette are the mixed pixels: on noiseless scans of a room
    /// corner whose balls' edges blend with the background over the beam's footprint
    /// (`simulate`, the sphere fits' footprint), every beam `at_silhouette` leaves in reads
    /// the sphere's range exactly, and some that the grazing test alone kept read many mm
    /// long.
    #[test]
    fn the_beams_at_a_silhouette_are_the_mixed_pixels() {
        use crate::simulate::{room_corner_scene, SimulatedLrf};
        use crate::sphere_fit::FitOptions;
        let mut g = rng(11);
        let scene = room_corner_scene(6, &mut g);
        let lrf = SimulatedLrf {
            footprint: SimulatedLrf::default().footprint,
            ..SimulatedLrf::noiseless()
        };
        let lines = scene.half_sweep(400, &lrf, &mut g);
        let fit = FitOptions::default();
        let identity = pingcal_geometry::Rigid3::identity();
        let theta = MountModel::default().to_params();
        let (mut clear, mut worst_clear, mut worst_kept) = (0, 0.0f64, 0.0f64);
        for line in &lines {
            for (i, &range_mm) in line.ranges_mm.iter().enumerate() {
                if range_mm <= 0.0 {
                    continue;
                }
                let reading =
                    BeamReading::at_rest(line.servo_deg, lrf.sensor.beam_angle(i), range_mm);
                for c in &scene.balls {
                    let beam = BeamOnBall {
                        reading,
                        radius: scene.radius,
                        sigma: 10.0,
                        servo_zero_deg: 0.0,
                        ball: PointKey(0),
                        extrinsic: ParameterKey(0),
                        mount: ParameterKey(1),
                        time_offset: None,
                        half_width_mm: fit.beam_half_width(range_mm),
                    };
                    let Some(e) = beam.range_error(c, &identity, &theta, 0.0) else {
                        continue;
                    };
                    // a beam of this ball (not one of another object in front of it)
                    if e.abs() > 200.0 || beam.grazing(c, &identity, &theta, 0.0) {
                        continue;
                    }
                    if beam.at_silhouette(c, &identity, &theta, 0.0) {
                        worst_kept = worst_kept.max(e.abs());
                    } else {
                        clear += 1;
                        worst_clear = worst_clear.max(e.abs());
                    }
                }
            }
        }
        assert!(clear > 100, "{clear} beams on the balls");
        assert!(
            worst_clear < 1e-6,
            "a beam clear of the silhouette is {worst_clear} mm off"
        );
        assert!(
            worst_kept > 5.0,
            "no mixed pixel the grazing test keeps: {worst_kept} mm"
        );
    }

    /// A check ball's sphere, fitted again to its beams, lands on the ball on noiseless
    /// scans whose balls' edges blend with the background (mixed pixels over the beam's
    /// footprint): the beams at the silhouette are left out. With the grazing test alone
    /// the first ball's centre came out 2.6 mm off.
    #[test]
    fn a_sphere_fitted_to_beams_is_not_pulled_by_mixed_pixels() {
        let mut g = rng(5);
        let scene = room_corner_scene(6, &mut g);
        // mixed pixels over two thirds of the fit's footprint (pingcal-sim's outer sub-rays
        // lie at two thirds of its beam's half-width): a start a fraction of a millimetre
        // off still chooses only clean beams
        let gate = FitOptions::default();
        let lrf = SimulatedLrf {
            footprint: Some(Footprint {
                a_mm: gate.beam_width_a_mm * 2.0 / 3.0,
                b: gate.beam_width_b * 2.0 / 3.0,
            }),
            ..SimulatedLrf::noiseless()
        };
        let lines = scene.half_sweep(1500, &lrf, &mut g);
        // the weights of the URG-04LX (the ranges are exact)
        let noise = crate::sensor::LrfSensor::urg_04lx().noise;
        let mount = MountModel::default();
        for c in &scene.balls {
            let readings: Vec<BeamReading> = (lines.iter())
                .flat_map(|l| {
                    (l.ranges_mm.iter().enumerate()).map(|(i, &range_mm)| {
                        BeamReading::at_rest(l.servo_deg, lrf.sensor.beam_angle(i), range_mm)
                    })
                })
                .filter(|r| r.range_mm > 0.0)
                .filter(|r| {
                    let b = beam_range_residual(r, &mount, c, scene.radius);
                    b.margin_mm > -10.0 && b.e.abs() < 200.0
                })
                .collect();
            let start = c + Vector3::new(0.4, -0.4, 0.4);
            let clear = (readings.iter())
                .filter(|r| {
                    !beam_range_residual(r, &mount, c, scene.radius)
                        .at_silhouette(gate.beam_half_width(r.range_mm))
                })
                .count();
            let Some((fit, _)) =
                fit_sphere_to_beams(&readings, &mount, scene.radius, &start, &noise)
            else {
                panic!(
                    "no sphere: {} beams, {clear} clear of the silhouette",
                    readings.len()
                );
            };
            let error = (fit - c).norm();
            assert!(
                error < 1e-3,
                "centre {error} mm off ({} beams)",
                readings.len()
            );
        }
    }
}
