//! The adjustment report, laid out like Australis's: the network and its statistics;
//! each camera's parameters (initial value, adjusted value, standard deviation) with
//! high correlations; the exterior orientations; the object points; what was rejected.
//! The same content as JSON for programs.

use crate::problem::Problem;
use crate::solver::{ControlRejection, DistanceRejection, Precision, Rejection, Summary};
use pingcal_geometry::to_opk;
use serde::Serialize;
use std::fmt::Write;

/// One intrinsic parameter in the report.
#[derive(Clone, Debug, Serialize)]
pub struct ParameterReport {
    /// Name (c, xp, …).
    pub name: String,
    /// Value before the adjustment.
    pub initial: f64,
    /// Adjusted value.
    pub value: f64,
    /// Standard deviation (None: held fixed).
    pub sigma: Option<f64>,
}

/// One camera in the report.
#[derive(Clone, Debug, Serialize)]
pub struct CameraReport {
    /// Camera name.
    pub name: String,
    /// Model name.
    pub model: String,
    /// Every parameter.
    pub parameters: Vec<ParameterReport>,
    /// Correlations above 0.95 between free parameters.
    pub high_correlations: Vec<(String, String, f64)>,
}

/// One image in the report.
#[derive(Clone, Debug, Serialize)]
pub struct ImageReport {
    /// Image name.
    pub name: String,
    /// Projection centre.
    pub centre: [f64; 3],
    /// Its standard deviations (None: held fixed).
    pub sigma_centre: Option<[f64; 3]>,
    /// ω, φ, κ in degrees (R = R_ω R_φ R_κ).
    pub omega_phi_kappa_deg: [f64; 3],
    /// Standard deviations of the small rotations about the camera axes, degrees.
    pub sigma_rotation_deg: Option<[f64; 3]>,
}

