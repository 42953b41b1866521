//! A camera in the models other ecosystems' files hold, each with what it loses.
//!
//! | file | holds | from pingcal's models |
//! |---|---|---|
//! | OpenCV (FileStorage YAML, `cv2`) | pinhole with 5, 8 or 12 coefficients (`plumb_bob`, `rational_polynomial`, `thin_prism`), or `cv::fisheye` (k1–k4) | photogrammetric: closed form (B1 to first order in fx, B2 dropped); opencv: itself; kannala-brandt: itself (fisheye); brown-backward: plumb_bob fitted; double-sphere: fisheye fitted |
//! | ROS `camera_info` | `plumb_bob`, `rational_polynomial` or `equidistant` | as OpenCV's, but a thin prism is fitted away (rational_polynomial) |
//! | Kalibr camchain | `pinhole` + `radtan` (k1 k2 r1 r2), `pinhole` + `equidistant` (k1–k4), `ds` | radtan fitted for the pinhole models, equidistant exact for kannala-brandt, ds exact for double-sphere |
//!
//! Every form is a model of this crate ([`super::OpenCvCamera`], [`super::FisheyeCamera`],
//! [`super::DoubleSphereCamera`]) with parameters, so its loss against the source is measured the
//! same way for all ([`super::refit::GridRays::loss`]); a fitted form is the least-squares
//! one over the grid ([`super::refit::refit`]).

use super::refit::{refit, GridRays, Loss};
use super::ModelKind;

/// The ecosystems a camera is written for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ecosystem {
    /// OpenCV's FileStorage YAML (`cv2.projectPoints`, `cv2.fisheye.projectPoints`).
    OpenCv,
    /// ROS's `camera_info` (camera_calibration_parsers).
    Ros,
    /// Kalibr's camchain.
    Kalibr,
}

/// A camera as one ecosystem's file holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct Form {
    /// The model in this crate that projects as the file does.
    pub kind: ModelKind,
    /// Its parameters, in `kind`'s slice order.
    pub params: Vec<f64>,
    /// The file's name of its distortion model: `plumb_bob`, `rational_polynomial`,
    /// `thin_prism`, `fisheye` (OpenCV), `equidistant` (ROS, Kalibr), `radtan`, `none`
    /// (Kalibr's `ds`).
    pub distortion_model: &'static str,
    /// The file's name of its camera model: `pinhole`, `fisheye` (OpenCV), `ds` (Kalibr).
    pub camera_model: &'static str,
    /// The distortion coefficients in the file's order.
    pub coeffs: Vec<f64>,
    /// Whether it was fitted to the source over the grid (else converted in closed form).
    pub fitted: bool,
    /// Whether fx, fy, cx, cy were fitted too (else the closed form's).
    pub intrinsics_fitted: bool,
    /// Its loss against the source over the grid.
    pub loss: Loss,
}

impl Form {
    /// fx, fy, cx, cy (px); for the double sphere Kalibr's `[xi, alpha, fu, fv, pu, pv]`
    /// come from [`Form::params`].
    pub fn k(&self) -> [f64; 4] {
        [
            self.params[0],
            self.params[1],
            self.params[2],
            self.params[3],
        ]
    }
}

/// OpenCV's names of its pinhole model's distortion coefficients, in its order.
pub const OPENCV_COEFFICIENTS: [&str; 12] = [
    "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
];

impl Form {
    /// Whether it is OpenCV's fisheye model (`cv::fisheye`).
    pub fn is_opencv_fisheye(&self) -> bool {
        self.camera_model == "fisheye"
    }

    /// The names of its distortion coefficients [`Form::coeffs`] in the file's order.
    pub fn coefficient_names(&self) -> &'static [&'static str] {
        match self.distortion_model {
            "fisheye" | "equidistant" => &["k1", "k2", "k3", "k4"],
            "radtan" => &["k1", "k2", "r1", "r2"],
            "none" => &[],
            _ => &OPENCV_COEFFICIENTS[..self.coeffs.len().min(12)],
        }
    }

    /// Fx, fy, cx, cy and OpenCV's twelve coefficients when it is OpenCV's pinhole model
    /// (`None` for a fisheye or a double sphere).
    pub fn opencv_pinhole(&self) -> Option<([f64; 4], [f64; 12])> {
        if self.camera_model != "pinhole" || self.kind != ModelKind::OpenCv {
            return None;
        }
        let mut dist = [0.0; 12];
        dist.copy_from_slice(&self.params[4..16]);
        Some((self.k(), dist))
    }

    /// Its intrinsics as Kalibr's camchain lists them: `[xi, alpha, fu, fv, pu, pv]` for
    /// `ds`, `[fu, fv, pu, pv]` otherwise.
    pub fn kalibr_intrinsics(&self) -> Vec<f64> {
        match self.camera_model {
            "ds" => {
                let p = &self.params;
                vec![p[4], p[5], p[0], p[1], p[2], p[3]]
            }
            _ => self.k().to_vec(),
        }
    }
}

