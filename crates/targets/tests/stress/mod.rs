//! Images made to tempt the ring decoder into a wrong number (issue 38): rings partly covered,
//! targets overlapping, rings half in shadow, printed text (black on white paper and white on
//! black), checkerboards, and all of them at once; with real targets of known numbers among
//! them. [`scene`] draws one from a seed; [`score`] counts the numbers read and the wrong ones.
//!
//! A read is right when a drawn target's centre is within max(2 px, half its dot radius) of
//! it and that target carries the number read; any other read is wrong (a number read where no
//! target is, or another target's number).

use pingcal_geometry::consensus::SeededRng;
use pingcal_targets::printable::target_is_white;
use pingcal_targets::{GrayImage, ImageDetections, TargetKind};
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// The temptations, one per scene (`scene` takes `kinds[seed % len]`).
pub const KINDS: [&str; 6] = [
    "partial ring",
    "overlapping targets",
    "half-shadowed ring",
    "printed text",
    "checkerboard",
    "all at once",
];

/// A target drawn in a scene: centre (px), dot radius (px), the pose of its plane (in-plane
/// rotation, tilt, tilt axis), and its number and code.
#[derive(Clone, Debug)]
pub struct Drawn {
    pub cx: f64,
    pub cy: f64,
    pub rad: f64,
    pub pose: [f64; 3],
    pub id: u32,
    pub code: u32,
}

impl Drawn {
    /// The target-plane point (dot radii) under image point (x, y).
    fn plane(&self, x: f64, y: f64) -> (f64, f64) {
        let [rot, tilt, axis] = self.pose;
        let (px, py) = ((x - self.cx) / self.rad, (y - self.cy) / self.rad);
        let (ca, sa) = (axis.cos(), axis.sin());
        let along = px * ca + py * sa;
        let across = (-px * sa + py * ca) / tilt.cos();
        let (qx, qy) = (along * ca - across * sa, along * sa + across * ca);
        (
            qx * rot.cos() + qy * rot.sin(),
            -qx * rot.sin() + qy * rot.cos(),
        )
    }

    /// The grey level at (x, y) when the target is there (its black square and white
    /// pattern), or None outside its square.
    fn level(&self, x: f64, y: f64) -> Option<f32> {
        // the square's corners are 4√2 dot radii out, stretched by at most 1 / cos(tilt)
        let reach = 5.7 * self.rad / self.pose[1].cos();
        if (x - self.cx).abs() > reach || (y - self.cy).abs() > reach {
            return None;
        }
        let (u, v) = self.plane(x, y);
        (u.abs() <= 4.0 && v.abs() <= 4.0).then(|| {
            if target_is_white(self.code, 14, u, v) {
                WHITE
            } else {
                BLACK
            }
        })
    }
}

const WHITE: f32 = 0.8;
const BLACK: f32 = 0.05;
const GREY: f32 = 0.35;

/// Something painted over the image, in drawing order.
enum Layer {
    Target(Drawn),
    /// A bar of `level`: points within `half_width` of the line n·p = d, and within
    /// `half_length` of its middle `(mx, my)` along it.
    Bar {
        n: (f64, f64),
        d: f64,
        half_width: f64,
        mid: (f64, f64),
        half_length: f64,
        level: f32,
    },
    /// Everything on the side n·p > d darkened by `factor`, with a soft edge of `soft` px.
    Shadow {
        n: (f64, f64),
        d: f64,
        factor: f32,
        soft: f64,
    },
    /// A box of `paper` with rows of glyphs of `ink`: `cell` px per glyph dot, glyphs of 5 × 7
    /// dots, each glyph's dots in `glyphs`.
    Text {
        x0: f64,
        y0: f64,
        cols: usize,
        rows: usize,
        cell: f64,
        paper: f32,
        ink: f32,
        glyphs: Vec<[u8; 7]>,
    },
    /// A rotated checkerboard of `n` × `n` cells of `cell` px from corner `(x0, y0)`.
    Checker {
        x0: f64,
        y0: f64,
        cell: f64,
        n: usize,
        angle: f64,
    },
}

