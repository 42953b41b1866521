//! The board's grid grown over the x-corner candidates, and its numbering.

use super::saddles::Saddle;
use super::{BoardMiss, Chessboard};
use crate::homography::fit_homography;
use crate::raster::GrayImage;
use std::collections::HashMap;

/// Seeds tried (the strongest candidates first) before giving up.
const MAX_SEEDS: usize = 40;
/// A neighbour's direction may differ from an edge direction by this much (radians).
const EDGE_ANGLE: f64 = 0.3;
/// A candidate is taken for a predicted corner within this fraction of the local side.
const TAKE_FRACTION: f64 = 0.3;

/// A grid of corner positions, `ni × nj`, grown from a seed: `i` along one edge direction,
/// `j` along the other, the pair right-handed in the image (j is i turned by +90°, x right,
/// y down).
#[derive(Clone, Debug)]
pub struct Grown {
    /// Extent along `i`.
    pub ni: usize,
    /// Extent along `j`.
    pub nj: usize,
    /// Positions, `pos[j * ni + i]` (px, to the pixel).
    pub pos: Vec<[f64; 2]>,
}

/// The grid of `board`'s size grown over `cands`, or the largest grid found.
pub fn grow_board(cands: &[Saddle], board: &Chessboard) -> Result<Grown, BoardMiss> {
    let mut tried = vec![false; cands.len()];
    let mut largest = (0, 0, 0);
    let mut larger = false;
    let limit = (board.cols, board.rows);
    for _ in 0..MAX_SEEDS {
        let Some(seed) = (0..cands.len()).find(|&k| !tried[k]) else {
            break;
        };
        tried[seed] = true;
        let Some(cells) = grow(cands, seed, limit) else {
            continue;
        };
        let (imin, imax, jmin, jmax) = extent(&cells);
        let (ni, nj) = ((imax - imin + 1) as usize, (jmax - jmin + 1) as usize);
        let fits = (ni, nj) == (board.cols, board.rows) || (ni, nj) == (board.rows, board.cols);
        if fits && cells.len() == ni * nj && continues_beyond(cands, &cells) {
            larger = true;
        } else if fits && cells.len() == ni * nj {
            let mut pos = vec![[0.0; 2]; ni * nj];
            for (&(i, j), &k) in &cells {
                pos[(j - jmin) as usize * ni + (i - imin) as usize] = cands[k].uv;
            }
            return Ok(Grown { ni, nj, pos });
        }
        if cells.len() > largest.0 {
            largest = (cells.len(), ni, nj);
        }
    }
    if larger {
        return Err(BoardMiss::LargerBoard {
            cols: board.cols,
            rows: board.rows,
        });
    }
    Err(BoardMiss::WrongGrid {
        cols: board.cols,
        rows: board.rows,
        found: largest.0,
        found_cols: largest.1,
        found_rows: largest.2,
    })
}

/// Whether the grid goes on past one of its sides: at three quarters or more of the cells
/// just beyond a side, an x-corner lies where the grid predicts one, with its edges along
/// the grid's lines (part of a larger board).
fn continues_beyond(cands: &[Saddle], cells: &HashMap<(i32, i32), usize>) -> bool {
    let (imin, imax, jmin, jmax) = extent(cells);
    let mut used = vec![false; cands.len()];
    for &k in cells.values() {
        used[k] = true;
    }
    let goes_on = |beyond: Vec<(i32, i32)>, inward: (i32, i32)| {
        let n = beyond.len();
        let found = beyond
            .into_iter()
            .filter(|&c| {
                let inner = cells.get(&(c.0 + inward.0, c.1 + inward.1));
                let hit = predict(cands, cells, c).and_then(|(p, side)| {
                    nearest_free(cands, &used, p, TAKE_FRACTION * side).map(|k| (k, p))
                });
                match (hit, inner) {
                    (Some((k, p)), Some(&inner)) => {
                        let q = cands[inner].uv;
                        edges_agree(&cands[k], [q[0] - p[0], q[1] - p[1]])
                    }
                    _ => false,
                }
            })
            .count();
        4 * found >= 3 * n
    };
    goes_on((jmin..=jmax).map(|j| (imin - 1, j)).collect(), (1, 0))
        || goes_on((jmin..=jmax).map(|j| (imax + 1, j)).collect(), (-1, 0))
        || goes_on((imin..=imax).map(|i| (i, jmin - 1)).collect(), (0, 1))
        || goes_on((imin..=imax).map(|i| (i, jmax + 1)).collect(), (0, -1))
}

