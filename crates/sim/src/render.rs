//! Image formation by ray casting.
//!
//! For every pixel the ray is the exact back-projection of the pixel (`unproject` of the
//! camera model: perspective and distortion, no approximation). Pixels whose footprint may
//! touch a target, ball or stem (their projected bounding boxes, found by projecting their
//! outlines) are supersampled with n×n sub-pixel rays, each unprojected exactly; other
//! pixels (plain wall or floor) take one ray through the pixel centre, from a per-camera
//! table. The radiance model, in fractions of full scale:
//!
//! * flash at the projection centre: irradiance `flash_at_1m · cos i / d²` (d in m), plus
//!   an ambient term;
//! * walls and floor: matt (Lambertian) with a procedural paint texture;
//! * targets: black print, and retro-reflective dot and ring sectors whose brightness is
//!   `retro_gain · flash_at_1m · cos e / d²` at the target centre (uniform over a target,
//!   so it does not bias the centroid; brighter for targets facing the flash and near it);
//! * balls: white, 70 % Lambertian and 30 % uniformly glowing (translucent celluloid), so
//!   somewhat darker towards the limb; stems grey.
//!
//! Then Gaussian blur (optics and defocus), vignetting (quadratic fall-off to the corner),
//! photon noise (Poisson, as a Gaussian in electrons), read noise, 8-bit quantisation.

use crate::config::RenderConfig;
use crate::rng_for;
use crate::scene::{HitKind, Object, TestField};
use crate::stations::CameraUnit;
use nalgebra::{Vector2, Vector3};
use pingcal_ba::camera::CameraModel;
use pingcal_geometry::Rigid3;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

type V3 = Vector3<f64>;

/// Unit rays (camera frame) through every pixel centre of a camera, computed once.
#[derive(Debug, Clone)]
pub struct RayTable {
    width: u32,
    rays: Vec<[f32; 3]>,
}

impl RayTable {
    /// Unprojects every pixel centre of `cam`.
    pub fn new(cam: &CameraUnit) -> Self {
        let (w, h) = (cam.model.width, cam.model.height);
        let rays: Vec<[f32; 3]> = (0..h)
            .into_par_iter()
            .flat_map_iter(|v| {
                (0..w).map(move |u| {
                    cam.model
                        .unproject(&cam.params, &Vector2::new(u as f64, v as f64))
                        .map_or([f32::NAN; 3], |r| [r.x as f32, r.y as f32, r.z as f32])
                })
            })
            .collect();
        Self { width: w, rays }
    }

    /// The unit ray through the centre of pixel (`u`, `v`), `None` where the distortion
    /// cannot be inverted.
    pub fn ray(&self, u: u32, v: u32) -> Option<V3> {
        self.get(u, v)
    }

    fn get(&self, u: u32, v: u32) -> Option<V3> {
        let r = self.rays[(v * self.width + u) as usize];
        r[0].is_finite()
            .then(|| V3::new(r[0] as f64, r[1] as f64, r[2] as f64).normalize())
    }
}

/// A float image (or a window of one): radiance in fractions of full scale.
#[derive(Debug, Clone)]
pub struct Radiance {
    /// Column of the window's first pixel in the full image.
    pub x0: u32,
    /// Row of the window's first pixel in the full image.
    pub y0: u32,
    /// Window width.
    pub width: u32,
    /// Window height.
    pub height: u32,
    /// Row-major values.
    pub data: Vec<f64>,
}

impl Radiance {
    /// Value at window coordinates.
    pub fn at(&self, x: u32, y: u32) -> f64 {
        self.data[(y * self.width + x) as usize]
    }
}

#[derive(Clone, Copy)]
struct BBox {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
}