/// Glyphs of 5 × 7 dots (rows top down, bit 4 leftmost) that look like print and hold round
/// counters: o, 0, 8, e, a, @, B, 6, 9, D.
const FONT: [[u8; 7]; 10] = [
    [0, 0, 14, 17, 17, 17, 14],
    [14, 17, 19, 21, 25, 17, 14],
    [14, 17, 17, 14, 17, 17, 14],
    [0, 0, 14, 17, 31, 16, 14],
    [0, 0, 14, 1, 15, 17, 15],
    [14, 17, 23, 21, 23, 16, 14],
    [30, 17, 17, 30, 17, 17, 30],
    [6, 8, 16, 30, 17, 17, 14],
    [14, 17, 17, 15, 1, 2, 12],
    [28, 18, 17, 17, 17, 18, 28],
];

impl Layer {
    fn paint(&self, x: f64, y: f64, g: f32) -> f32 {
        match self {
            Layer::Target(t) => t.level(x, y).unwrap_or(g),
            Layer::Bar {
                n,
                d,
                half_width,
                mid,
                half_length,
                level,
            } => {
                let across = n.0 * x + n.1 * y - d;
                let along = -n.1 * (x - mid.0) + n.0 * (y - mid.1);
                if across.abs() <= *half_width && along.abs() <= *half_length {
                    *level
                } else {
                    g
                }
            }
            Layer::Shadow { n, d, factor, soft } => {
                let s = n.0 * x + n.1 * y - d;
                let t = if *soft > 0.0 {
                    (0.5 + s / soft).clamp(0.0, 1.0)
                } else {
                    f64::from(u8::from(s > 0.0))
                } as f32;
                g * (1.0 - t * (1.0 - factor))
            }
            Layer::Text {
                x0,
                y0,
                cols,
                rows,
                cell,
                paper,
                ink,
                glyphs,
            } => {
                let (gx, gy) = ((x - x0) / cell, (y - y0) / cell);
                // glyph boxes of 6 × 9 dots (one dot between glyphs, two between lines)
                if gx < 0.0 || gy < 0.0 || gx >= 6.0 * *cols as f64 || gy >= 9.0 * *rows as f64 {
                    return g;
                }
                let (c, r) = ((gx / 6.0) as usize, (gy / 9.0) as usize);
                let (dx, dy) = (
                    (gx - 6.0 * c as f64) as usize,
                    (gy - 9.0 * r as f64) as usize,
                );
                let glyph = &glyphs[(r * cols + c) % glyphs.len()];
                if dx < 5 && dy < 7 && glyph[dy] >> (4 - dx) & 1 == 1 {
                    *ink
                } else {
                    *paper
                }
            }
            Layer::Checker {
                x0,
                y0,
                cell,
                n,
                angle,
            } => {
                let (c, s) = (angle.cos(), angle.sin());
                let (u, v) = ((x - x0) * c + (y - y0) * s, -(x - x0) * s + (y - y0) * c);
                let (i, j) = ((u / cell).floor(), (v / cell).floor());
                if i < 0.0 || j < 0.0 || i >= *n as f64 || j >= *n as f64 {
                    return g;
                }
                if (i as i64 + j as i64) % 2 == 0 {
                    WHITE
                } else {
                    BLACK
                }
            }
        }
    }
}

/// One scene: the image and the targets drawn in it.
pub struct Scene {
    pub kind: &'static str,
    pub image: GrayImage,
    pub targets: Vec<Drawn>,
}

/// A random target of the 14-bit table at (cx, cy) with dot radius `rad`.
fn target(rng: &mut SeededRng, cx: f64, cy: f64, rad: f64) -> Drawn {
    let table = pingcal_targets::aicon::CodeTable::generate(14).unwrap();
    let id = rng.random_range(1..=table.codes.len() as u32);
    Drawn {
        cx,
        cy,
        rad,
        pose: [
            rng.random_range(0.0..std::f64::consts::TAU),
            rng.random_range(0.0f64..50.0).to_radians(),
            rng.random_range(0.0..std::f64::consts::PI),
        ],
        id,
        code: table.code(id).unwrap(),
    }
}

