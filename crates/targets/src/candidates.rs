//! Candidate blobs: connected components at every rung of the threshold ladder that pass the
//! shape tests, grouped across rungs (a real target is a component at several consecutive
//! levels, noise rarely is).

use crate::blobs::{components_at_levels, Blob};
use crate::ellipse::Ellipse;
use crate::image_io::GrayImage;
use crate::threshold::threshold_levels;

/// Settings of the candidate search.
#[derive(Clone, Debug)]
pub struct CandidateParams {
    /// Smallest accepted blob diameter (pixels, of the equivalent disc); a stable blob under
    /// it is refused as too small.
    pub min_diameter_px: f64,
    /// Largest accepted blob diameter (pixels, of the equivalent disc); a larger blob is
    /// dropped without a refusal.
    pub max_diameter_px: f64,
    /// Number of threshold levels.
    pub levels: usize,
    /// Smallest fill ratio (area over moment-ellipse area).
    pub min_fill: f64,
    /// Smallest minor/major axis ratio (0.3 ≈ 72° of tilt).
    pub min_axis_ratio: f64,
    /// A candidate must be found at this many levels.
    pub min_repeat: usize,
}

impl Default for CandidateParams {
    fn default() -> Self {
        CandidateParams {
            min_diameter_px: 5.0,
            max_diameter_px: 200.0,
            levels: 10,
            min_fill: 0.8,
            min_axis_ratio: 0.3,
            min_repeat: 2,
        }
    }
}

/// A candidate: the moment ellipse of its representative component and how many levels it
/// was seen at.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The moment ellipse of the representative component (the middle one of the levels it
    /// was seen at), px.
    pub seed: Ellipse,
    /// At how many threshold levels it was seen.
    pub repeats: usize,
    /// The representative component's area, pixels.
    pub area: usize,
}

/// Why a component failed the shape tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlobRefusal {
    /// It touches the image border.
    AtBorder,
    /// Its fill ratio or axis ratio is not an ellipse's.
    NotElliptic,
    /// It passed the shape tests but its diameter is under the smallest accepted.
    TooSmall,
}

fn shape_ok(b: &Blob, w: usize, h: usize, p: &CandidateParams) -> Result<Ellipse, BlobRefusal> {
    if b.touches_border(w, h) {
        return Err(BlobRefusal::AtBorder);
    }
    let e = b.moment_ellipse().ok_or(BlobRefusal::NotElliptic)?;
    if e.b / e.a < p.min_axis_ratio {
        return Err(BlobRefusal::NotElliptic);
    }
    // Small blobs are ragged by quantisation: relax the fill test below ~10 px diameter.
    let d = 2.0 * e.radius();
    let min_fill = if d < 10.0 {
        p.min_fill - 0.1
    } else {
        p.min_fill
    };
    // `b.fill_ratio()` without computing the moment ellipse again.
    let fill = b.area as f64 / (std::f64::consts::PI * e.a * e.b);
    if fill < min_fill || fill > 1.15 {
        return Err(BlobRefusal::NotElliptic);
    }
    Ok(e)
}

/// A blob seen at `min_repeat` or more levels of which no candidate came: its moment ellipse
/// (the middle level's; at the border, of the part inside the image) and why.
#[derive(Clone, Debug)]
pub struct RefusedBlob {
    /// Its outline, px: the moment ellipse of the middle level's component (at the border,
    /// of the part inside the image).
    pub seed: Ellipse,
    /// At how many threshold levels it was seen.
    pub repeats: usize,
    /// Which test it failed.
    pub why: BlobRefusal,
}

/// All candidates of an image, sorted by position (row-major of their centres).
pub fn find_candidates(img: &GrayImage, p: &CandidateParams) -> Vec<Candidate> {
    find_candidates_and_refusals(img, p, false).0
}