/// Projected bounding boxes (pixels, with a margin) of every object in the camera-frame
/// scene `sc`; `None` for objects that cannot be seen (entirely behind the camera).
fn object_boxes(sc: &TestField, cam: &CameraUnit) -> Vec<(Object, BBox)> {
    let (w, h) = (cam.model.width as f64, cam.model.height as f64);
    let r_max = cam.max_ideal_radius_mm() * 1.02;
    let full = BBox {
        x0: -1.0,
        y0: -1.0,
        x1: w,
        y1: h,
    };
    let bbox_of = |pts: &[V3]| -> Option<BBox> {
        let mut b = BBox {
            x0: f64::INFINITY,
            y0: f64::INFINITY,
            x1: f64::NEG_INFINITY,
            y1: f64::NEG_INFINITY,
        };
        let mut any_front = false;
        for p in pts {
            // Points near or behind the camera plane (or outside the invertible part of the
            // distortion): be conservative.
            let uv = if p.y > 1.0 {
                cam.project_in_view(p, r_max)
            } else {
                None
            };
            match uv {
                Some(uv) => {
                    any_front = true;
                    b.x0 = b.x0.min(uv.x);
                    b.y0 = b.y0.min(uv.y);
                    b.x1 = b.x1.max(uv.x);
                    b.y1 = b.y1.max(uv.y);
                }
                None => {
                    // Far off to the side, or behind: the outline leaves the image on
                    // that side; extend the box to the image edges in that direction.
                    any_front |= p.y > 0.0;
                    if p.x > 0.0 {
                        b.x1 = full.x1;
                    } else {
                        b.x0 = full.x0;
                    }
                    if p.z > 0.0 {
                        b.y0 = full.y0;
                    } else {
                        b.y1 = full.y1;
                    }
                }
            }
        }
        if !any_front {
            return None;
        }
        let m = 2.0;
        Some(BBox {
            x0: b.x0 - m,
            y0: b.y0 - m,
            x1: b.x1 + m,
            y1: b.y1 + m,
        })
    };
    let mut out = Vec::new();
    let ring = |c: &V3, e1: &V3, e2: &V3, r: f64, n: usize| -> Vec<V3> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                c + (e1 * a.cos() + e2 * a.sin()) * r
            })
            .collect()
    };
    for (i, t) in sc.targets.iter().enumerate() {
        // Back-facing targets are invisible.
        if t.normal.dot(&t.centre) >= 0.0 {
            continue;
        }
        if let Some(b) = bbox_of(&ring(&t.centre, &t.t1, &t.t2, t.background, 48)) {
            out.push((Object::Target(i as u32), b));
        }
    }
    for (i, bl) in sc.balls.iter().enumerate() {
        let d = bl.centre.norm();
        let mut pts = Vec::new();
        if d > bl.radius * 1.01 {
            let v = bl.centre / d;
            let e1 = v
                .cross(&if v.x.abs() < 0.9 { V3::x() } else { V3::y() })
                .normalize();
            let e2 = v.cross(&e1);
            let cc = bl.centre * (1.0 - bl.radius * bl.radius / (d * d));
            let rho = bl.radius * (d * d - bl.radius * bl.radius).sqrt() / d;
            pts.extend(ring(&cc, &e1, &e2, rho, 48));
        } else {
            pts.push(V3::new(0.0, 1.0, 0.0)); // camera inside a ball: whole image
        }
        let e1 = bl
            .axis
            .cross(&if bl.axis.x.abs() < 0.9 {
                V3::x()
            } else {
                V3::y()
            })
            .normalize();
        let e2 = bl.axis.cross(&e1);
        pts.extend(ring(&bl.foot, &e1, &e2, bl.stem_radius, 12));
        pts.extend(ring(
            &(bl.foot + bl.axis * bl.stem_length),
            &e1,
            &e2,
            bl.stem_radius,
            12,
        ));
        if let Some(b) = bbox_of(&pts) {
            out.push((Object::Ball(i as u32), b));
        }
    }
    out
}

/// Radiance of a camera-frame ray `d` (unit) from the origin, in the camera-frame scene.
fn shade(sc: &TestField, d: &V3, objs: Option<&[Object]>, rc: &RenderConfig) -> f64 {
    let Some(hit) = sc.cast(&V3::zeros(), d, objs) else {
        return 0.02;
    };
    let dist_m = hit.t * 1e-3;
    let cos_i = d.dot(&hit.normal).abs();
    let e = rc.flash_at_1m * cos_i / (dist_m * dist_m) + rc.ambient;
    match hit.kind {
        HitKind::Surface { index, u, v } => sc.surfaces[index].albedo_at(u, v) * e,
        HitKind::Black { .. } => sc.black_albedo * e,
        HitKind::Retro { target } => {
            let t = &sc.targets[target];
            let dc = t.centre.norm() * 1e-3;
            let cos_e = (-t.normal.dot(&t.centre) / t.centre.norm()).max(0.0);
            sc.retro_gain * rc.flash_at_1m * cos_e / (dc * dc) + 0.8 * rc.ambient
        }
        // Celluloid is translucent: part of the light is scattered inside the ball, which
        // softens the limb darkening of a pure Lambertian sphere.
        HitKind::Ball { ball } => {
            let c = sc.balls[ball].centre.norm() * 1e-3;
            sc.ball_albedo * (0.7 * (e - rc.ambient) + 0.3 * rc.flash_at_1m / (c * c) + rc.ambient)
        }
        HitKind::Stem { .. } => sc.stem_albedo * e,
    }
}

