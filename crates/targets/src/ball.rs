//! Ping-pong balls: the silhouette of a sphere is an ellipse whose centre is **not** the
//! projection of the sphere's centre (it is pushed outward, away from the principal point, by
//! about r²/(Z² − r²) of the off-axis distance; docs/method.md "A ball in an image", Luhmann 2014, Matsuoka & Maruyama
//! 2016). The correction needs the camera's interior orientation, which lives in another crate
//! and is known only after calibration, so it is exposed as a function of the camera's two maps
//! (pixel → ray and ray → pixel), through the small trait [`CameraRays`]: a camera of pingcal's
//! models at its values ([`pingcal_camera::CameraAt`]) is one, and closures are too, via
//! [`FnCamera`].
//!
//! Method: the rays through the silhouette form a right circular cone whose axis passes through
//! the sphere's centre. With unit rays qᵢ through outline points, the axis w and half-angle α
//! satisfy qᵢ·w = cos α; solving qᵢ·v = 1 in the least-squares sense gives v = w / cos α, so
//! w = v/|v| and cos α = 1/|v|. The corrected image point is the projection of w; with a known
//! radius R the distance to the centre is R / sin α. Using all outline points (not only the
//! two ends of the major axis) makes it robust to edge noise, and it works with any lens
//! distortion because rays are formed by the camera's own pixel → ray map.
//!
//! Shading does not bias the axis when the light is close to the camera (flash): the intensity
//! on the sphere is then symmetric about the camera–centre line, so any iso-intensity outline
//! (including the mid-level edge the detector finds) is a circle about the same axis.

use crate::centre::{edge_points, refine, CentreParams, Refined, Reject, Round};
use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;

/// A camera's two maps. Rays are in the camera frame (any convention, as long as the two maps
/// agree); they need not be unit vectors.
pub trait CameraRays {
    /// The ray through an image point (pixels, origin at the centre of the top-left pixel).
    fn pixel_to_ray(&self, x: f64, y: f64) -> Option<[f64; 3]>;
    /// The image point of a ray (pixels); `None` when it does not reach the image plane.
    fn ray_to_pixel(&self, ray: [f64; 3]) -> Option<[f64; 2]>;
}

/// A camera of pingcal's models at its intrinsic values: the model's own maps.
impl CameraRays for pingcal_camera::CameraAt<'_> {
    fn pixel_to_ray(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        self.ray(x, y).map(|r| [r.x, r.y, r.z])
    }
    fn ray_to_pixel(&self, ray: [f64; 3]) -> Option<[f64; 2]> {
        self.pixel(&nalgebra::Vector3::from(ray))
            .map(|p| [p.x, p.y])
    }
}

/// [`CameraRays`] from two closures.
pub struct FnCamera<F, G>(pub F, pub G);

impl<F, G> CameraRays for FnCamera<F, G>
where
    F: Fn(f64, f64) -> Option<[f64; 3]>,
    G: Fn([f64; 3]) -> Option<[f64; 2]>,
{
    fn pixel_to_ray(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        (self.0)(x, y)
    }
    fn ray_to_pixel(&self, ray: [f64; 3]) -> Option<[f64; 2]> {
        (self.1)(ray)
    }
}

/// An ideal pinhole camera (x right, y down, z forward), for tests and as an example.
#[derive(Clone, Copy, Debug)]
pub struct Pinhole {
    /// Focal length, px.
    pub f: f64,
    /// Principal point x, px (the crate's pixel convention).
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
}

impl CameraRays for Pinhole {
    fn pixel_to_ray(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        Some([(x - self.cx) / self.f, (y - self.cy) / self.f, 1.0])
    }
    fn ray_to_pixel(&self, r: [f64; 3]) -> Option<[f64; 2]> {
        if r[2] <= 0.0 {
            return None;
        }
        Some([
            self.cx + self.f * r[0] / r[2],
            self.cy + self.f * r[1] / r[2],
        ])
    }
}

/// The sphere's centre recovered from its outline.
#[derive(Clone, Copy, Debug)]
pub struct SphereCentre {
    /// Image of the sphere's centre: x, px (the projection of its centre, not the centre of
    /// the outline).
    pub x: f64,
    /// Image of the sphere's centre: y, px.
    pub y: f64,
    /// Unit direction to the centre (camera frame of the [`CameraRays`]).
    pub axis: [f64; 3],
    /// Half-angle of the silhouette cone (radians).
    pub half_angle: f64,
    /// Distance to the centre, when the radius was given (same unit as the radius).
    pub distance: Option<f64>,
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 0.0 && n.is_finite() {
        Some([v[0] / n, v[1] / n, v[2] / n])
    } else {
        None
    }
}

/// Cone fit to outline points (at least 5, spread around the outline). `radius`: the sphere's
/// radius, to get the distance.
pub fn sphere_centre_from_outline(
    points: &[(f64, f64)],
    cam: &dyn CameraRays,
    radius: Option<f64>,
) -> Option<SphereCentre> {
    if points.len() < 5 {
        return None;
    }
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for &(x, y) in points {
        let q = unit(cam.pixel_to_ray(x, y)?)?;
        let q = nalgebra::Vector3::new(q[0], q[1], q[2]);
        ata += q * q.transpose();
        atb += q;
    }
    let v = ata.try_inverse()? * atb;
    let n = v.norm();
    if !(n > 1.0) || !n.is_finite() {
        return None;
    }
    let w = [v[0] / n, v[1] / n, v[2] / n];
    let cos_a = 1.0 / n;
    let half_angle = cos_a.acos();
    let p = cam.ray_to_pixel(w)?;
    let distance = radius.map(|r| r / half_angle.sin());
    Some(SphereCentre {
        x: p[0],
        y: p[1],
        axis: w,
        half_angle,
        distance,
    })
}

