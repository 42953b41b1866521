//! A fixed 2D LRF: a scanner bolted to the camera head, its scans taken at stations of the
//! head whose images orient it in the field, and its beams as observations of a bundle
//! adjustment.
//!
//! **Geometry.** A beam of angle α and range r lies in the scan plane, the LRF frame's XY
//! plane (the rotating LRF's at β = 0: `x = r cos α, y = r sin α, z = 0`). At a station whose
//! main image has the pose `P = camera_from_object` (the bundle's image pose, object = the
//! photogrammetric frame), the LRF with the extrinsic `E = camera_from_lrf` casts the ray
//!
//! ```text
//! o = R_Pᵀ (t_E − t_P),   u = R_Pᵀ R_E (cos α, sin α, 0)
//! ```
//!
//! in the object frame. The range the model predicts, `r̂`, is where the ray meets the
//! surface the beam is on: a wall, floor or ceiling, `n·x = d + b(x)`, or a ball's sphere of
//! radius R about `c` (the near root of `|o + r̂u − c| = R`). No wall is flat to the
//! millimetre, so a plane bends smoothly, as the rotating LRF's room planes do
//! ([`crate::room`]) and with the terms of a panel held at its edges besides: `b = Σ c_j
//! β_j(ũ, ṽ)` over [`bend_basis`] in its frame's coordinates, each coefficient under a prior
//! of [`crate::room::FLATNESS_MM`], fixed mostly by the targets on it; the ray meets
//! it at `r̂ = t₀ + b(h)/s` (first order in b), `t₀ = (d − n·o)/s`, `s = n·u`, `h = o + t₀u`.
//! A target on the plane has the misfit `n·X − d − b(X)`. The range model is
//! `r = (1 + s)·r̂ + k` (range offset k, scale s, the rotating LRF's last two mount
//! parameters), so the residual is `e = r − (1 + s)·r̂ − k`, whitened by the sensor's σ(r).
//!
//! **Blocks.** The station's image pose ([`pingcal_ba::Block::Pose`] of its main image), the
//! extrinsic (a pose parameter block), the range model (a vector block `[k, s]`) and the
//! surface: a plane (a vector block of [`FIXED_PLANE_UNKNOWNS`] about a [`PlaneFrame`]: the
//! local turn `(a, b)` of its normal, its offset `d` and its bend) or a ball's centre ([`pingcal_ba::Block::Point`]). Both poses take the solver's left update
//! (`R ← exp([δω]×)R, t ← t + δt`); the Jacobians are analytic and checked by central
//! differences in the tests.

use crate::beam::GRAZING_KAPPA;
use crate::room::PlaneFrame;
use nalgebra::{Matrix3, Vector3};
use pingcal_ba::{Block, Jacobians, ParameterKey, PointKey, Residual, Value};
use pingcal_geometry::{skew, Rigid3};

type V3 = Vector3<f64>;

/// The variance-component group of the beams on the field's planes.
pub const FIXED_PLANE_GROUP: &str = "LRF beams on planes";
/// The variance-component group of the beams on the balls.
pub const FIXED_BALL_GROUP: &str = "LRF beams on balls";

/// Terms of a fixed LRF's plane's bend: `ũ², ṽ², ũṽ, ũ²ṽ, ũṽ², ũ²ṽ²` ([`bend_basis`]).
pub const BEND_TERMS: usize = 6;

/// Unknowns of a plane of a fixed LRF's adjustment: the turn of its normal `(a, b)`, its
/// offset `d` and its [`BEND_TERMS`] bend coefficients (mm) about its [`PlaneFrame`].
pub const FIXED_PLANE_UNKNOWNS: usize = 3 + BEND_TERMS;