/// Renders the radiance (no blur, vignetting or noise) of the window `[x0, y0, w, h]`
/// (the whole image when `None`) seen by `cam` at `pose` (world → camera), with
/// `rc.supersampling`² exact rays on pixels near objects. `table` (the camera's
/// [`RayTable`]) only speeds up the single-ray pixels.
pub fn render_radiance(
    scene: &TestField,
    cam: &CameraUnit,
    pose: &Rigid3,
    rc: &RenderConfig,
    window: Option<[u32; 4]>,
    table: Option<&RayTable>,
) -> Radiance {
    let sc = scene.transformed(pose);
    let [x0, y0, ww, wh] = window.unwrap_or([0, 0, cam.model.width, cam.model.height]);
    let boxes = object_boxes(&sc, cam);
    const TILE: u32 = 16;
    let tiles_x = ww.div_ceil(TILE);
    let tiles_y = wh.div_ceil(TILE);
    let mut tiles: Vec<Vec<(Object, BBox)>> = vec![Vec::new(); (tiles_x * tiles_y) as usize];
    for (o, b) in &boxes {
        let tx0 = (((b.x0 - x0 as f64) / TILE as f64).floor().max(0.0)) as i64;
        let ty0 = (((b.y0 - y0 as f64) / TILE as f64).floor().max(0.0)) as i64;
        let tx1 = (((b.x1 - x0 as f64) / TILE as f64).floor()).min(tiles_x as f64 - 1.0) as i64;
        let ty1 = (((b.y1 - y0 as f64) / TILE as f64).floor()).min(tiles_y as f64 - 1.0) as i64;
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                tiles[(ty as u32 * tiles_x + tx as u32) as usize].push((*o, *b));
            }
        }
    }
    let n = rc.supersampling.max(1);
    let mut data = vec![0.0; (ww * wh) as usize];
    data.par_chunks_mut(ww as usize)
        .enumerate()
        .for_each(|(row, out)| {
            let v = y0 + row as u32;
            let mut objs: Vec<Object> = Vec::new();
            for (col, px) in out.iter_mut().enumerate() {
                let u = x0 + col as u32;
                let tile = &tiles[((row as u32 / TILE) * tiles_x + col as u32 / TILE) as usize];
                objs.clear();
                let (uf, vf) = (u as f64, v as f64);
                for (o, b) in tile {
                    if uf >= b.x0 && uf <= b.x1 && vf >= b.y0 && vf <= b.y1 {
                        objs.push(*o);
                    }
                }
                *px = if objs.is_empty() {
                    let ray = match table {
                        Some(t) => t.get(u, v),
                        None => cam.model.unproject(&cam.params, &Vector2::new(uf, vf)),
                    };
                    ray.map_or(0.0, |d| shade(&sc, &d, Some(&objs), rc))
                } else {
                    let mut acc = 0.0;
                    for j in 0..n {
                        for i in 0..n {
                            let uv = Vector2::new(
                                uf - 0.5 + (i as f64 + 0.5) / n as f64,
                                vf - 0.5 + (j as f64 + 0.5) / n as f64,
                            );
                            if let Some(d) = cam.model.unproject(&cam.params, &uv) {
                                acc += shade(&sc, &d, Some(&objs), rc);
                            }
                        }
                    }
                    acc / (n * n) as f64
                };
            }
        });
    Radiance {
        x0,
        y0,
        width: ww,
        height: wh,
        data,
    }
}

/// Separable Gaussian blur with σ in pixels (edges clamped).
pub fn blur(img: &mut Radiance, sigma: f64) {
    if sigma <= 0.0 {
        return;
    }
    let r = (3.0 * sigma).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    let k: Vec<f64> = k.iter().map(|v| v / s).collect();
    let (w, h) = (img.width as i64, img.height as i64);
    let src = img.data.clone();
    let mut tmp = vec![0.0; src.len()];
    tmp.par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, out)| {
            for x in 0..w {
                let mut a = 0.0;
                for (ki, kv) in k.iter().enumerate() {
                    let xx = (x + ki as i64 - r).clamp(0, w - 1);
                    a += kv * src[(y as i64 * w + xx) as usize];
                }
                out[x as usize] = a;
            }
        });
    img.data
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, out)| {
            for x in 0..w {
                let mut a = 0.0;
                for (ki, kv) in k.iter().enumerate() {
                    let yy = (y as i64 + ki as i64 - r).clamp(0, h - 1);
                    a += kv * tmp[(yy * w + x) as usize];
                }
                out[x as usize] = a;
            }
        });
}

