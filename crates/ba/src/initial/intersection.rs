//! Spatial intersection: an object point from two or more oriented rays.
//!
//! Linear least squares first (the point closest to all rays: Σ (I − d dᵀ)(X − C) = 0,
//! d the unit ray in object space), then Gauss–Newton on the reprojection errors in
//! pixels. The point is rejected when the largest angle between its rays is below a
//! threshold (a poorly determined depth), when it lies behind a camera, or when its
//! reprojection error exceeds a threshold.

use crate::camera::CameraModel;
use nalgebra::{Matrix2x3, Matrix3, Vector2, Vector3};
use pingcal_geometry::Rigid3;

/// One ray: an oriented image's pose, its camera and the measured pixel.
#[derive(Clone, Copy, Debug)]
pub struct Ray<'a> {
    /// Exterior orientation of the image: object → camera.
    pub camera_from_object: Rigid3,
    /// Camera model.
    pub model: &'a dyn CameraModel,
    /// Intrinsics.
    pub params: &'a [f64],
    /// Measured pixel.
    pub uv: Vector2<f64>,
}

/// Options of [`intersect`].
#[derive(Clone, Debug)]
pub struct IntersectionOptions {
    /// Smallest acceptable largest angle between two rays, degrees.
    pub min_angle_deg: f64,
    /// Largest acceptable RMS reprojection error, pixels.
    pub max_rms_px: f64,
}

impl Default for IntersectionOptions {
    fn default() -> Self {
        Self {
            min_angle_deg: 2.0,
            max_rms_px: 10.0,
        }
    }
}

/// An intersected point.
#[derive(Clone, Debug)]
pub struct Intersection {
    /// Object coordinates.
    pub position: Vector3<f64>,
    /// Largest angle between two of its rays, degrees.
    pub max_angle_deg: f64,
    /// RMS reprojection error, pixels (per coordinate).
    pub rms_px: f64,
}

/// Why an intersection failed.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum IntersectionError {
    /// Fewer than two rays (that could be back-projected).
    #[error("intersection needs at least 2 rays, got {got}")]
    TooFewRays {
        /// Rays whose pixel could be back-projected (the intersection also fails when any
        /// one of them cannot be).
        got: usize,
    },
    /// The rays are nearly parallel.
    #[error("the rays meet at {angle_deg:.3}°, below the {min_deg}° needed")]
    SmallAngle {
        /// Largest angle between two of the rays, degrees.
        angle_deg: f64,
        /// The smallest accepted ([`IntersectionOptions::min_angle_deg`]), degrees.
        min_deg: f64,
    },
    /// The point is behind one of the cameras.
    #[error("the intersection lies behind camera {ray}")]
    BehindCamera {
        /// 0-based index of that ray in the rays given.
        ray: usize,
    },
    /// The rays do not meet well.
    #[error("the rays miss each other: RMS reprojection error {rms_px:.2} px")]
    LargeResidual {
        /// RMS reprojection error of the intersected point, pixels per coordinate (above
        /// [`IntersectionOptions::max_rms_px`]).
        rms_px: f64,
    },
}

/// Residual (pixels) of `x` in one ray and its Jacobian with respect to `x`
/// (`∂uv/∂xc · R`).
pub fn point_residual_jacobian(
    ray: &Ray,
    x: &Vector3<f64>,
) -> Option<(Vector2<f64>, Matrix2x3<f64>)> {
    let xc = ray.camera_from_object.transform(x);
    let mut jp = Matrix2x3::zeros();
    let p = ray.model.project(ray.params, &xc, Some(&mut jp), None)?;
    Some((p - ray.uv, jp * ray.camera_from_object.rotation))
}

