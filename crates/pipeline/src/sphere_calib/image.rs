//! The camera side of one frame: the sphere's silhouettes in the photograph
//! ([`pingcal_targets::silhouette`]: edges from the colour gradient, candidate circles, the
//! silhouette cone fitted to the visible outline through the camera's own model), each as an
//! [`ImageSphere`] with its centre in the camera frame and that centre's covariance; and the
//! published closed form beside it ([`closed_form_centre`]).

use super::camera::Camera;
use nalgebra::{Matrix3, Vector3};
use pingcal_targets::ball::{sphere_centre_major_axis, FnCamera};
use pingcal_targets::centre::robust_ellipse_fit;
use pingcal_targets::ellipse::Ellipse;
use pingcal_targets::silhouette::{self, refine, ColourImage, Fit, SilhouetteOptions};

type V3 = Vector3<f64>;
/// An image point, pixels.
pub type Pixel = (f64, f64);

/// The sphere's centre in the camera frame from its silhouette.
#[derive(Debug, Clone)]
pub struct ImageSphere {
    /// The image of the centre's direction, px.
    pub image_centre: Pixel,
    /// The silhouette's mean radius, px.
    pub radius_px: f64,
    /// The ellipse fitted to the edge points used (pixels; `None` when it does not fit).
    pub ellipse: Option<Ellipse>,
    /// Edge points used by the centre fit.
    pub edges: usize,
    /// RMS of their residuals, pixels.
    pub rms_px: f64,
    /// The edge's blur (σ of a Gaussian, pixels) measured from its profile.
    pub sigma_blur_px: f64,
    /// Centre, mm (camera frame).
    pub centre: V3,
    /// Its covariance, mm² (the fit's, times the variance inflation of the edge residuals'
    /// correlation along the outline).
    pub cov: Matrix3<f64>,
    /// That inflation factor.
    pub inflation: f64,
    /// The fraction of the outline that the edge points used cover.
    pub coverage: f64,
    /// The fraction of the outline inside the image.
    pub visible: f64,
    /// The published closed form's centre (ellipse of the undistorted plain edge points,
    /// the bisector of its major axis' end rays, d = √2·r/√(1 − q₁·q₂)), mm; `None` when
    /// those edge points give no ellipse.
    pub closed_form: Option<V3>,
    /// The fitted outline (for the overlays), px.
    pub outline: Vec<Pixel>,
    /// The edge points used, px.
    pub edge_points: Vec<Pixel>,
    /// Edge points found and rejected by the fit (a stand, a highlight), px.
    pub rejected: Vec<Pixel>,
}

/// The closed form of Tóth et al. (docs/method.md, "A ball in an image"): an ellipse fitted to
/// the undistorted edge points, the two ends of its major axis as unit rays q₁, q₂,
/// w = normalize(q₁ + q₂), d = √2·r/√(1 − q₁·q₂), C = d·w. Camera frame of `cam`.
pub fn closed_form_centre(edges: &[Pixel], cam: &Camera, r: f64) -> Option<V3> {
    let f = cam.f_px();
    // the ideal pinhole image (x right, y down, in pixels of focal length f) of each edge ray
    let ideal: Vec<(f64, f64)> = edges
        .iter()
        .filter_map(|&(x, y)| {
            let q = cam.ray(x, y)?;
            (q.y > 0.0).then(|| (f * q.x / q.y, -f * q.z / q.y))
        })
        .collect();
    let (e, _, _) = robust_ellipse_fit(&ideal)?;
    let pin = FnCamera(
        move |x: f64, y: f64| Some([x / f, 1.0, -y / f]),
        move |q: [f64; 3]| (q[1] > 0.0).then(|| [f * q[0] / q[1], -f * q[2] / q[1]]),
    );
    let s = sphere_centre_major_axis(&e, &pin, Some(r))?;
    Some(V3::from(s.axis) * s.distance?)
}