/// The bend's basis at `x` in `frame`'s scaled coordinates `ũ, ṽ` and its gradients: the
/// tensor product of `{1, ũ, ũ²}` and `{1, ṽ, ṽ²}` without the plane's own `1, ũ, ṽ`. A
/// panel held at its edges bows between them as `ũ²ṽ²` does; the room planes' quadratic
/// bend alone (`ũ², ṽ², ũṽ`) left a pillow-shaped wall's 3 mm as a 2.5 mm bias in the fixed
/// scanner's height where the beams and the targets see different parts of the wall.
pub fn bend_basis(frame: &PlaneFrame, x: &V3) -> ([f64; BEND_TERMS], [V3; BEND_TERMS]) {
    let d = x - frame.centre;
    let (u, v) = (
        frame.e1.dot(&d) / frame.scale,
        frame.e2.dot(&d) / frame.scale,
    );
    let (gu, gv) = (frame.e1 / frame.scale, frame.e2 / frame.scale);
    (
        [u * u, v * v, u * v, u * u * v, u * v * v, u * u * v * v],
        [
            gu * (2.0 * u),
            gv * (2.0 * v),
            gu * v + gv * u,
            gu * (2.0 * u * v) + gv * (u * u),
            gu * (v * v) + gv * (2.0 * u * v),
            gu * (2.0 * u * v * v) + gv * (2.0 * u * u * v),
        ],
    )
}

/// The bend `b(x)` of a plane of local unknowns `plane` (the bend's coefficients from index
/// 3) about `frame`, with its basis and its gradient `∇b` at `x`.
pub fn bend_at(frame: &PlaneFrame, plane: &[f64], x: &V3) -> (f64, [f64; BEND_TERMS], V3) {
    let (basis, grads) = bend_basis(frame, x);
    let c = &plane[3..3 + BEND_TERMS];
    let bend = (0..BEND_TERMS).map(|j| c[j] * basis[j]).sum();
    let g = (0..BEND_TERMS).map(|j| grads[j] * c[j]).sum();
    (bend, basis, g)
}

/// Whether the ray `o + t u` (u unit) grazes the sphere of `radius` about `c` (its
/// half-chord under [`GRAZING_KAPPA`] of the radius: its range is a footprint effect more
/// than a distance) or misses it.
pub fn grazes_sphere(o: &V3, u: &V3, c: &V3, radius: f64) -> bool {
    let w = o - c;
    let b = u.dot(&w);
    let q = b * b - w.norm_squared() + radius * radius;
    q <= 0.0 || q.sqrt() < GRAZING_KAPPA * radius
}

/// The flatness prior on a plane's bend: σ [`crate::room::FLATNESS_MM`] at zero on each of
/// the [`BEND_TERMS`] coefficients of parameter block `plane`.
pub fn flatness_prior(plane: ParameterKey) -> pingcal_ba::ParameterPrior {
    pingcal_ba::ParameterPrior {
        parameter: plane,
        components: (3..FIXED_PLANE_UNKNOWNS).collect(),
        value: vec![0.0; BEND_TERMS],
        sigma: vec![crate::room::FLATNESS_MM; BEND_TERMS],
    }
}

/// A beam of a fixed LRF: its station (the index of the station's image pose in the
/// adjustment's problem is the caller's), angle and range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedBeam {
    /// Beam angle α (radians).
    pub alpha_rad: f64,
    /// Measured range (mm).
    pub range_mm: f64,
    /// Its σ (mm).
    pub sigma: f64,
}

impl FixedBeam {
    /// The beam's point in the LRF frame at range `r`.
    pub fn point_at(&self, r: f64) -> V3 {
        V3::new(r * self.alpha_rad.cos(), r * self.alpha_rad.sin(), 0.0)
    }

    /// The beam's unit direction in the LRF frame.
    pub fn direction(&self) -> V3 {
        self.point_at(1.0)
    }

    /// The measured point in the object frame at the station pose `camera_from_object` and
    /// the extrinsic, with the range model `[k, s]` taken out of the range.
    pub fn object_point(&self, camera_from_object: &Rigid3, e: &Rigid3, range: [f64; 2]) -> V3 {
        let r = (self.range_mm - range[0]) / (1.0 + range[1]);
        camera_from_object
            .inverse()
            .transform(&e.transform(&self.point_at(r)))
    }
}

/// The ray of a beam in the object frame and its derivatives with respect to the station
/// pose's and the extrinsic's left updates (δω, δt): `(o, u, ∂o/∂P, ∂u/∂P, ∂o/∂E, ∂u/∂E)`,
/// each derivative a 3 × 6 matrix.
struct Ray {
    o: V3,
    u: V3,
    do_dp: nalgebra::Matrix3x6<f64>,
    du_dp: nalgebra::Matrix3x6<f64>,
    do_de: nalgebra::Matrix3x6<f64>,
    du_de: nalgebra::Matrix3x6<f64>,
}