/// Cone fit to 72 points of a silhouette ellipse.
pub fn sphere_centre_from_ellipse(
    e: &Ellipse,
    cam: &dyn CameraRays,
    radius: Option<f64>,
) -> Option<SphereCentre> {
    let pts: Vec<(f64, f64)> = (0..72)
        .map(|i| e.point(i as f64 * std::f64::consts::PI / 36.0))
        .collect();
    sphere_centre_from_outline(&pts, cam, radius)
}

/// The closed form (docs/method.md, "A ball in an image"): the bisector of the rays through the two ends of the major
/// axis (exact for an undistorted camera).
pub fn sphere_centre_major_axis(
    e: &Ellipse,
    cam: &dyn CameraRays,
    radius: Option<f64>,
) -> Option<SphereCentre> {
    let (x1, y1) = e.map(1.0, 0.0);
    let (x2, y2) = e.map(-1.0, 0.0);
    let q1 = unit(cam.pixel_to_ray(x1, y1)?)?;
    let q2 = unit(cam.pixel_to_ray(x2, y2)?)?;
    let w = unit([q1[0] + q2[0], q1[1] + q2[1], q1[2] + q2[2]])?;
    let dot = (q1[0] * q2[0] + q1[1] * q2[1] + q1[2] * q2[2]).clamp(-1.0, 1.0);
    let half_angle = dot.acos() / 2.0;
    let p = cam.ray_to_pixel(w)?;
    Some(SphereCentre {
        x: p[0],
        y: p[1],
        axis: w,
        half_angle,
        distance: radius.map(|r| r / half_angle.sin()),
    })
}

/// The refinement settings of a ball: balls are not retro-reflective (lower contrast) and
/// their limb is shaded, so the tolerances are wider than a target's.
fn ball_params() -> CentreParams {
    CentreParams {
        min_contrast: 0.02,
        max_rms: (0.5, 0.04),
        ..CentreParams::default()
    }
}

/// Fits a ball's silhouette from a rough outline `seed` (e.g. a detected target of kind
/// `ball`): sub-pixel edge points at the mid level and a robust ellipse fit.
pub fn fit_ball_silhouette(img: &GrayImage, seed: &Ellipse) -> Result<Refined, Reject> {
    refine(img, seed, &ball_params())
}

/// The sub-pixel edge points of a ball's silhouette fitted by [`fit_ball_silhouette`],
/// found as in the fit's final round around its ellipse (one per pixel of perimeter, in
/// order around the outline), for [`crate::silhouette::sphere_centre_from_edges`]: the cone
/// fitted to them in ray space, whatever shape the lens gives the outline.
pub fn ball_silhouette_edges(img: &GrayImage, fit: &Refined) -> Result<Vec<(f64, f64)>, Reject> {
    let (edges, _) = edge_points(img, &fit.ellipse, fit.fg, &ball_params(), Round::Final)?;
    Ok(edges)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact silhouette from the formulas of docs/method.md; both recoveries must give the true projection.
    #[test]
    fn exact_silhouette_recovers_projected_centre() {
        let cam = Pinhole {
            f: 650.0,
            cx: 640.0,
            cy: 360.0,
        };
        let (cx, cy, cz, r) = (300.0f64, -150.0f64, 500.0f64, 19.0f64);
        // Silhouette in normalised coordinates, then to pixels.
        let p = [cx / cz, cy / cz];
        let k = cz * cz / (cz * cz - r * r);
        let e_n = [p[0] * k, p[1] * k];
        let a = r * (cx * cx + cy * cy + cz * cz - r * r).sqrt() / (cz * cz - r * r);
        let b = r / (cz * cz - r * r).sqrt();
        let theta = p[1].atan2(p[0]);
        let e = Ellipse {
            cx: cam.cx + cam.f * e_n[0],
            cy: cam.cy + cam.f * e_n[1],
            a: a * cam.f,
            b: b * cam.f,
            theta,
        };
        let truth = [cam.cx + cam.f * p[0], cam.cy + cam.f * p[1]];
        let naive = ((e.cx - truth[0]).powi(2) + (e.cy - truth[1]).powi(2)).sqrt();
        assert!(naive > 0.5, "eccentricity should be visible here: {naive}");
        for s in [
            sphere_centre_from_ellipse(&e, &cam, Some(r)).unwrap(),
            sphere_centre_major_axis(&e, &cam, Some(r)).unwrap(),
        ] {
            assert!(
                (s.x - truth[0]).abs() < 1e-6 && (s.y - truth[1]).abs() < 1e-6,
                "{s:?} vs {truth:?}"
            );
            let d = (cx * cx + cy * cy + cz * cz).sqrt();
            assert!(
                (s.distance.unwrap() - d).abs() < 1e-4,
                "{} vs {d}",
                s.distance.unwrap()
            );
        }
    }
}
