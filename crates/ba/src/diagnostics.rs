//! Patterns in an adjustment's image residuals that say which part of the model is wrong.
//!
//! [`radial_profile`]: the residuals of one camera's observations split into rings by their
//! distance from the principal point, each ring's RMS of the residuals' radial component
//! (along the line from the principal point) and tangential one. A lens whose distortion the
//! camera model cannot hold — a fisheye adjusted with a pinhole model — leaves radial
//! residuals that grow toward the edge of the image, while the tangential ones stay small;
//! a wrong principal point or decentring leaves tangential ones too.

use crate::keys::CameraKey;
use crate::problem::Problem;

/// One ring of [`RadialProfile`].
#[derive(Clone, Debug, PartialEq)]
pub struct Ring {
    /// Its inner and outer radius, as fractions of the image's largest distance from the
    /// principal point.
    pub from: f64,
    /// Outer radius (fraction).
    pub to: f64,
    /// Observations in it.
    pub n: usize,
    /// RMS of the residuals' radial components, px.
    pub radial_px: f64,
    /// RMS of the residuals' tangential components, px.
    pub tangential_px: f64,
    /// RMS of the radial components over each observation's σ.
    pub radial_sigma: f64,
    /// Observations of the camera in it that data snooping removed (not among `n`).
    pub rejected: usize,
}

/// The image residuals of one camera by distance from its principal point ([`Ring`]s from
/// the centre out).
#[derive(Clone, Debug, PartialEq)]
pub struct RadialProfile {
    /// The rings, from the principal point out.
    pub rings: Vec<Ring>,
}

/// The [`RadialProfile`] of camera `camera` of `problem` (at its current solution) over
/// `rings` rings of equal width, for images of `width × height` pixels, with the pixels of
/// the camera's observations removed as gross errors (`rejected`) counted per ring.
/// Observations that do not project are left out.
pub fn radial_profile(
    problem: &Problem,
    camera: CameraKey,
    (width, height): (u32, u32),
    rings: usize,
    rejected: &[nalgebra::Vector2<f64>],
) -> RadialProfile {
    let cam = &problem.cameras[camera];
    let pp = cam.model.principal_point_px(&cam.params);
    let r_max = [
        (0.0, 0.0),
        (f64::from(width) - 1.0, 0.0),
        (0.0, f64::from(height) - 1.0),
        (f64::from(width) - 1.0, f64::from(height) - 1.0),
    ]
    .iter()
    .map(|&(x, y)| (x - pp.x).hypot(y - pp.y))
    .fold(0.0, f64::max);
    let rings = rings.max(1);
    let ring_of = |r: f64| ((r / r_max.max(1e-9) * rings as f64) as usize).min(rings - 1);
    let mut sums = vec![(0usize, 0.0, 0.0, 0.0); rings];
    let mut dropped = vec![0usize; rings];
    for uv in rejected {
        dropped[ring_of((uv - pp).norm())] += 1;
    }
    for o in &problem.observations {
        if problem.images[o.image].camera != camera {
            continue;
        }
        let Some(res) = problem.residual(o) else {
            continue;
        };
        let d = o.uv - pp;
        let r = d.norm();
        let k = ring_of(r);
        let (radial, tangential) = match r > 0.0 {
            true => {
                let u = d / r;
                (res.dot(&u), res.x * -u.y + res.y * u.x)
            }
            false => (0.0, res.norm()),
        };
        let s = &mut sums[k];
        s.0 += 1;
        s.1 += radial * radial;
        s.2 += tangential * tangential;
        s.3 += (radial / o.sigma).powi(2);
    }
    let rms = |sum: f64, n: usize| (sum / n.max(1) as f64).sqrt();
    RadialProfile {
        rings: sums
            .iter()
            .enumerate()
            .map(|(k, &(n, rad, tan, rs))| Ring {
                from: k as f64 / rings as f64,
                to: (k + 1) as f64 / rings as f64,
                n,
                radial_px: rms(rad, n),
                tangential_px: rms(tan, n),
                radial_sigma: rms(rs, n),
                rejected: dropped[k],
            })
            .collect(),
    }
}

impl RadialProfile {
    /// Whether the residuals grow along the radius toward the edge, as a distortion the
    /// model cannot hold leaves them: the outermost ring with 10 or more observations has a
    /// radial RMS over twice that of the innermost such ring and over 1.5 times its own
    /// tangential RMS. (Whether the residuals are too large at all is the σ0 test's to say;
    /// with 10 observations a ring's RMS varies by about 22 %, so noise alone does not
    /// double it.) Returns (inner, outer) rings when so.
    pub fn grows_radially(&self) -> Option<(&Ring, &Ring)> {
        let filled: Vec<&Ring> = self.rings.iter().filter(|r| r.n >= 10).collect();
        let (inner, outer) = (filled.first()?, filled.last()?);
        if std::ptr::eq(*inner, *outer) {
            return None;
        }
        (outer.radial_px > 2.0 * inner.radial_px && outer.radial_px > 1.5 * outer.tangential_px)
            .then_some((*inner, *outer))
    }