/// One object point in the report.
#[derive(Clone, Debug, Serialize)]
pub struct PointReport {
    /// Point name.
    pub name: String,
    /// Coordinates.
    pub xyz: [f64; 3],
    /// Standard deviations (None: held fixed).
    pub sigma: Option<[f64; 3]>,
    /// Number of rays.
    pub rays: usize,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct AdjustmentReport {
    /// Images in the adjustment.
    pub images: usize,
    /// Object points in the adjustment.
    pub points: usize,
    /// Image points (observations of a point in an image), each two coordinates.
    pub image_observations: usize,
    /// Measured distances between object points.
    pub distances: usize,
    /// Control points: points with one or more coordinates held, plus weighted control
    /// points.
    pub control_points: usize,
    /// Observations − unknowns.
    pub redundancy: i64,
    /// A-posteriori σ of unit weight.
    pub sigma0: f64,
    /// RMS image residual in pixels.
    pub rms_image_px: f64,
    /// The same in µm on the sensor, with the pixel pitch of the first camera whose model
    /// knows it (None: no camera does, as with the OpenCV and fisheye models).
    pub rms_image_um: Option<f64>,
    /// Iterations of the solver.
    pub iterations: usize,
    /// Why the solver stopped, in words (e.g. `converged: gradient below the gradient
    /// tolerance`).
    pub termination: String,
    /// Per camera, its parameters, in the problem's order.
    pub cameras: Vec<CameraReport>,
    /// Per image, its exterior orientation, in the problem's order.
    pub exterior: Vec<ImageReport>,
    /// Per object point, its coordinates and precision, in the problem's order.
    pub object_points: Vec<PointReport>,
    /// Observations left out as gross errors, in the order they were left out: what the
    /// caller passed to [`AdjustmentReport::new`] (in [`crate::workflow`], the initialiser's
    /// start-up rejections, then data snooping's).
    pub rejected: Vec<Rejection>,
    /// Distances left out as gross errors by data snooping, in order (empty from
    /// [`AdjustmentReport::new`]; [`crate::workflow`] fills it in).
    pub rejected_distances: Vec<DistanceRejection>,
    /// Control points left out as gross errors by data snooping, in order (as
    /// `rejected_distances`).
    pub rejected_control_points: Vec<ControlRejection>,
}

impl AdjustmentReport {
    /// Gathers the report. `initial_intrinsics[c]` are camera c's parameters before the
    /// adjustment.
    pub fn new(
        problem: &Problem,
        initial_intrinsics: &[Vec<f64>],
        summary: &Summary,
        precision: &Precision,
        rejected: &[Rejection],
    ) -> Self {
        let cameras = problem
            .cameras
            .iter()
            .enumerate()
            .map(|(c, cam)| {
                let prec = precision.intrinsics.iter().find(|p| p.camera == cam.name);
                let names = cam.model.parameter_names();
                let parameters = (0..cam.params.len())
                    .map(|k| ParameterReport {
                        name: names[k].to_string(),
                        initial: initial_intrinsics
                            .get(c)
                            .and_then(|v| v.get(k))
                            .copied()
                            .unwrap_or(cam.params[k]),
                        value: cam.params[k],
                        sigma: prec.and_then(|p| {
                            p.names
                                .iter()
                                .position(|n| n == names[k])
                                .map(|i| p.sigmas[i])
                        }),
                    })
                    .collect();
                CameraReport {
                    name: cam.name.clone(),
                    model: cam.model.name().to_string(),
                    parameters,
                    high_correlations: prec
                        .map(|p| p.high_correlations.clone())
                        .unwrap_or_default(),
                }
            })
            .collect();
        let exterior = problem
            .images
            .iter()
            .enumerate()
            .map(|(i, im)| {
                let (o, p, k) = to_opk(&im.camera_from_object.rotation);
                let s = precision.poses.get(i).copied().flatten();
                ImageReport {
                    name: im.name.clone(),
                    centre: im.camera_from_object.centre().into(),
                    sigma_centre: s.map(|s| s.centre),
                    omega_phi_kappa_deg: [o.to_degrees(), p.to_degrees(), k.to_degrees()],
                    sigma_rotation_deg: s.map(|s| s.rotation_rad.map(f64::to_degrees)),
                }
            })
            .collect();
        let mut rays = vec![0usize; problem.points.len()];
        for o in &problem.observations {
            rays[o.point.0] += 1;
        }
        let object_points = problem
            .points
            .iter()
            .enumerate()
            .map(|(p, pt)| PointReport {
                name: pt.name.clone(),
                xyz: pt.position.into(),
                sigma: precision.point_sigma(p).map(Into::into),
                rays: rays[p],
            })
            .collect();
        let pixel = problem.cameras.iter().find_map(|c| c.model.pixel_size_mm());
        Self {
            images: problem.images.len(),
            points: problem.points.len(),
            image_observations: problem.observations.len(),
            distances: problem.distances.len(),
            control_points: (problem.points.iter())
                .filter(|p| p.held().iter().any(|&h| h))
                .count()
                + problem.point_priors.len(),
            redundancy: precision.redundancy,
            sigma0: precision.sigma0,
            rms_image_px: precision.rms_image_px,
            rms_image_um: pixel.map(|ps| precision.rms_image_px * ps * 1000.0),
            iterations: summary.iterations,
            termination: summary.termination.to_string(),
            cameras,
            exterior,
            object_points,
            rejected: rejected.to_vec(),
            rejected_distances: Vec::new(),
            rejected_control_points: Vec::new(),
        }
    }