/// [`find_candidates`], and, when `refusals` is set, the stable blobs that failed the shape
/// tests or the smallest diameter (each group of them seen at `min_repeat` levels or more,
/// grouped as the candidates are; sorted by position).
pub fn find_candidates_and_refusals(
    img: &GrayImage,
    p: &CandidateParams,
    refusals: bool,
) -> (Vec<Candidate>, Vec<RefusedBlob>) {
    let levels = threshold_levels(img, p.levels);
    let min_area = (std::f64::consts::PI * (p.min_diameter_px / 2.0).powi(2) * 0.7)
        .floor()
        .max(3.0) as usize;
    let max_area = (std::f64::consts::PI * (p.max_diameter_px / 2.0).powi(2) * 1.3).ceil() as usize;
    let (w, h) = (img.width, img.height);
    let mut refused_members: Vec<(Ellipse, BlobRefusal)> = Vec::new();
    let per_level: Vec<Vec<(Ellipse, usize)>> =
        components_at_levels(img, &levels, min_area, max_area)
            .into_iter()
            .map(|blobs| {
                blobs
                    .iter()
                    .filter_map(|b| match shape_ok(b, w, h, p) {
                        Ok(e) => Some((e, b.area)),
                        Err(why) => {
                            if refusals {
                                let (cx, cy) = b.centroid();
                                let r = 0.5
                                    * ((b.x_max - b.x_min + 1).max(b.y_max - b.y_min + 1)) as f64;
                                let e = b.moment_ellipse().unwrap_or(Ellipse {
                                    cx,
                                    cy,
                                    a: r,
                                    b: r,
                                    theta: 0.0,
                                });
                                refused_members.push((e, why));
                            }
                            None
                        }
                    })
                    .collect()
            })
            .collect();
    let groups = group_by_centre(per_level.into_iter().flatten(), w, h);
    let mut out: Vec<Candidate> = Vec::new();
    let mut refused: Vec<RefusedBlob> = Vec::new();
    for g in groups.into_iter().filter(|g| g.len() >= p.min_repeat) {
        // Levels ascend, so members go from the largest to the smallest component; take
        // the middle one as the representative.
        let (seed, area) = g[g.len() / 2];
        let d = 2.0 * seed.radius();
        if d >= p.min_diameter_px && d <= p.max_diameter_px {
            out.push(Candidate {
                seed,
                repeats: g.len(),
                area,
            });
        } else if refusals && d < p.min_diameter_px {
            refused.push(RefusedBlob {
                seed,
                repeats: g.len(),
                why: BlobRefusal::TooSmall,
            });
        }
    }
    if refusals {
        for g in group_by_centre(refused_members.into_iter(), w, h)
            .into_iter()
            .filter(|g| g.len() >= p.min_repeat)
        {
            let (seed, _) = g[g.len() / 2];
            let why = if g.iter().any(|m| m.1 == BlobRefusal::AtBorder) {
                BlobRefusal::AtBorder
            } else {
                BlobRefusal::NotElliptic
            };
            refused.push(RefusedBlob {
                seed,
                repeats: g.len(),
                why,
            });
        }
    }
    let by_position = |a: &Ellipse, b: &Ellipse| {
        (a.cy, a.cx)
            .partial_cmp(&(b.cy, b.cx))
            .unwrap_or(std::cmp::Ordering::Equal)
    };
    out.sort_by(|a, b| by_position(&a.seed, &b.seed));
    refused.sort_by(|a, b| by_position(&a.seed, &b.seed));
    (out, refused)
}

/// Groups ellipses (with a payload) across levels, in the order given: an ellipse joins the
/// first group (in order of creation) whose first member's centre is within half the smaller
/// radius (at least 1 px) of its own, else starts a group. Returns the groups in order of
/// creation, each with its members in order.
fn group_by_centre<T: Copy>(
    items: impl Iterator<Item = (Ellipse, T)>,
    w: usize,
    h: usize,
) -> Vec<Vec<(Ellipse, T)>> {
    struct Group<T> {
        members: Vec<(Ellipse, T)>,
        cx: f64,
        cy: f64,
        r: f64,
        /// The next group of the same grid cell.
        next: u32,
    }
    // The groups by grid cell of 16 px, in order of creation: a list from `head` through
    // `Group::next` to `tail` per cell. A component's centre is inside the image, so its cell
    // is one of the grid's (the clamp is only active for the centre of a refused component
    // cut by the border, which may lie outside).
    const NONE: u32 = u32::MAX;
    let cell = 16.0;
    let (gw, gh) = (w.div_ceil(16).max(1) as i64, h.div_ceil(16).max(1) as i64);
    let mut head = vec![NONE; (gw * gh) as usize];
    let mut tail = vec![NONE; (gw * gh) as usize];
    let cell_of = |x: f64, y: f64| {
        let (i, j) = ((x / cell).floor() as i64, (y / cell).floor() as i64);
        (i.clamp(0, gw - 1), j.clamp(0, gh - 1))
    };
    let mut groups: Vec<Group<T>> = Vec::new();
    for (e, payload) in items {
        let key = cell_of(e.cx, e.cy);
        let mut hit = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                let (i, j) = (key.0 + dx, key.1 + dy);
                if i < 0 || j < 0 || i >= gw || j >= gh {
                    continue;
                }
                let mut gi = head[(j * gw + i) as usize];
                while gi != NONE {
                    let g = &groups[gi as usize];
                    let d = ((g.cx - e.cx).powi(2) + (g.cy - e.cy).powi(2)).sqrt();
                    if d <= (0.5 * g.r.min(e.radius())).max(1.0) {
                        hit = Some(gi as usize);
                        break 'search;
                    }
                    gi = g.next;
                }
            }
        }
        match hit {
            Some(gi) => groups[gi].members.push((e, payload)),
            None => {
                let (c, gi) = ((key.1 * gw + key.0) as usize, groups.len() as u32);
                match tail[c] {
                    NONE => head[c] = gi,
                    t => groups[t as usize].next = gi,
                }
                tail[c] = gi;
                groups.push(Group {
                    members: vec![(e, payload)],
                    cx: e.cx,
                    cy: e.cy,
                    r: e.radius(),
                    next: NONE,
                });
            }
        }
    }
    groups.into_iter().map(|g| g.members).collect()
}