/// A unit normal at a random angle.
fn normal(rng: &mut SeededRng) -> (f64, f64) {
    let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    (a.cos(), a.sin())
}

/// The image side (px).
const SIDE: usize = 400;

/// The scene of `seed`: its temptation is `KINDS[seed % 6]`.
pub fn scene(seed: u64) -> Scene {
    let mut rng = pingcal_geometry::consensus::rng(seed);
    let kind = KINDS[(seed % KINDS.len() as u64) as usize];
    let mut layers = Vec::new();
    let mut targets = Vec::new();
    // dot radii of 3.5 to 10 px, blur of 0.5 to 1.4 px
    let rad = rng.random_range(3.5..10.0);
    let blur = rng.random_range(0.5..1.4);
    // four target slots in a 2 × 2 grid, each with room for its square
    let slots = [
        (100.0, 100.0),
        (300.0, 100.0),
        (100.0, 300.0),
        (300.0, 300.0),
    ];
    let jitter = |rng: &mut SeededRng| rng.random_range(-20.0..20.0);
    let all = kind == "all at once";
    let mut push = |layers: &mut Vec<Layer>, t: Drawn| {
        targets.push(t.clone());
        layers.push(Layer::Target(t));
    };
    if kind == "printed text" || all {
        // a page of text across the middle band, black on white, and a white-on-black label
        let cell = rng.random_range(1.0..3.5);
        let glyphs: Vec<[u8; 7]> = (0..40)
            .map(|_| FONT[rng.random_range(0..FONT.len())])
            .collect();
        layers.push(Layer::Text {
            x0: 10.0,
            y0: rng.random_range(150.0..200.0),
            cols: (380.0 / (6.0 * cell)) as usize,
            rows: 2,
            cell,
            paper: 0.85,
            ink: BLACK,
            glyphs: glyphs.clone(),
        });
        layers.push(Layer::Text {
            x0: rng.random_range(150.0..250.0),
            y0: rng.random_range(20.0..60.0),
            cols: 6,
            rows: 1,
            cell: cell + 1.0,
            paper: BLACK,
            ink: WHITE,
            glyphs,
        });
    }
    if kind == "checkerboard" || all {
        let cell = rng.random_range(5.0..16.0);
        layers.push(Layer::Checker {
            x0: rng.random_range(120.0..200.0),
            y0: rng.random_range(120.0..200.0),
            cell,
            n: (120.0 / cell) as usize + 1,
            angle: rng.random_range(0.0..1.6),
        });
    }
    for (k, &(sx, sy)) in slots.iter().enumerate() {
        let (cx, cy) = (sx + jitter(&mut rng), sy + jitter(&mut rng));
        let t = target(&mut rng, cx, cy, rad);
        match kind {
            "overlapping targets" => {
                // a second target over this one, 4 to 7 dot radii away
                let n = normal(&mut rng);
                let d = rng.random_range(4.0..7.0) * rad;
                let other = target(&mut rng, cx + d * n.0, cy + d * n.1, rad);
                push(&mut layers, t);
                push(&mut layers, other);
            }
            "partial ring" => {
                push(&mut layers, t);
                partial_cover(&mut layers, &mut rng, cx, cy, rad);
            }
            "half-shadowed ring" => {
                push(&mut layers, t);
                half_shadow(&mut layers, &mut rng, cx, cy, rad);
            }
            "all at once" => {
                push(&mut layers, t);
                match k {
                    0 => partial_cover(&mut layers, &mut rng, cx, cy, rad),
                    1 => half_shadow(&mut layers, &mut rng, cx, cy, rad),
                    2 => {
                        let n = normal(&mut rng);
                        let d = rng.random_range(4.0..7.0) * rad;
                        let other = target(&mut rng, cx + d * n.0, cy + d * n.1, rad);
                        push(&mut layers, other);
                    }
                    _ => {}
                }
            }
            // text and checkerboard: the targets are clean, the tempters are around them
            _ => push(&mut layers, t),
        }
    }
    let image = render(&layers, blur, &mut rng);
    Scene {
        kind,
        image,
        targets,
    }
}