/// An [`ImageSphere`] of a silhouette fit.
pub fn image_sphere(f: Fit, cam: &Camera, r: f64) -> ImageSphere {
    let closed_form = closed_form_centre(&f.raw_edges, cam, r);
    let ellipse = robust_ellipse_fit(&f.raw_edges).map(|e| e.0);
    ImageSphere {
        image_centre: f.image_centre,
        radius_px: f.radius_px,
        ellipse,
        edges: f.edges.len(),
        rms_px: f.rms_px,
        sigma_blur_px: f.sigma_blur_px,
        centre: f.centre,
        cov: f.cov,
        inflation: f.inflation,
        coverage: f.coverage,
        visible: f.visible,
        closed_form,
        outline: f.outline,
        edge_points: f.edges,
        rejected: f.rejected,
    }
}

/// The options of the image side for a sphere of radius `r` (mm) in `cam`'s images.
pub fn options(cam: &Camera, r: f64) -> SilhouetteOptions {
    SilhouetteOptions::new(r, cam.sensor.width as usize, cam.sensor.height as usize)
}

/// Every silhouette of a sphere of radius `r` in `img` (see
/// [`pingcal_targets::silhouette::find_silhouettes`]), by decreasing coverage.
pub fn candidates(img: &ColourImage, cam: &Camera, r: f64) -> Vec<ImageSphere> {
    silhouette::find_silhouettes(img, cam, &options(cam, r))
        .into_iter()
        .map(|f| image_sphere(f, cam, r))
        .collect()
}

/// The silhouettes near a predicted centre `c` (camera frame, mm) whose σ is about
/// `sigma_mm`, by decreasing coverage: fits started at the prediction (searching first 3 px
/// plus four times that σ in the image either side of the outline, at most a third of its
/// radius) and at every circle of the predicted size the Hough transform finds within half
/// the outline's radius of the predicted place (a partly hidden outline can lead the first
/// astray). Only accepted fits are returned.
pub fn at_prediction(
    img: &ColourImage,
    cam: &Camera,
    r: f64,
    c: &V3,
    sigma_mm: f64,
) -> Vec<ImageSphere> {
    let Some((centre, rho)) = predicted_circle(cam, c, r) else {
        return Vec::new();
    };
    let d = c.norm();
    let reach = (3.0 + 4.0 * sigma_mm / d * cam.f_px())
        .min(rho / 3.0)
        .max(3.0);
    let mut starts = vec![(*c, reach)];
    let opts = SilhouetteOptions {
        radius_px: (0.7 * rho, 1.3 * rho),
        window: Some((centre.0, centre.1, (0.5 * rho).max(10.0))),
        ..options(cam, r)
    };
    for (k, s) in silhouette::candidates(img, &opts) {
        if let Some(c0) = silhouette::centre_of_circle(&k, cam, r) {
            starts.push((c0, silhouette::start_width(&k, s)));
        }
    }
    let mut fits: Vec<ImageSphere> = starts
        .into_iter()
        .filter_map(|(c0, w0)| refine::refine(img, cam, r, c0, w0))
        .filter(|f| silhouette::accepted(f, &options(cam, r)))
        .map(|f| image_sphere(f, cam, r))
        .collect();
    fits.sort_by(|a, b| b.coverage.total_cmp(&a.coverage));
    fits
}

/// The image of the sphere of radius `r` at `c`: its centre's pixel and the outline's mean
/// distance from it (px), through the camera model.
fn predicted_circle(cam: &Camera, c: &V3, r: f64) -> Option<(Pixel, f64)> {
    let centre = cam.project(c)?;
    let pts: Vec<Pixel> = silhouette::cone::cone_rays(c, r, 36)?
        .iter()
        .filter_map(|q| cam.project(q))
        .collect();
    (pts.len() >= 12).then(|| {
        let rho = pts
            .iter()
            .map(|p| (p.0 - centre.0).hypot(p.1 - centre.1))
            .sum::<f64>()
            / pts.len() as f64;
        (centre, rho)
    })
}