/// An image rendered ray by ray: each pixel's radiance along its ray of `table`
/// (`radiance`), the mean over `supersampling × supersampling` sub-pixel rays where
/// `near_edge` says an edge crosses the pixel; then blurred, vignetted, noised and
/// quantised ([`expose`], image `index` of `seed`).
pub fn render_rays(
    cam: &CameraUnit,
    table: &RayTable,
    render: &RenderConfig,
    (seed, index): (u64, u64),
    near_edge: impl Fn(&V3) -> bool + Sync,
    radiance: impl Fn(&V3) -> f64 + Sync,
) -> image::GrayImage {
    let (w, h) = (cam.model.width, cam.model.height);
    let n = render.supersampling.max(1);
    let mut data = vec![0.0; (w * h) as usize];
    data.par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(v, row)| {
            for (u, px) in row.iter_mut().enumerate() {
                let Some(ray) = table.ray(u as u32, v as u32) else {
                    continue;
                };
                if !near_edge(&ray) {
                    *px = radiance(&ray);
                    continue;
                }
                let mut acc = 0.0;
                for j in 0..n {
                    for i in 0..n {
                        let uv = Vector2::new(
                            u as f64 - 0.5 + (i as f64 + 0.5) / n as f64,
                            v as f64 - 0.5 + (j as f64 + 0.5) / n as f64,
                        );
                        if let Some(d) = cam.model.unproject(&cam.params, &uv) {
                            acc += radiance(&d.normalize());
                        }
                    }
                }
                *px = acc / (n * n) as f64;
            }
        });
    let rad = Radiance {
        x0: 0,
        y0: 0,
        width: w,
        height: h,
        data,
    };
    let bytes = expose(rad, w, h, render, seed, index);
    image::GrayImage::from_raw(w, h, bytes).expect("buffer size")
}

/// Blur, vignetting, noise and 8-bit quantisation of a full-image radiance.
/// `seed` and `stream_index` choose the noise (one independent stream per image row).
pub fn expose(
    mut img: Radiance,
    full_width: u32,
    full_height: u32,
    rc: &RenderConfig,
    seed: u64,
    stream_index: u64,
) -> Vec<u8> {
    blur(&mut img, rc.blur_sigma_px);
    let (cx, cy) = (
        (full_width as f64 - 1.0) * 0.5,
        (full_height as f64 - 1.0) * 0.5,
    );
    let rmax2 = cx * cx + cy * cy;
    let w = img.width as usize;
    let mut out = vec![0u8; img.data.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(row, o)| {
        let mut rng = rng_for(seed, "image-noise", stream_index * 1_000_000 + row as u64);
        let y = (img.y0 as usize + row) as f64;
        for (col, px) in o.iter_mut().enumerate() {
            let x = (img.x0 as usize + col) as f64;
            let r2 = ((x - cx).powi(2) + (y - cy).powi(2)) / rmax2;
            let mut val = img.data[row * w + col] * (1.0 - rc.vignetting * r2);
            if rc.noise {
                let e = val.max(0.0) * rc.full_well_e;
                let n1: f64 = StandardNormal.sample(&mut rng);
                let n2: f64 = StandardNormal.sample(&mut rng);
                val = (e + e.sqrt() * n1 + rc.read_noise_e * n2) / rc.full_well_e;
            }
            *px = (val * 255.0).round().clamp(0.0, 255.0) as u8;
        }
    });
    out
}

/// A whole 8-bit image of `scene` by `cam` at `pose`.
pub fn render_image(
    scene: &TestField,
    cam: &CameraUnit,
    pose: &Rigid3,
    rc: &RenderConfig,
    table: Option<&RayTable>,
    seed: u64,
    stream_index: u64,
) -> image::GrayImage {
    let rad = render_radiance(scene, cam, pose, rc, None, table);
    let bytes = expose(
        rad,
        cam.model.width,
        cam.model.height,
        rc,
        seed,
        stream_index,
    );
    image::GrayImage::from_raw(cam.model.width, cam.model.height, bytes).expect("buffer size")
}
