//! A chessboard corner's sub-pixel position: the point that every image gradient around it
//! is orthogonal to (the gradient at an edge pixel is orthogonal to the edge, which runs
//! through the corner; in a flat square the gradient is zero and weighs nothing).

use crate::raster::GrayImage;
use nalgebra::{Matrix2, Vector2};

/// Iterations at most.
const MAX_ITERATIONS: usize = 30;
/// Stop when a step is shorter than this (px).
const CONVERGED_PX: f64 = 1e-4;
/// The σ never reported below this (px): the gradients of neighbouring pixels are not
/// independent, so the fit's own σ is optimistic for the sharpest corners.
const SIGMA_FLOOR_PX: f64 = 0.01;

/// A refined corner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubPixel {
    /// Position (px).
    pub uv: [f64; 2],
    /// σ per coordinate (px).
    pub sigma_px: f64,
}

/// The half width of the gradient window for a corner whose nearest neighbour on the board
/// is `spacing` px away: a third of it, 3 to `7 · scale` px (`scale` > 1 for a board found
/// on a coarser level of the image, whose corners are as wide).
pub fn half_window(spacing: f64, scale: usize) -> i64 {
    if spacing.is_finite() {
        ((spacing / 3.0).round() as i64).clamp(3, 7 * scale.max(1) as i64)
    } else {
        5
    }
}

/// Refines `start` (px) in `img`; the local square side is `spacing` px, the board was
/// found at level `scale` ([`half_window`]). A fit that runs away (further than the window
/// from the start) keeps the start, with a σ of half the window.
pub fn refine(img: &GrayImage, start: [f64; 2], spacing: f64, scale: usize) -> SubPixel {
    refine_in(img, start, half_window(spacing, scale))
}

/// Refines `start` (px) in `img` with a gradient window of half width `half` px (for corners
/// whose neighbourhood is not a plain chessboard's: a marker's edge nearer than a third of
/// the square). A fit that runs away keeps the start, with a σ of half the window.
pub fn refine_in(img: &GrayImage, start: [f64; 2], half: i64) -> SubPixel {
    let mut q = Vector2::new(start[0], start[1]);
    for _ in 0..MAX_ITERATIONS {
        let Some((normal, rhs)) = normal_equations(img, q, half) else {
            break;
        };
        let Some(next) = normal.try_inverse().map(|inv| inv * rhs) else {
            break;
        };
        if (next - Vector2::new(start[0], start[1])).norm() > half as f64 {
            return SubPixel {
                uv: start,
                sigma_px: 0.5 * half as f64,
            };
        }
        let step = (next - q).norm();
        q = next;
        if step < CONVERGED_PX {
            break;
        }
    }
    SubPixel {
        uv: [q.x, q.y],
        sigma_px: sigma(img, q, half).max(SIGMA_FLOOR_PX),
    }
}

/// The image gradient at a pixel (central differences), `None` at the border.
fn gradient(img: &GrayImage, x: i64, y: i64) -> Option<Vector2<f64>> {
    if x < 1 || y < 1 || x + 1 >= img.width as i64 || y + 1 >= img.height as i64 {
        return None;
    }
    let (x, y) = (x as usize, y as usize);
    Some(Vector2::new(
        0.5 * (img.get(x + 1, y) - img.get(x - 1, y)) as f64,
        0.5 * (img.get(x, y + 1) - img.get(x, y - 1)) as f64,
    ))
}

/// The window's pixels around `q`: position, gradient and Gaussian weight.
fn window(
    img: &GrayImage,
    q: Vector2<f64>,
    half: i64,
) -> impl Iterator<Item = (Vector2<f64>, Vector2<f64>, f64)> + '_ {
    let (cx, cy) = (q.x.round() as i64, q.y.round() as i64);
    let inv = 1.0 / (half * half) as f64;
    (-half..=half).flat_map(move |dy| {
        (-half..=half).filter_map(move |dx| {
            let (x, y) = (cx + dx, cy + dy);
            let g = gradient(img, x, y)?;
            let p = Vector2::new(x as f64, y as f64);
            let w = (-(p - q).norm_squared() * inv).exp();
            Some((p, g, w))
        })
    })
}

/// `Σ w g gᵀ` and `Σ w g gᵀ p` over the window around `q`.
fn normal_equations(
    img: &GrayImage,
    q: Vector2<f64>,
    half: i64,
) -> Option<(Matrix2<f64>, Vector2<f64>)> {
    let mut a = Matrix2::zeros();
    let mut b = Vector2::zeros();
    for (p, g, w) in window(img, q, half) {
        let ggt = g * g.transpose() * w;
        a += ggt;
        b += ggt * p;
    }
    (a.determinant() > 1e-12).then_some((a, b))
}

/// The σ per coordinate of the fit at `q`: the sandwich covariance
/// `A⁻¹ (Σ w² ε² g gᵀ) A⁻¹` with `ε = g · (p − q)`.
fn sigma(img: &GrayImage, q: Vector2<f64>, half: i64) -> f64 {
    let mut a = Matrix2::zeros();
    let mut meat = Matrix2::zeros();
    for (p, g, w) in window(img, q, half) {
        let ggt = g * g.transpose();
        let e = g.dot(&(p - q));
        a += ggt * w;
        meat += ggt * (w * w * e * e);
    }
    match a.try_inverse() {
        Some(inv) => (0.5 * (inv * meat * inv).trace()).max(0.0).sqrt(),
        None => 0.5 * half as f64,
    }
}