fn ray(beam: &FixedBeam, p: &Rigid3, e: &Rigid3) -> Ray {
    let rpt: Matrix3<f64> = p.rotation.transpose();
    let oc = e.translation - p.translation;
    let uc = e.rotation * beam.direction();
    let mut r = Ray {
        o: rpt * oc,
        u: rpt * uc,
        do_dp: Default::default(),
        du_dp: Default::default(),
        do_de: Default::default(),
        du_de: Default::default(),
    };
    // under P ← (exp(δω)R_P, t_P + δt): v_obj = R_Pᵀ exp(−δω) v  ⇒  ∂/∂δω = R_Pᵀ [v]×
    r.do_dp
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(rpt * skew(&oc)));
    r.do_dp.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-rpt));
    r.du_dp
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(rpt * skew(&uc)));
    // under E ← (exp(δω)R_E, t_E + δt): u_c = exp(δω) R_E u_l ⇒ ∂u_c/∂δω = −[u_c]×
    r.do_de.fixed_view_mut::<3, 3>(0, 3).copy_from(&rpt);
    r.du_de
        .fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-rpt * skew(&uc)));
    r
}

/// A surface the beam meets: the predicted range and its derivatives with respect to the
/// ray's origin, its direction and the surface's own unknowns.
struct Hit {
    r: f64,
    dr_do: V3,
    dr_du: V3,
    dr_surface: Vec<f64>,
}

/// The range along the ray `(o, u)` to the bent plane of local unknowns `plane` about
/// `frame` (see the module doc).
fn plane_hit(frame: &PlaneFrame, plane: &[f64], o: &V3, u: &V3) -> Option<Hit> {
    let (n, dn_a, dn_b) = frame.normal_at(plane[0], plane[1]);
    let s = n.dot(u);
    if s.abs() < 1e-9 {
        return None;
    }
    let t0 = (plane[2] - n.dot(o)) / s;
    let h = o + u * t0;
    let (bend, basis, g) = bend_at(frame, plane, &h);
    let gu = g.dot(u);
    // r = t₀ + b(h)/s: ∂r = ∂t₀ + ∇b·∂h/s − b ∂s/s², ∂h = ∂o + t₀ ∂u + u ∂t₀;
    // ∂t₀ = (∂d − ∂n·h − n·∂o − t₀ n·∂u)/s
    let dt0_to_r = 1.0 + gu / s;
    let dn = |dn: &V3| -dn.dot(&h) / s * dt0_to_r - bend * dn.dot(u) / (s * s);
    let mut dr_surface = vec![dn(&dn_a), dn(&dn_b), dt0_to_r / s];
    dr_surface.extend(basis.iter().map(|b| b / s));
    Some(Hit {
        r: t0 + bend / s,
        dr_do: -n / s * dt0_to_r + g / s,
        dr_du: -n * (t0 / s) * dt0_to_r + g * (t0 / s) - n * (bend / (s * s)),
        dr_surface,
    })
}

/// The range along the ray `(o, u)` to the near side of the sphere of `radius` about `c`
/// (a ray that misses it: to its closest approach).
fn sphere_hit(c: &V3, radius: f64, o: &V3, u: &V3) -> Hit {
    let w = o - c;
    let b = u.dot(&w);
    let q = b * b - w.norm_squared() + radius * radius;
    if q <= 0.0 {
        // a ray that misses: the range of its closest approach (continuous with the
        // tangent ray's), so that an adjustment's step past the rim stays defined
        return Hit {
            r: -b,
            dr_do: -u,
            dr_du: -w,
            dr_surface: u.iter().copied().collect(),
        };
    }
    let sq = q.sqrt();
    let r = -b - sq;
    // ∂r = −∂b − (b ∂b − w·∂w)/sq,  ∂b = ∂u·w + u·∂w,  ∂w = ∂o − ∂c
    let k = 1.0 + b / sq;
    let dr_dw = -u * k + w / sq;
    let dr_du = -w * k;
    Hit {
        r,
        dr_do: dr_dw,
        dr_du,
        dr_surface: (-dr_dw).iter().copied().collect(),
    }
}

