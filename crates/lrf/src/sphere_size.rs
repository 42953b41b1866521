//! When no ball of the nominal diameter is found: is a sphere of another size evident?
//!
//! A wrong diameter (the 38 mm default on a lidar frame of a 600 mm sphere, a diameter in
//! metres) finds nothing, and says nothing about why. [`evident_spheres`] looks for a sphere
//! of any size from 10 mm to 3.6 m across: the finder runs at each diameter of [`LADDER_MM`]
//! with its radius tests opened (any fit σ₀, a free radius within 100 % of the nominal),
//! which keeps the candidates whose free-radius fit determines a radius; each such radius
//! is then tried as the nominal one by the finder with the caller's own options, and the
//! first that finds balls is the answer. Its balls passed every test a ball passes at its
//! nominal size: the size is evident, not guessed.
//!
//! **Cost.** At most [`LADDER_MM`]`.len()` runs of the finder, then one per distinct
//! candidate size (at most [`MAX_TRIED`]): a bounded number of runs, each bounded by the
//! points (see [`crate::ball_finder`]).

use crate::ball_finder::{find_balls, FindResult, FinderOptions};
use crate::cloud::Cloud;

/// Nominal diameters tried, mm, a factor 2 apart: the finder's 4-point hypotheses take
/// radii from 0.5 to 1.5 times the nominal one, so together they take any sphere from
/// 10 mm to 3.6 m across.
pub const LADDER_MM: [f64; 8] = [20.0, 40.0, 80.0, 160.0, 320.0, 640.0, 1280.0, 2400.0];

/// Distinct candidate sizes tried as the nominal one, at most.
pub const MAX_TRIED: usize = 4;

/// A sphere size other than the nominal one that the cloud shows: the diameter (mm, from
/// the free-radius fits) and what the finder finds with it.
#[derive(Debug, Clone)]
pub struct Evident {
    /// The diameter, mm.
    pub diameter_mm: f64,
    /// The balls found with it as the nominal diameter (at least one).
    pub found: FindResult,
}

/// The spheres of other sizes than `opt.diameter_mm` that the cloud shows (see the module
/// doc), the best supported first (by the most rays on one of their balls).
pub fn evident_spheres(cloud: &Cloud, opt: &FinderOptions) -> Vec<Evident> {
    let mut sizes: Vec<(f64, usize)> = Vec::new(); // (diameter, how many fits gave it)
    for d in LADDER_MM {
        let open = FinderOptions {
            diameter_mm: d,
            max_sigma0: f64::INFINITY,
            radius_tolerance: 1.0,
            ..*opt
        };
        for b in find_balls(cloud, &open).balls {
            let s = &b.support;
            if !s.free_radius_determined(d / 2.0) {
                continue;
            }
            let free = 2.0 * s.free_radius_mm;
            // the nominal size itself was tried by the caller
            if (free / opt.diameter_mm - 1.0).abs() < 0.1 {
                continue;
            }
            match sizes
                .iter_mut()
                .find(|(x, _)| (free / *x - 1.0).abs() < 0.1)
            {
                Some((_, n)) => *n += 1,
                None => sizes.push((free, 1)),
            }
        }
    }
    sizes.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.total_cmp(&b.0)));
    let mut out: Vec<Evident> = sizes
        .into_iter()
        .take(MAX_TRIED)
        .filter_map(|(d, _)| {
            let d = d.round();
            let found = find_balls(
                cloud,
                &FinderOptions {
                    diameter_mm: d,
                    ..*opt
                },
            );
            (!found.balls.is_empty()).then_some(Evident {
                diameter_mm: d,
                found,
            })
        })
        .collect();
    out.sort_by_key(|e| std::cmp::Reverse(e.support()));
    out
}

impl Evident {
    /// The most rays on one of its balls.
    pub fn support(&self) -> usize {
        self.found
            .balls
            .iter()
            .map(|b| b.inliers.len())
            .max()
            .unwrap_or(0)
    }
}