/// The OpenCV parameter slice (16) of pinhole intrinsics `k` and coefficients.
fn opencv_params(k: [f64; 4], d: &[f64]) -> Vec<f64> {
    let mut p = vec![0.0; 16];
    p[..4].copy_from_slice(&k);
    p[4..4 + d.len()].copy_from_slice(d);
    p
}

/// The photogrammetric parameters `p` of a `width × height` sensor of pitch `pixel_mm` in
/// OpenCV's pinhole model, in closed form: fx = c (1 + B1)/pitch, fy = c/pitch, the
/// principal point moved from the array centre, k1 = K1 c², k2 = K2 c⁴, k3 = K3 c⁶, p1 =
/// −P2 c, p2 = P1 c (OpenCV's y is down). B1 is kept to first order only; B2 (shear) is
/// dropped. Returns fx, fy, cx, cy and k1 k2 p1 p2 k3.
pub fn opencv_of_photogrammetric(
    p: &[f64],
    width: u32,
    height: u32,
    pixel_mm: f64,
) -> ([f64; 4], [f64; 5]) {
    let c = p[0];
    (
        [
            c * (1.0 + p[8]) / pixel_mm,
            c / pixel_mm,
            (width as f64 - 1.0) / 2.0 + p[1] / pixel_mm,
            (height as f64 - 1.0) / 2.0 - p[2] / pixel_mm,
        ],
        [
            p[3] * c * c,
            p[4] * c.powi(4),
            -p[7] * c,
            p[6] * c,
            p[5] * c.powi(6),
        ],
    )
}

/// The OpenCV coefficients `d` (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4) cut to the shortest of
/// OpenCV's lengths that holds every non-zero one, with its name.
fn opencv_length(d: &[f64]) -> (usize, &'static str) {
    let last = d.iter().rposition(|v| *v != 0.0).map_or(0, |k| k + 1);
    match last {
        0..=5 => (5, "plumb_bob"),
        6..=8 => (8, "rational_polynomial"),
        _ => (12, "thin_prism"),
    }
}

/// A pinhole form of intrinsics `k` and OpenCV coefficients `d` (the first 12 of OpenCV's
/// order), its loss over `grid`.
fn pinhole(k: [f64; 4], d: &[f64], fitted: bool, grid: &GridRays, intr_fitted: bool) -> Form {
    let (n, name) = opencv_length(d);
    let params = opencv_params(k, &d[..n.min(d.len())]);
    let loss = grid.loss(&super::OpenCvCamera, &params);
    Form {
        kind: ModelKind::OpenCv,
        coeffs: params[4..4 + n].to_vec(),
        params,
        distortion_model: name,
        camera_model: "pinhole",
        fitted,
        intrinsics_fitted: intr_fitted,
        loss,
    }
}

/// A Kannala–Brandt form of `p` (fx fy cx cy k1–k4).
fn equidistant(
    p: Vec<f64>,
    fitted: bool,
    grid: &GridRays,
    name: &'static str,
    cam: &'static str,
) -> Form {
    let loss = grid.loss(&super::FisheyeCamera, &p);
    Form {
        kind: ModelKind::KannalaBrandt,
        coeffs: p[4..8].to_vec(),
        params: p,
        distortion_model: name,
        camera_model: cam,
        fitted,
        intrinsics_fitted: fitted,
        loss,
    }
}

/// The least-squares pinhole form with the first `n_coeffs` of OpenCV's coefficients free
/// (and fx fy cx cy when `intrinsics`), from `k` and `d`.
fn fitted_pinhole(
    grid: &GridRays,
    k: [f64; 4],
    d: &[f64],
    n_coeffs: usize,
    intrinsics: bool,
) -> Option<Form> {
    let mut start = opencv_params(k, &d[..d.len().min(12)]);
    let free: Vec<bool> = (0..16)
        .map(|j| (j < 4 && intrinsics) || (4..4 + n_coeffs).contains(&j))
        .collect();
    start[4 + n_coeffs..].fill(0.0);
    let (p, _) = refit(grid, &super::OpenCvCamera, &start, &free)?;
    Some(pinhole(
        [p[0], p[1], p[2], p[3]],
        &p[4..4 + n_coeffs],
        true,
        grid,
        intrinsics,
    ))
}