/// What a fixed beam's residual is on: a plane or a ball.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// A plane: its parameter block (of [`FIXED_PLANE_UNKNOWNS`]) about its frame.
    Plane(ParameterKey, PlaneFrame),
    /// A ball: its centre's point and its radius (mm).
    Ball(PointKey, f64),
}

/// A fixed LRF's beam on a plane or a ball as an observation of a bundle adjustment
/// ([`pingcal_ba::Residual`]; see the module doc): blocks (station pose, extrinsic, range
/// model, surface).
#[derive(Clone, Copy, Debug)]
pub struct FixedBeamOn {
    /// The beam.
    pub beam: FixedBeam,
    /// The image whose pose is the station's.
    pub station: pingcal_ba::ImageKey,
    /// The extrinsic `camera_from_lrf` (a pose block).
    pub extrinsic: ParameterKey,
    /// The range model `[k, s]` (a vector block of 2).
    pub range: ParameterKey,
    /// What the beam is on.
    pub surface: Surface,
}

/// The residual `e = r − (1 + s)·r̂ − k` and its derivatives (station pose, extrinsic, range
/// model, surface).
type Evaluated = (f64, [f64; 6], [f64; 6], [f64; 2], Vec<f64>);

impl FixedBeamOn {
    /// `e` (mm, not whitened) and its derivatives at these values; None where the beam
    /// misses or grazes its surface.
    fn at(&self, p: &Rigid3, e: &Rigid3, range: &[f64], surface: &Value) -> Option<Evaluated> {
        let ray = ray(&self.beam, p, e);
        let hit = match (&self.surface, surface) {
            (Surface::Plane(_, frame), Value::Vector(v)) if v.len() == FIXED_PLANE_UNKNOWNS => {
                plane_hit(frame, v, &ray.o, &ray.u)?
            }
            (Surface::Ball(_, radius), Value::Point(c)) => sphere_hit(c, *radius, &ray.o, &ray.u),
            _ => return None,
        };
        let (k, s) = (*range.first()?, *range.get(1)?);
        let gain = 1.0 + s;
        let res = self.beam.range_mm - gain * hit.r - k;
        if !res.is_finite() {
            return None;
        }
        let row = |dodx: &nalgebra::Matrix3x6<f64>, dudx: &nalgebra::Matrix3x6<f64>| {
            let v = dodx.transpose() * hit.dr_do + dudx.transpose() * hit.dr_du;
            std::array::from_fn(|j| -gain * v[j])
        };
        let d_pose = row(&ray.do_dp, &ray.du_dp);
        let d_ext = row(&ray.do_de, &ray.du_de);
        let d_surface = hit.dr_surface.iter().map(|v| -gain * v).collect();
        Some((res, d_pose, d_ext, [-1.0, -hit.r], d_surface))
    }

    /// Whether the beam grazes its ball at these values (the root's half-chord under
    /// [`GRAZING_KAPPA`] of the radius: its range is a footprint effect more than a
    /// distance), or misses it, the ball's centre at `c`; false on a plane.
    pub fn grazes(&self, p: &Rigid3, e: &Rigid3, c: &V3) -> bool {
        match &self.surface {
            Surface::Ball(_, radius) => {
                let ray = ray(&self.beam, p, e);
                grazes_sphere(&ray.o, &ray.u, c, *radius)
            }
            _ => false,
        }
    }

    /// `e = r − (1 + s)·r̂ − k` (mm, not whitened) at the station pose, the extrinsic, the
    /// range model and the surface's value; None where undefined.
    pub fn error(&self, p: &Rigid3, e: &Rigid3, range: &[f64], surface: &Value) -> Option<f64> {
        self.at(p, e, range, surface).map(|a| a.0)
    }
}

impl Residual for FixedBeamOn {
    fn dim(&self) -> usize {
        1
    }