/// Whether one of the candidate's edges runs along `dir` (within [`EDGE_ANGLE`]).
fn edges_agree(s: &Saddle, dir: [f64; 2]) -> bool {
    let a = dir[1].atan2(dir[0]).rem_euclid(std::f64::consts::PI);
    s.edges.iter().any(|&e| {
        let d = (e - a).rem_euclid(std::f64::consts::PI);
        d.min(std::f64::consts::PI - d) < EDGE_ANGLE
    })
}

fn extent(cells: &HashMap<(i32, i32), usize>) -> (i32, i32, i32, i32) {
    cells.keys().fold(
        (i32::MAX, i32::MIN, i32::MAX, i32::MIN),
        |(a, b, c, d), &(i, j)| (a.min(i), b.max(i), c.min(j), d.max(j)),
    )
}

/// The nearest candidate other than `from` whose direction from `from` is within
/// [`EDGE_ANGLE`] of `dir`.
fn neighbour_along(cands: &[Saddle], from: usize, dir: [f64; 2]) -> Option<usize> {
    let p = cands[from].uv;
    let cos_max = EDGE_ANGLE.cos();
    (0..cands.len())
        .filter(|&k| k != from)
        .filter_map(|k| {
            let d = [cands[k].uv[0] - p[0], cands[k].uv[1] - p[1]];
            let n = d[0].hypot(d[1]);
            (n > 2.0 && (d[0] * dir[0] + d[1] * dir[1]) / n > cos_max).then_some((k, n))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// The seed's first ring: its neighbours along both edges, the grid's axes right-handed.
fn seed_cells(cands: &[Saddle], seed: usize) -> Option<HashMap<(i32, i32), usize>> {
    let [a, b] = cands[seed].edges;
    let (d1, d2) = ([a.cos(), a.sin()], [b.cos(), b.sin()]);
    // j must be i turned by +90° in the image: flip the second axis when it is not.
    let s = if d1[0] * d2[1] - d1[1] * d2[0] > 0.0 {
        1
    } else {
        -1
    };
    let mut cells = HashMap::from([((0, 0), seed)]);
    for (dir, cell) in [
        (d1, (1, 0)),
        ([-d1[0], -d1[1]], (-1, 0)),
        (d2, (0, s)),
        ([-d2[0], -d2[1]], (0, -s)),
    ] {
        if let Some(k) = neighbour_along(cands, seed, dir) {
            cells.insert(cell, k);
        }
    }
    let has = |c: (i32, i32)| cells.contains_key(&c);
    ((has((1, 0)) || has((-1, 0))) && (has((0, 1)) || has((0, -1)))).then_some(cells)
}

/// The grid grown from `seed`, no larger than the board `limit = (cols, rows)`; `None` when the
/// seed has no neighbours along both edges.
fn grow(
    cands: &[Saddle],
    seed: usize,
    limit: (usize, usize),
) -> Option<HashMap<(i32, i32), usize>> {
    let mut cells = seed_cells(cands, seed)?;
    let mut used: Vec<bool> = vec![false; cands.len()];
    for &k in cells.values() {
        used[k] = true;
    }
    let mut failed: std::collections::HashSet<(i32, i32)> = Default::default();
    loop {
        let mut grew = false;
        for cell in frontier(&cells, &failed, limit) {
            // Each cell taken in this pass changes the extent: check it again.
            if !fits(&cells, cell, limit) {
                continue;
            }
            let taken = predict(cands, &cells, cell)
                .and_then(|(p, side)| nearest_free(cands, &used, p, TAKE_FRACTION * side));
            match taken {
                Some(k) => {
                    used[k] = true;
                    cells.insert(cell, k);
                    grew = true;
                }
                None => {
                    failed.insert(cell);
                }
            }
        }
        if !grew {
            break;
        }
        // A cell that failed may be predicted better from the cells found since.
        failed.clear();
    }
    Some(cells)
}

/// The empty cells next to the grid, not yet failed, that keep it within the board.
fn frontier(
    cells: &HashMap<(i32, i32), usize>,
    failed: &std::collections::HashSet<(i32, i32)>,
    limit: (usize, usize),
) -> Vec<(i32, i32)> {
    let mut out: Vec<(i32, i32)> = Vec::new();
    for &(i, j) in cells.keys() {
        for c in [(i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)] {
            if !cells.contains_key(&c)
                && !failed.contains(&c)
                && !out.contains(&c)
                && fits(cells, c, limit)
            {
                out.push(c);
            }
        }
    }
    out.sort_unstable();
    out
}

/// Whether the grid with `cell` added still fits the board `limit = (cols, rows)` in one
/// of its orientations.
fn fits(cells: &HashMap<(i32, i32), usize>, c: (i32, i32), limit: (usize, usize)) -> bool {
    let (imin, imax, jmin, jmax) = extent(cells);
    let ni = (imax.max(c.0) - imin.min(c.0) + 1) as usize;
    let nj = (jmax.max(c.1) - jmin.min(c.1) + 1) as usize;
    let (cols, rows) = limit;
    (ni <= cols && nj <= rows) || (ni <= rows && nj <= cols)
}

/// Where `cell` should be, and the local square side there (px): a homography of the grid
/// cells within two steps when they span both axes, else a step from a neighbour.
fn predict(
    cands: &[Saddle],
    cells: &HashMap<(i32, i32), usize>,
    cell: (i32, i32),
) -> Option<([f64; 2], f64)> {
    let (ci, cj) = cell;
    let near: Vec<((i32, i32), [f64; 2])> = cells
        .iter()
        .filter(|(&(i, j), _)| (i - ci).abs() <= 2 && (j - cj).abs() <= 2)
        .map(|(&c, &k)| (c, cands[k].uv))
        .collect();
    let distinct = |f: fn(&(i32, i32)) -> i32| {
        let mut v: Vec<i32> = near.iter().map(|(c, _)| f(c)).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    };
    let p = if near.len() >= 5 && distinct(|c| c.0) >= 2 && distinct(|c| c.1) >= 2 {
        let src: Vec<[f64; 2]> = near.iter().map(|(c, _)| [c.0 as f64, c.1 as f64]).collect();
        let dst: Vec<[f64; 2]> = near.iter().map(|(_, p)| *p).collect();
        fit_homography(&src, &dst)?.apply([ci as f64, cj as f64])?
    } else {
        step_from_neighbour(cands, cells, cell)?
    };
    let side = [(1, 0), (-1, 0), (0, 1), (0, -1)]
        .iter()
        .filter_map(|(di, dj)| cells.get(&(ci + di, cj + dj)))
        .map(|&k| (cands[k].uv[0] - p[0]).hypot(cands[k].uv[1] - p[1]))
        .fold(f64::NAN, f64::min);
    side.is_finite().then_some((p, side))
}

/// `cell` as a straight step on from a neighbour: `2·p(n) − p(n')` along a line of two.
fn step_from_neighbour(
    cands: &[Saddle],
    cells: &HashMap<(i32, i32), usize>,
    (ci, cj): (i32, i32),
) -> Option<[f64; 2]> {
    [(1, 0), (-1, 0), (0, 1), (0, -1)]
        .iter()
        .find_map(|(di, dj)| {
            let a = cells.get(&(ci + di, cj + dj))?;
            let b = cells.get(&(ci + 2 * di, cj + 2 * dj))?;
            let (pa, pb) = (cands[*a].uv, cands[*b].uv);
            Some([2.0 * pa[0] - pb[0], 2.0 * pa[1] - pb[1]])
        })
}

fn nearest_free(cands: &[Saddle], used: &[bool], p: [f64; 2], radius: f64) -> Option<usize> {
    (0..cands.len())
        .filter(|&k| !used[k])
        .map(|k| (k, (cands[k].uv[0] - p[0]).hypot(cands[k].uv[1] - p[1])))
        .filter(|&(_, d)| d <= radius)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// A grown grid numbered by the board's rule (see the module doc of [`super`]).
#[derive(Clone, Debug)]
pub struct Numbered {
    /// Positions in id order (px).
    pub cells: Vec<[f64; 2]>,
    /// More than one orientation fits the colours; corner 0 was taken nearest the top left.
    pub symmetric: bool,
}

/// Numbers `grown`: of the turns of the grid that give the board's shape, those whose
/// corner 0 has white diagonal squares; of those, the one whose corner 0 is nearest the
/// image's top-left corner. `None` when the grid has not the board's shape.
pub fn number(img: &GrayImage, grown: &Grown, board: &Chessboard) -> Option<Numbered> {
    let (ni, nj) = (grown.ni, grown.nj);
    let (c, r) = (board.cols, board.rows);
    // Each turn maps (col, row) to (i, j) of the grown grid, keeping the handedness.
    type Turn = Box<dyn Fn(usize, usize) -> (usize, usize)>;
    let mut turns: Vec<Turn> = Vec::new();
    if (ni, nj) == (c, r) {
        turns.push(Box::new(|col, row| (col, row)));
        turns.push(Box::new(move |col, row| (ni - 1 - col, nj - 1 - row)));
    }
    if (ni, nj) == (r, c) {
        turns.push(Box::new(move |col, row| (ni - 1 - row, col)));
        turns.push(Box::new(move |col, row| (row, nj - 1 - col)));
    }
    let labelled: Vec<Vec<[f64; 2]>> = turns
        .iter()
        .map(|t| {
            (0..c * r)
                .map(|id| {
                    let (i, j) = t(id % c, id / c);
                    grown.pos[j * ni + i]
                })
                .collect()
        })
        .collect();
    if !squares_alternate(img, &labelled[0], board) {
        return None;
    }
    let white: Vec<&Vec<[f64; 2]>> = labelled
        .iter()
        .filter(|cells| origin_is_white(img, cells, board))
        .collect();
    let pool: Vec<&Vec<[f64; 2]>> = if white.is_empty() {
        labelled.iter().collect()
    } else {
        white
    };
    let symmetric = pool.len() > 1;
    let best = pool.into_iter().min_by(|a, b| {
        let da = a[0][0].hypot(a[0][1]);
        let db = b[0][0].hypot(b[0][1]);
        da.total_cmp(&db)
    })?;
    Some(Numbered {
        cells: best.clone(),
        symmetric,
    })
}

/// Whether the squares between the corners alternate light and dark as a chessboard's do:
/// every one of the lighter colour's squares lighter than the mid-level between the two
/// colours' means, every one of the other darker, and the two means apart by a tenth of the
/// range at least (a grid grown over noise or texture does not).
fn squares_alternate(img: &GrayImage, cells: &[[f64; 2]], board: &Chessboard) -> bool {
    let c = board.cols;
    let mut parity = [Vec::new(), Vec::new()];
    for row in 0..board.rows - 1 {
        for col in 0..c - 1 {
            let ids = [
                row * c + col,
                row * c + col + 1,
                (row + 1) * c + col,
                (row + 1) * c + col + 1,
            ];
            let x = ids.iter().map(|&k| cells[k][0]).sum::<f64>() / 4.0;
            let y = ids.iter().map(|&k| cells[k][1]).sum::<f64>() / 4.0;
            parity[(row + col) % 2].push(mean_around(img, x, y));
        }
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
    let (a, b) = (mean(&parity[0]), mean(&parity[1]));
    let (light, dark) = if a > b { (0, 1) } else { (1, 0) };
    let mid = 0.5 * (a + b);
    (a - b).abs() > 0.1
        && parity[light].iter().all(|&v| v > mid)
        && parity[dark].iter().all(|&v| v < mid)
}

/// Whether the square between corners 0, 1, cols and cols + 1 is lighter than the one
/// next to it (between 1, 2, cols + 1, cols + 2; along the rows for a board 2 wide).
fn origin_is_white(img: &GrayImage, cells: &[[f64; 2]], board: &Chessboard) -> bool {
    let c = board.cols;
    let centre = |ids: [usize; 4]| {
        let x = ids.iter().map(|&k| cells[k][0]).sum::<f64>() / 4.0;
        let y = ids.iter().map(|&k| cells[k][1]).sum::<f64>() / 4.0;
        mean_around(img, x, y)
    };
    let origin = centre([0, 1, c, c + 1]);
    let next = if c >= 3 {
        centre([1, 2, c + 1, c + 2])
    } else {
        centre([c, c + 1, 2 * c, 2 * c + 1])
    };
    origin > next
}

fn mean_around(img: &GrayImage, x: f64, y: f64) -> f32 {
    let mut s = 0.0;
    for dy in [-1.0, 0.0, 1.0] {
        for dx in [-1.0, 0.0, 1.0] {
            s += img.sample(x + dx, y + dy);
        }
    }
    s / 9.0
}

/// The distance (px) from corner `id` to its nearest neighbour on the board.
pub fn local_spacing(cells: &[[f64; 2]], board: &Chessboard, id: usize) -> f64 {
    let (col, row) = (id % board.cols, id / board.cols);
    let p = cells[id];
    let mut best = f64::INFINITY;
    for (dc, dr) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
        let (nc, nr) = (col as i64 + dc, row as i64 + dr);
        if nc < 0 || nr < 0 || nc >= board.cols as i64 || nr >= board.rows as i64 {
            continue;
        }
        let q = cells[nr as usize * board.cols + nc as usize];
        best = best.min((q[0] - p[0]).hypot(q[1] - p[1]));
    }
    best
}