/// Intersects the rays.
pub fn intersect(
    rays: &[Ray],
    options: &IntersectionOptions,
) -> Result<Intersection, IntersectionError> {
    let mut dirs = Vec::new();
    let mut centres = Vec::new();
    for r in rays {
        if let Some(d) = r.model.unproject(r.params, &r.uv) {
            dirs.push(r.camera_from_object.rotation.transpose() * d);
            centres.push(r.camera_from_object.centre());
        }
    }
    if dirs.len() < 2 || dirs.len() < rays.len() {
        return Err(IntersectionError::TooFewRays { got: dirs.len() });
    }
    let mut max_cos: f64 = 1.0;
    for i in 0..dirs.len() {
        for j in i + 1..dirs.len() {
            max_cos = max_cos.min(dirs[i].dot(&dirs[j]));
        }
    }
    let angle = max_cos.clamp(-1.0, 1.0).acos().to_degrees();
    if !(angle >= options.min_angle_deg) {
        return Err(IntersectionError::SmallAngle {
            angle_deg: angle,
            min_deg: options.min_angle_deg,
        });
    }
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for (d, c) in dirs.iter().zip(&centres) {
        let p = Matrix3::identity() - d * d.transpose();
        a += p;
        b += p * c;
    }
    let Some(mut x) = a.try_inverse().map(|ai| ai * b) else {
        return Err(IntersectionError::SmallAngle {
            angle_deg: angle,
            min_deg: options.min_angle_deg,
        });
    };
    for (k, (d, c)) in dirs.iter().zip(&centres).enumerate() {
        if (x - c).dot(d) <= 0.0 {
            return Err(IntersectionError::BehindCamera { ray: k });
        }
    }
    // Gauss–Newton on the reprojection errors, with step halving.
    let cost = |x: &Vector3<f64>| -> Option<f64> {
        rays.iter()
            .map(|r| point_residual_jacobian(r, x).map(|(e, _)| e.norm_squared()))
            .sum()
    };
    let mut c = cost(&x).unwrap_or(f64::INFINITY);
    for _ in 0..20 {
        let mut h = Matrix3::zeros();
        let mut g = Vector3::zeros();
        for r in rays {
            if let Some((e, j)) = point_residual_jacobian(r, &x) {
                h += j.transpose() * j;
                g += j.transpose() * e;
            }
        }
        let Some(step) = h.try_inverse().map(|hi| -(hi * g)) else {
            break;
        };
        let mut t = 1.0;
        let mut improved = false;
        for _ in 0..8 {
            let trial = x + step * t;
            if let Some(ct) = cost(&trial) {
                if ct < c {
                    improved = (c - ct) > 1e-14 * c;
                    x = trial;
                    c = ct;
                    break;
                }
            }
            t *= 0.5;
        }
        if !improved {
            break;
        }
    }
    for (k, r) in rays.iter().enumerate() {
        if r.model
            .project(r.params, &r.camera_from_object.transform(&x), None, None)
            .is_none()
        {
            return Err(IntersectionError::BehindCamera { ray: k });
        }
    }
    let rms_px = (c / (2 * rays.len()) as f64).sqrt();
    if !(rms_px <= options.max_rms_px) {
        return Err(IntersectionError::LargeResidual { rms_px });
    }
    Ok(Intersection {
        position: x,
        max_angle_deg: angle,
        rms_px,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::initial::resection::tests::{camera, look_at};
    use rand_distr::{Distribution, Normal};

    #[test]
    fn point_jacobian_matches_central_differences() {
        let (cam, p) = camera();
        let ray = Ray {
            camera_from_object: look_at(
                Vector3::new(0.3, -1.5, 1.2),
                Vector3::new(0.5, 0.5, 0.0),
                0.3,
            ),
            model: &cam,
            params: &p,
            uv: Vector2::new(1000.0, 700.0),
        };
        let x = Vector3::new(0.2, 0.7, 0.05);
        let (_, j) = point_residual_jacobian(&ray, &x).unwrap();
        for k in 0..3 {
            let h = 1e-6;
            let (mut a, mut b) = (x, x);
            a[k] += h;
            b[k] -= h;
            let fd = (point_residual_jacobian(&ray, &a).unwrap().0
                - point_residual_jacobian(&ray, &b).unwrap().0)
                / (2.0 * h);
            assert!((fd - j.column(k)).norm() < 1e-5 * fd.norm().max(1.0));
        }
    }

    #[test]
    fn recovers_a_point_from_noisy_rays_and_rejects_bad_geometry() {
        let (cam, p) = camera();
        let target = Vector3::new(0.5, 0.5, 0.0);
        let poses = [
            look_at(Vector3::new(-0.5, -0.5, 1.5), target, 0.0),
            look_at(Vector3::new(1.5, -0.3, 1.4), target, 1.0),
            look_at(Vector3::new(0.6, 1.8, 1.6), target, -2.0),
        ];
        let truth = Vector3::new(0.3, 0.6, 0.0);
        let noise = Normal::new(0.0, 0.1).unwrap();
        let mut rng = pingcal_geometry::consensus::rng(9);
        let rays: Vec<Ray> = poses
            .iter()
            .map(|pose| Ray {
                camera_from_object: *pose,
                model: &cam,
                params: &p,
                uv: cam
                    .project(&p, &pose.transform(&truth), None, None)
                    .unwrap()
                    + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng)),
            })
            .collect();
        let r = intersect(&rays, &IntersectionOptions::default()).unwrap();
        assert!(
            (r.position - truth).norm() < 2e-4,
            "{:?}",
            r.position - truth
        );
        assert!(r.max_angle_deg > 30.0);
        assert!(r.rms_px < 0.3);
        // Two nearly identical stations: small angle.
        let mut near = rays[0];
        near.camera_from_object = look_at(Vector3::new(-0.5, -0.5, 1.51), target, 0.0);
        near.uv = cam
            .project(&p, &near.camera_from_object.transform(&truth), None, None)
            .unwrap();
        assert!(matches!(
            intersect(&[rays[0], near], &IntersectionOptions::default()),
            Err(IntersectionError::SmallAngle { .. })
        ));
        assert!(matches!(
            intersect(&rays[..1], &IntersectionOptions::default()),
            Err(IntersectionError::TooFewRays { got: 1 })
        ));
        // Inconsistent rays (one measurement 300 px off).
        let mut bad = rays.clone();
        bad[2].uv.x += 300.0;
        assert!(intersect(&bad, &IntersectionOptions::default()).is_err());
    }
}