    fn blocks(&self) -> Vec<Block> {
        vec![
            Block::Pose(self.station),
            Block::Parameter(self.extrinsic),
            Block::Parameter(self.range),
            match self.surface {
                Surface::Plane(k, _) => Block::Parameter(k),
                Surface::Ball(k, _) => Block::Point(k),
            },
        ]
    }

    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let (Some(p), Some(e), Some(range)) =
            (values[0].pose(), values[1].pose(), values[2].vector())
        else {
            return false;
        };
        let Some((res, dp, de, dr, ds)) = self.at(p, e, range, &values[3]) else {
            return false;
        };
        let sigma = self.beam.sigma;
        residual[0] = res / sigma;
        if let Some(j) = jacobians {
            for k in 0..6 {
                j[0][(0, k)] = dp[k] / sigma;
                j[1][(0, k)] = de[k] / sigma;
            }
            for (k, v) in dr.iter().enumerate() {
                j[2][(0, k)] = v / sigma;
            }
            for (k, v) in ds.iter().enumerate() {
                j[3][(0, k)] = v / sigma;
            }
        }
        true
    }

    fn group(&self) -> &str {
        match self.surface {
            Surface::Plane(..) => FIXED_PLANE_GROUP,
            Surface::Ball(..) => FIXED_BALL_GROUP,
        }
    }
}

/// A point lying on a plane of a fixed LRF's adjustment (a target on the wall that defines
/// it): `e = n·X − d − b(X)` (the plane's bend, see the module doc), whitened by σ (the wall's flatness and the target's thickness); blocks
/// (point, plane).
#[derive(Clone, Copy, Debug)]
pub struct PointOnPlane {
    /// The point.
    pub point: PointKey,
    /// The plane's block and frame.
    pub plane: ParameterKey,
    /// The plane's frame.
    pub frame: PlaneFrame,
    /// σ (mm).
    pub sigma: f64,
    /// Its variance-component group.
    pub group: &'static str,
}

impl PointOnPlane {
    /// `n·X − d − b(X)` (mm) at these values, and `b(X)`'s basis and gradient.
    fn at(&self, x: &V3, plane: &[f64]) -> (f64, [f64; BEND_TERMS], V3) {
        let (n, _, _) = self.frame.normal_at(plane[0], plane[1]);
        let (bend, basis, g) = bend_at(&self.frame, plane, x);
        (n.dot(x) - plane[2] - bend, basis, g)
    }

    /// `n·X − d − b(X)` (mm) at these values (NaN for a plane of the wrong size).
    pub fn error(&self, x: &V3, plane: &[f64]) -> f64 {
        if plane.len() != FIXED_PLANE_UNKNOWNS {
            return f64::NAN;
        }
        self.at(x, plane).0
    }
}

impl Residual for PointOnPlane {
    fn dim(&self) -> usize {
        1
    }

    fn blocks(&self) -> Vec<Block> {
        vec![Block::Point(self.point), Block::Parameter(self.plane)]
    }

    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let (Some(x), Some(pl)) = (values[0].point(), values[1].vector()) else {
            return false;
        };
        if pl.len() != FIXED_PLANE_UNKNOWNS {
            return false;
        }
        let (n, dn_a, dn_b) = self.frame.normal_at(pl[0], pl[1]);
        let (e, basis, g) = self.at(x, pl);
        residual[0] = e / self.sigma;
        if let Some(j) = jacobians {
            let dx = n - g;
            for k in 0..3 {
                j[0][(0, k)] = dx[k] / self.sigma;
            }
            j[1][(0, 0)] = dn_a.dot(x) / self.sigma;
            j[1][(0, 1)] = dn_b.dot(x) / self.sigma;
            j[1][(0, 2)] = -1.0 / self.sigma;
            for (k, b) in basis.iter().enumerate() {
                j[1][(0, 3 + k)] = -b / self.sigma;
            }
        }
        true
    }

    fn group(&self) -> &str {
        self.group
    }
}

/// A weighted prior on some components of a pose parameter block (the extrinsic), in its
/// local update's coordinates: `r = (log(R R₀ᵀ), t − t₀)` component-wise over σ. A weak one
/// makes the normal equations regular while what the data determine is tested; components
/// not listed are free of it.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseBlockPrior {
    /// The pose parameter block.
    pub parameter: ParameterKey,
    /// Where the prior is centred.
    pub value: Rigid3,
    /// The components it constrains (0–2 δω, 3–5 δt).
    pub components: Vec<usize>,
    /// Their σ's (rad, mm).
    pub sigma: Vec<f64>,
}

impl Residual for PoseBlockPrior {
    fn dim(&self) -> usize {
        self.components.len()
    }