    /// Whether the gross errors data snooping removed gather toward the edge, as the
    /// points a model cannot fit there are removed instead of leaving residuals: of the
    /// outermost ring with 10 or more observations (kept and removed), over a fifth removed,
    /// and over four times the share of the innermost such ring. Returns (inner, outer).
    pub fn rejections_grow(&self) -> Option<(&Ring, &Ring)> {
        let share = |r: &Ring| r.rejected as f64 / (r.n + r.rejected).max(1) as f64;
        let filled: Vec<&Ring> = self
            .rings
            .iter()
            .filter(|r| r.n + r.rejected >= 10)
            .collect();
        let (inner, outer) = (filled.first()?, filled.last()?);
        if std::ptr::eq(*inner, *outer) {
            return None;
        }
        (share(outer) > 0.2 && share(outer) > 4.0 * share(inner)).then_some((*inner, *outer))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{CameraModel, FisheyeCamera, PhotogrammetricCamera};
    use crate::keys::{ImageKey, PointKey};
    use crate::problem::{Camera, Image, Observation, Point};
    use nalgebra::Vector3;
    use std::sync::Arc;

    /// Points seen through a fisheye, adjusted (here: only evaluated) with a pinhole of the
    /// same focal length: the radial residuals grow to the edge; with the fisheye itself
    /// there is no pattern.
    #[test]
    fn a_fisheye_seen_as_a_pinhole_leaves_radial_residuals_that_grow() {
        let fisheye = [360.0, 360.0, 639.5, 359.5, 0.02, -0.005, 0.001, -1e-4];
        let mut obs = Vec::new();
        let mut points = Vec::new();
        for i in 0..30 {
            for j in 0..15 {
                let x = Vector3::new(
                    -1500.0 + 100.0 * i as f64,
                    1000.0,
                    -700.0 + 100.0 * j as f64,
                );
                if let Some(uv) = FisheyeCamera.project(&fisheye, &x, None, None) {
                    if (0.0..1279.0).contains(&uv.x) && (0.0..719.0).contains(&uv.y) {
                        obs.push(Observation {
                            image: ImageKey(0),
                            point: PointKey(points.len()),
                            uv,
                            sigma: 0.1,
                        });
                        points.push(Point {
                            name: format!("P{i}_{j}"),
                            position: x,
                            fixed: false,
                            fixed_axes: [false; 3],
                        });
                    }
                }
            }
        }
        let pinhole = Arc::new(PhotogrammetricCamera::new(1280, 720, 0.00375));
        let mut c = vec![0.0; 10];
        c[0] = 360.0 * 0.00375;
        let problem = |model: Arc<dyn CameraModel>, params: Vec<f64>| Problem {
            cameras: vec![Camera::new("cam", model, params)],
            images: vec![Image {
                name: "a".into(),
                camera: CameraKey(0),
                camera_from_object: crate::Rigid3::identity(),
                fixed: false,
                fixed_centre: [false; 3],
            }],
            points: points.clone(),
            observations: obs.clone(),
            ..Problem::default()
        };
        let wrong = radial_profile(&problem(pinhole, c), CameraKey(0), (1280, 720), 5, &[]);
        let (inner, outer) = wrong.grows_radially().expect("a radial pattern");
        assert!(
            outer.radial_px > 10.0 * inner.radial_px.max(0.01),
            "{wrong:?}"
        );
        let right_problem = problem(Arc::new(FisheyeCamera), fisheye.to_vec());
        let right = radial_profile(&right_problem, CameraKey(0), (1280, 720), 5, &[]);
        assert!(right.grows_radially().is_none(), "{right:?}");
        assert!(right.rings.iter().all(|r| r.radial_px < 1e-9));
        assert!(right.rejections_grow().is_none());
        // the same points' outer ones removed instead: the removals gather at the edge
        let r_far = obs
            .iter()
            .map(|o| (o.uv - nalgebra::Vector2::new(639.5, 359.5)).norm())
            .fold(0.0, f64::max);
        let outer: Vec<nalgebra::Vector2<f64>> = obs
            .iter()
            .map(|o| o.uv)
            .filter(|uv| (uv - nalgebra::Vector2::new(639.5, 359.5)).norm() > 0.8 * r_far)
            .collect();
        let removed = radial_profile(&right_problem, CameraKey(0), (1280, 720), 5, &outer);
        let (_, ring) = removed.rejections_grow().expect("removals at the edge");
        assert!(ring.rejected > 0, "{removed:?}");
    }
}