/// A bar across the ring of the target at (cx, cy): 0.4 to 3 dot radii wide, 1.2 to 3.5 dot
/// radii from the centre, of a level from black to white.
fn partial_cover(layers: &mut Vec<Layer>, rng: &mut SeededRng, cx: f64, cy: f64, rad: f64) {
    let n = normal(rng);
    let off = rng.random_range(1.2..3.5) * rad;
    let levels = [0.02, 0.15, 0.35, 0.6, 0.9];
    layers.push(Layer::Bar {
        n,
        d: n.0 * cx + n.1 * cy + off,
        half_width: 0.5 * rng.random_range(0.4..3.0) * rad,
        mid: (cx + off * n.0, cy + off * n.1),
        half_length: rng.random_range(2.0..8.0) * rad,
        level: levels[rng.random_range(0..levels.len())],
    });
}

/// A shadow edge near the target at (cx, cy): within ±2.5 dot radii of its centre, darkening
/// by a factor of 0.15 to 0.7, soft over 0 to 3 px.
fn half_shadow(layers: &mut Vec<Layer>, rng: &mut SeededRng, cx: f64, cy: f64, rad: f64) {
    let n = normal(rng);
    layers.push(Layer::Shadow {
        n,
        d: n.0 * cx + n.1 * cy + rng.random_range(-2.5..2.5) * rad,
        factor: rng.random_range(0.15..0.7),
        soft: rng.random_range(0.0..3.0),
    });
}

/// The layers over a grey background, 3 × 3 supersampled, blurred by a Gaussian of σ `blur`
/// px, with noise of σ 0.01.
fn render(layers: &[Layer], blur: f64, rng: &mut SeededRng) -> GrayImage {
    const SS: usize = 3;
    let mut img = GrayImage::new(SIDE, SIDE, GREY);
    for y in 0..SIDE {
        for x in 0..SIDE {
            let mut acc = 0.0;
            for sy in 0..SS {
                for sx in 0..SS {
                    let px = x as f64 - 0.5 + (sx as f64 + 0.5) / SS as f64;
                    let py = y as f64 - 0.5 + (sy as f64 + 0.5) / SS as f64;
                    acc += layers.iter().fold(GREY, |g, l| l.paint(px, py, g));
                }
            }
            img.data[y * SIDE + x] = acc / (SS * SS) as f32;
        }
    }
    super::gaussian_blur(&mut img, blur);
    let n = Normal::new(0.0, 0.01).unwrap();
    for v in &mut img.data {
        *v += n.sample(rng) as f32;
    }
    img
}

/// Numbers read in a scene, and the wrong ones (described).
pub fn score(scene: &Scene, found: &ImageDetections) -> (usize, Vec<String>) {
    let (mut read, mut wrong) = (0, Vec::new());
    for t in found.targets.iter().filter(|t| t.kind == TargetKind::Coded) {
        let Some(id) = t.id else { continue };
        read += 1;
        let near = scene
            .targets
            .iter()
            .find(|d| (d.cx - t.x).hypot(d.cy - t.y) <= (0.5 * d.rad).max(2.0));
        match near {
            Some(d) if d.id == id => {}
            Some(d) => wrong.push(format!(
                "{}: {id} read at ({:.1}, {:.1}), where {} is",
                scene.kind, t.x, t.y, d.id
            )),
            None => wrong.push(format!(
                "{}: {id} read at ({:.1}, {:.1}), where no target is",
                scene.kind, t.x, t.y
            )),
        }
    }
    (read, wrong)
}