    fn blocks(&self) -> Vec<Block> {
        vec![Block::Parameter(self.parameter)]
    }

    fn evaluate(&self, values: &[Value], residual: &mut [f64], jacobians: Jacobians<'_>) -> bool {
        let Some(x) = values[0].pose() else {
            return false;
        };
        if self.sigma.len() != self.components.len() || self.components.iter().any(|&c| c > 5) {
            return false;
        }
        let phi = pingcal_geometry::log_so3(&(x.rotation * self.value.rotation.transpose()));
        let dt = x.translation - self.value.translation;
        let jl = pingcal_ba::residual::left_jacobian_inverse(&phi);
        for (i, (&c, &s)) in self.components.iter().zip(&self.sigma).enumerate() {
            residual[i] = if c < 3 { phi[c] } else { dt[c - 3] } / s;
        }
        if let Some(j) = jacobians {
            for (i, (&c, &s)) in self.components.iter().zip(&self.sigma).enumerate() {
                if c < 3 {
                    for k in 0..3 {
                        j[0][(i, k)] = jl[(c, k)] / s;
                    }
                } else {
                    j[0][(i, c)] = 1.0 / s;
                }
            }
        }
        true
    }

    fn group(&self) -> &str {
        "parameter priors"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pingcal_ba::residual::check_residual_jacobians;
    use pingcal_geometry::from_opk;

    fn pose(opk: [f64; 3], t: [f64; 3]) -> Rigid3 {
        let r = |d: f64| d.to_radians();
        Rigid3::new(from_opk(r(opk[0]), r(opk[1]), r(opk[2])), V3::from(t))
    }

    /// A station looking at a wall, an extrinsic with a few degrees and centimetres.
    fn setup() -> (Rigid3, Rigid3, FixedBeam) {
        let p = pose([12.0, -7.0, 31.0], [150.0, -80.0, 900.0]);
        let e = pose([-14.0, 1.5, 3.0], [60.0, 25.0, -70.0]);
        let beam = FixedBeam {
            alpha_rad: 0.3,
            range_mm: 0.0,
            sigma: 10.0,
        };
        (p, e, beam)
    }

    #[test]
    fn the_beam_on_a_plane_has_the_jacobians_central_differences_give() {
        let (p, e, mut beam) = setup();
        let ray = ray(&beam, &p, &e);
        // a plane the ray meets at 1.8 m, not square to it
        let hit = ray.o + ray.u * 1800.0;
        let n = (-ray.u + V3::new(0.2, -0.1, 0.3)).normalize();
        let frame = PlaneFrame::new(n, hit, 500.0);
        let plane = [
            0.01,
            -0.02,
            n.dot(&hit) + 5.0,
            1.5,
            -2.0,
            0.7,
            0.4,
            -0.9,
            1.1,
        ];
        beam.range_mm = 1830.0;
        let res = FixedBeamOn {
            beam,
            station: pingcal_ba::ImageKey(0),
            extrinsic: ParameterKey(0),
            range: ParameterKey(1),
            surface: Surface::Plane(ParameterKey(2), frame),
        };
        let range = [12.0, 0.004];
        let values = [
            Value::Pose(&p),
            Value::Pose(&e),
            Value::Vector(&range),
            Value::Vector(&plane),
        ];
        let worst = check_residual_jacobians(&res, &values, 1e-6).expect("defined");
        assert!(worst < 1e-6, "worst relative Jacobian error {worst}");
    }

    #[test]
    fn the_beam_on_a_ball_has_the_jacobians_central_differences_give() {
        let (p, e, mut beam) = setup();
        let ray = ray(&beam, &p, &e);
        // a ball of radius 19 mm whose centre is 8 mm off the ray, 1.2 m along it
        let side = ray.u.cross(&V3::z()).normalize();
        let c = ray.o + ray.u * 1200.0 + side * 8.0;
        beam.range_mm = 1185.0;
        let res = FixedBeamOn {
            beam,
            station: pingcal_ba::ImageKey(0),
            extrinsic: ParameterKey(0),
            range: ParameterKey(1),
            surface: Surface::Ball(PointKey(0), 19.0),
        };
        let range = [-6.0, 0.01];
        let values = [
            Value::Pose(&p),
            Value::Pose(&e),
            Value::Vector(&range),
            Value::Point(&c),
        ];
        let worst = check_residual_jacobians(&res, &values, 1e-6).expect("defined");
        assert!(worst < 1e-6, "worst relative Jacobian error {worst}");
        // the predicted range is the near side's: 1200 − √(19² − 8²)
        let (e0, ..) = res.at(&p, &e, &range, &values[3]).expect("hits");
        let r_hat = 1200.0 - (19.0f64.powi(2) - 64.0).sqrt();
        assert!((e0 - (1185.0 - 1.01 * r_hat + 6.0)).abs() < 1e-6, "{e0}");
    }

    #[test]
    fn a_point_on_a_plane_has_the_jacobians_central_differences_give() {
        let frame = PlaneFrame::new(V3::new(0.1, 0.9, 0.2), V3::new(0.0, 2000.0, 300.0), 800.0);
        let res = PointOnPlane {
            point: PointKey(0),
            plane: ParameterKey(0),
            frame,
            sigma: 2.0,
            group: "targets on planes",
        };
        let x = V3::new(300.0, 2010.0, 500.0);
        let plane = [0.02, 0.01, 2100.0, -1.2, 0.8, 2.5, -0.6, 1.3, 0.9];
        let values = [Value::Point(&x), Value::Vector(&plane)];
        let worst = check_residual_jacobians(&res, &values, 1e-6).expect("defined");
        assert!(worst < 1e-6, "worst relative Jacobian error {worst}");
    }

    /// A panel held at its edges bowing between them (the simulator's pillow, `16 h s(1−s)
    /// q(1−q)` over the panel) lies in the span of the plane and its bend when the frame's
    /// axes run along the edges, wherever the frame's centre and scale are.
    #[test]
    fn a_pillow_along_the_frames_axes_is_in_the_bends_span() {
        let (w, h, bulge) = (2500.0, 2000.0, 3.0);
        let frame = PlaneFrame {
            normal: V3::z(),
            e1: V3::x(),
            e2: V3::y(),
            centre: V3::new(700.0, 600.0, 0.0),
            scale: 540.0,
        };
        let mut rows = Vec::new();
        let mut rhs = Vec::new();
        for i in 0..=20 {
            for j in 0..=20 {
                let (u, v) = (w * i as f64 / 20.0, h * j as f64 / 20.0);
                let (s, q) = (u / w, v / h);
                rhs.push(16.0 * bulge * s * (1.0 - s) * q * (1.0 - q));
                let x = V3::new(u, v, 0.0);
                let (basis, _) = bend_basis(&frame, &x);
                let mut row = vec![1.0, u, v];
                row.extend(basis);
                rows.push(row);
            }
        }
        let a = nalgebra::DMatrix::from_fn(rows.len(), 3 + BEND_TERMS, |r, c| rows[r][c]);
        let b = nalgebra::DVector::from_vec(rhs);
        let fit = a.clone().svd(true, true).solve(&b, 1e-12).expect("solves");
        let worst = (a * fit - b).amax();
        assert!(
            worst < 1e-6,
            "the pillow misses the bend's span by {worst} mm"
        );
    }

    #[test]
    fn the_pose_prior_has_the_jacobians_central_differences_give() {
        let (_, e, _) = setup();
        let prior = PoseBlockPrior {
            parameter: ParameterKey(0),
            value: pose([-10.0, 2.0, 1.0], [50.0, 20.0, -60.0]),
            components: vec![0, 2, 4, 5],
            sigma: vec![0.2, 0.1, 100.0, 50.0],
        };
        let worst = check_residual_jacobians(&prior, &[Value::Pose(&e)], 1e-6).expect("defined");
        assert!(worst < 1e-6, "worst relative Jacobian error {worst}");
    }

    #[test]
    fn the_measured_point_lies_where_the_model_predicts_it() {
        let (p, e, mut beam) = setup();
        let ray = ray(&beam, &p, &e);
        beam.range_mm = 1500.0 * 1.004 + 12.0;
        let x = beam.object_point(&p, &e, [12.0, 0.004]);
        assert!((x - (ray.o + ray.u * 1500.0)).norm() < 1e-9);
    }
}