/// The better of the fit with fx fy cx cy held and the one with them free: the second only
/// when it lowers the largest loss by a hundredth of a pixel or more (so the file's
/// intrinsics stay the other files' where that costs nothing).
fn best_pinhole(grid: &GridRays, k: [f64; 4], d: &[f64], n_coeffs: usize) -> Option<Form> {
    let held = fitted_pinhole(grid, k, d, n_coeffs, false);
    let free = fitted_pinhole(grid, k, d, n_coeffs, true);
    match (held, free) {
        (Some(a), Some(b)) if b.loss.max_px <= a.loss.max_px - 0.01 => Some(b),
        (Some(a), _) => Some(a),
        (None, b) => b,
    }
}

/// The source camera of a conversion: its model kind and parameters, its sensor, and the
/// rays of the loss grid through it.
pub struct Source<'a> {
    /// The model.
    pub kind: ModelKind,
    /// Its parameters.
    pub params: &'a [f64],
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Pixel pitch, mm.
    pub pixel_size_mm: f64,
    /// The loss grid's rays through the model.
    pub grid: &'a GridRays,
}

impl Source<'_> {
    /// The photogrammetric parameters' closed-form pinhole ([`opencv_of_photogrammetric`]).
    fn closed_form(&self) -> ([f64; 4], [f64; 5]) {
        opencv_of_photogrammetric(self.params, self.width, self.height, self.pixel_size_mm)
    }

    /// A Kannala–Brandt start (fx fy cx cy, no distortion).
    fn equidistant_start(&self) -> Vec<f64> {
        let m = self.kind.model(self.width, self.height, self.pixel_size_mm);
        let (f, c) = (m.focal_px(self.params), m.principal_point_px(self.params));
        vec![f, f, c.x, c.y, 0.0, 0.0, 0.0, 0.0]
    }
}

/// The camera `src` as `eco`'s file holds it, with its loss; `None` where a fit fails (a
/// grid the source model gives no ray on). Each model's forms are its registry line's
/// ([`super::kind::ModelEntry::forms`]).
pub fn form(src: &Source, eco: Ecosystem) -> Option<Form> {
    (src.kind.entry().forms)(src, eco)
}

/// Kalibr's radtan: k1 k2 r1 r2 (OpenCV's k1 k2 p1 p2, no k3), fitted from `k`, `d`.
fn radtan(g: &GridRays, k: [f64; 4], d: &[f64]) -> Option<Form> {
    let mut f = best_pinhole(g, k, d, 4)?;
    f.distortion_model = "radtan";
    f.coeffs.truncate(4);
    Some(f)
}

/// The photogrammetric model: OpenCV's and ROS's pinhole in closed form, Kalibr's radtan
/// fitted.
pub(crate) fn photogrammetric_forms(src: &Source, eco: Ecosystem) -> Option<Form> {
    let (k, d) = src.closed_form();
    match eco {
        Ecosystem::OpenCv | Ecosystem::Ros => Some(pinhole(k, &d, false, src.grid, false)),
        Ecosystem::Kalibr => radtan(src.grid, k, &d),
    }
}

/// Brown backward: every form fitted, from the closed form's intrinsics and no distortion
/// (its coefficients correct the measured point).
pub(crate) fn brown_backward_forms(src: &Source, eco: Ecosystem) -> Option<Form> {
    let (k, _) = src.closed_form();
    match eco {
        Ecosystem::OpenCv | Ecosystem::Ros => best_pinhole(src.grid, k, &[0.0; 5], 5),
        Ecosystem::Kalibr => radtan(src.grid, k, &[0.0; 5]),
    }
}

/// OpenCV's model: itself in OpenCV's file, in ROS's unless it has a thin prism (then
/// the rational model fitted), Kalibr's radtan fitted.
pub(crate) fn opencv_forms(src: &Source, eco: Ecosystem) -> Option<Form> {
    let (g, p) = (src.grid, src.params);
    let k = [p[0], p[1], p[2], p[3]];
    match eco {
        Ecosystem::OpenCv => Some(pinhole(k, &p[4..16], false, g, false)),
        Ecosystem::Ros => {
            let f = pinhole(k, &p[4..16], false, g, false);
            if f.distortion_model != "thin_prism" {
                return Some(f);
            }
            best_pinhole(g, k, &p[4..16], 8)
        }
        Ecosystem::Kalibr => radtan(g, k, &p[4..16]),
    }
}

/// Kannala–Brandt: itself everywhere (OpenCV's fisheye, ROS's and Kalibr's equidistant).
pub(crate) fn kannala_brandt_forms(src: &Source, eco: Ecosystem) -> Option<Form> {
    let (name, cam) = match eco {
        Ecosystem::OpenCv => ("fisheye", "fisheye"),
        Ecosystem::Ros | Ecosystem::Kalibr => ("equidistant", "pinhole"),
    };
    Some(equidistant(src.params.to_vec(), false, src.grid, name, cam))
}