    /// The report as text, in the order Australis prints it.
    pub fn to_text(&self) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "BUNDLE ADJUSTMENT (pingcal)");
        let _ = writeln!(t, "==========================");
        let _ = writeln!(
            t,
            "images {}   points {}   image observations {}   distances {}   control points {}",
            self.images, self.points, self.image_observations, self.distances, self.control_points
        );
        let um = self
            .rms_image_um
            .map(|v| format!(" ({v:.3} µm)"))
            .unwrap_or_default();
        let _ = writeln!(
            t,
            "redundancy {}   sigma0 {:.4}   RMS image residual {:.4} px{um}   iterations {} ({})",
            self.redundancy, self.sigma0, self.rms_image_px, self.iterations, self.termination
        );
        for c in &self.cameras {
            let _ = writeln!(t, "\nCAMERA '{}' ({})", c.name, c.model);
            let _ = writeln!(
                t,
                "  {:<6} {:>16} {:>16} {:>12}",
                "param", "initial", "final", "std dev"
            );
            for p in &c.parameters {
                let s = p
                    .sigma
                    .map(|s| format!("{s:12.4e}"))
                    .unwrap_or_else(|| format!("{:>12}", "fixed"));
                let _ = writeln!(
                    t,
                    "  {:<6} {:>16.8e} {:>16.8e} {s}",
                    p.name, p.initial, p.value
                );
            }
            for (a, b, r) in &c.high_correlations {
                let _ = writeln!(t, "  high correlation {a}–{b}: {:+.1} %", 100.0 * r);
            }
        }
        let _ = writeln!(t, "\nEXTERIOR ORIENTATION");
        let _ = writeln!(
            t,
            "  {:<16} {:>12} {:>12} {:>12} {:>9} {:>9} {:>9}   {:>8} {:>8} {:>8}",
            "image", "X", "Y", "Z", "omega", "phi", "kappa", "sX", "sY", "sZ"
        );
        for im in &self.exterior {
            let s = im
                .sigma_centre
                .map(|s| format!("{:8.3} {:8.3} {:8.3}", s[0], s[1], s[2]))
                .unwrap_or_else(|| format!("{:>26}", "fixed"));
            let [o, p, k] = im.omega_phi_kappa_deg;
            let _ = writeln!(
                t,
                "  {:<16} {:12.3} {:12.3} {:12.3} {o:9.4} {p:9.4} {k:9.4}   {s}",
                im.name, im.centre[0], im.centre[1], im.centre[2]
            );
        }
        let _ = writeln!(t, "\nOBJECT POINTS");
        let _ = writeln!(
            t,
            "  {:<10} {:>12} {:>12} {:>12}   {:>8} {:>8} {:>8} {:>5}",
            "point", "X", "Y", "Z", "sX", "sY", "sZ", "rays"
        );
        for p in &self.object_points {
            let s = p
                .sigma
                .map(|s| format!("{:8.4} {:8.4} {:8.4}", s[0], s[1], s[2]))
                .unwrap_or_else(|| format!("{:>26}", "fixed"));
            let _ = writeln!(
                t,
                "  {:<10} {:12.4} {:12.4} {:12.4}   {s} {:5}",
                p.name, p.xyz[0], p.xyz[1], p.xyz[2], p.rays
            );
        }
        if !self.rejected.is_empty() {
            let _ = writeln!(t, "\nREJECTED OBSERVATIONS");
            for r in &self.rejected {
                let _ = writeln!(
                    t,
                    "  image {} point {} at ({:.2}, {:.2}): {}",
                    r.image, r.point, r.uv[0], r.uv[1], r.reason
                );
            }
        }
        self.rejected_measurements_text(&mut t);
        t
    }

    /// The text of the distances and control points left out.
    fn rejected_measurements_text(&self, t: &mut String) {
        if !self.rejected_distances.is_empty() {
            let _ = writeln!(t, "\nREJECTED DISTANCES");
            for d in &self.rejected_distances {
                let _ = writeln!(
                    t,
                    "  {} – {} given as {:.4} (σ {}), adjusted {:.4} without it (w = {:.1}): {}",
                    d.a, d.b, d.given, d.sigma, d.estimated, d.w, d.reason
                );
            }
        }
        if !self.rejected_control_points.is_empty() {
            let _ = writeln!(t, "\nREJECTED CONTROL POINTS");
            for c in &self.rejected_control_points {
                let _ = writeln!(
                    t,
                    "  {} given at ({:.4}, {:.4}, {:.4}), adjusted ({:.4}, {:.4}, {:.4}) without it (w = {:.1}, {:.1}, {:.1}): {}",
                    c.point,
                    c.given[0],
                    c.given[1],
                    c.given[2],
                    c.estimated[0],
                    c.estimated[1],
                    c.estimated[2],
                    c.w[0],
                    c.w[1],
                    c.w[2],
                    c.reason
                );
            }
        }
    }
}