/// The double sphere: itself in Kalibr's `ds`, a fitted Kannala–Brandt in OpenCV's and
/// ROS's files.
pub(crate) fn double_sphere_forms(src: &Source, eco: Ecosystem) -> Option<Form> {
    let g = src.grid;
    let (name, cam) = match eco {
        Ecosystem::OpenCv => ("fisheye", "fisheye"),
        Ecosystem::Ros => ("equidistant", "pinhole"),
        Ecosystem::Kalibr => {
            let loss = g.loss(&super::DoubleSphereCamera, src.params);
            return Some(Form {
                kind: ModelKind::DoubleSphere,
                params: src.params.to_vec(),
                distortion_model: "none",
                camera_model: "ds",
                coeffs: Vec::new(),
                fitted: false,
                intrinsics_fitted: false,
                loss,
            });
        }
    };
    let (fitted, _) = refit(
        g,
        &super::FisheyeCamera,
        &src.equidistant_start(),
        &[true; 8],
    )?;
    Some(equidistant(fitted, true, g, name, cam))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn grid(w: u32, h: u32) -> Vec<Vector2<f64>> {
        (0..=32)
            .flat_map(|j| {
                (0..=32).map(move |i| {
                    Vector2::new(
                        (w - 1) as f64 * i as f64 / 32.0,
                        (h - 1) as f64 * j as f64 / 32.0,
                    )
                })
            })
            .collect()
    }

    fn source<'a>(kind: ModelKind, p: &'a [f64], g: &'a GridRays) -> Source<'a> {
        Source {
            kind,
            params: p,
            width: 1280,
            height: 720,
            pixel_size_mm: 0.00375,
            grid: g,
        }
    }

    #[test]
    fn exact_forms_lose_nothing_and_fits_state_their_loss() {
        let cases: Vec<(ModelKind, Vec<f64>)> = vec![
            (
                ModelKind::Photogrammetric,
                vec![
                    2.45, 0.012, -0.009, -0.021, 4e-4, -2e-6, 1.5e-4, -1e-4, 0.0, 0.0,
                ],
            ),
            (
                ModelKind::OpenCv,
                vec![
                    420.0, 421.0, 641.0, 359.0, 0.05, 0.0, 1e-4, -1.2e-4, 0.0, 0.3, 0.0, 0.0, 0.0,
                    0.0, 0.0, 0.0,
                ],
            ),
            (
                ModelKind::KannalaBrandt,
                vec![386.0, 386.5, 641.0, 359.0, 0.02, -0.005, 0.001, -1e-4],
            ),
            (
                ModelKind::DoubleSphere,
                vec![310.0, 310.4, 641.0, 359.0, -0.2, 0.58],
            ),
        ];
        for (kind, p) in &cases {
            let m = kind.model(1280, 720, 0.00375);
            let g = GridRays::of(m.as_ref(), p, &grid(1280, 720));
            let s = source(*kind, p, &g);
            for eco in [Ecosystem::OpenCv, Ecosystem::Ros, Ecosystem::Kalibr] {
                let f = form(&s, eco).unwrap_or_else(|| panic!("{kind:?} {eco:?}"));
                let exact = !f.fitted;
                if exact && *kind != ModelKind::Photogrammetric {
                    assert!(f.loss.max_px < 1e-9, "{kind:?} {eco:?}: {:?}", f.loss);
                }
                assert!(f.loss.max_px.is_finite(), "{kind:?} {eco:?}");
            }
        }
        // the photogrammetric model without B1, B2 converts exactly to plumb_bob
        let (kind, p) = &cases[0];
        let g = GridRays::of(kind.model(1280, 720, 0.00375).as_ref(), p, &grid(1280, 720));
        let f = form(&source(*kind, p, &g), Ecosystem::OpenCv).unwrap();
        assert!(
            f.loss.max_px < 1e-8 && f.distortion_model == "plumb_bob",
            "{:?}",
            f.loss
        );
        // a rational lens needs 8 coefficients; Kalibr's radtan refit loses something
        let (kind, p) = &cases[1];
        let g = GridRays::of(kind.model(1280, 720, 0.00375).as_ref(), p, &grid(1280, 720));
        let s = source(*kind, p, &g);
        assert_eq!(
            form(&s, Ecosystem::Ros).unwrap().distortion_model,
            "rational_polynomial"
        );
        let k = form(&s, Ecosystem::Kalibr).unwrap();
        assert!(k.fitted && k.distortion_model == "radtan" && k.coeffs.len() == 4);
        assert!(k.loss.max_px > 1e-3, "{:?}", k.loss);
    }
}
