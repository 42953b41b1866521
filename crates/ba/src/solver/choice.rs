//! Which linear solver runs, chosen from the structure of the reduced camera system before
//! anything of its size is allocated.
//!
//! For each candidate the cost of one Levenberg–Marquardt step and its peak memory are
//! estimated from the block pattern of S alone:
//!
//! | solver | memory (bytes) | work per step (flops) |
//! |---|---|---|
//! | dense | `8·nnz·(1 + workers) + 8·n²` | assembly `A` + `n³/3` |
//! | sparse | `8·nnz·(2 + workers) + 8·nnz(L)` | assembly `A` + `nnz(L)²/n` |
//! | iterative (its implicit product) | none beyond the Jacobians | `k · (Σ_o (4·m_o + 16) + Σ_b d_b²)` |
//!
//! (The iterative solver's cluster-Jacobi preconditioner adds `8·Σ_c d_c²·(1 + workers)`
//! bytes for its clusters c, at most `8·n·max_dim·(1 + workers)`; clusters that do not fit
//! in the memory limit are not used, and the preconditioner is then Schur–Jacobi, whose
//! blocks the table counts.)
//!
//! with n the dimension of S, nnz its stored upper triangle, workers the threads (each
//! assembles its own copy of S), `A = Σ_o 4 m_o² + Σ_f 6 (Σ_{o∈f} m_o)²` (m_o the
//! camera-side columns of observation o), nnz(L) the fill of the Cholesky factor from a
//! symbolic factorization of the block graph (scaled by the mean block size squared), and
//! k = 40 conjugate-gradient iterations, d_b the block sizes. The flop rates that turn work
//! into time (below) were measured on this project's benchmark (`bench/ba`): the scattered
//! assembly runs far below the factorizations' rate, and the implicit products are
//! bounded by memory bandwidth.
//!
//! `Auto` takes a factorization that fits in the memory limit (by default 80 % of the
//! memory the system reports available) unless the iterative solver's estimate is faster
//! by a margin: how many conjugate-gradient iterations a step needs depends on the
//! conditioning, which no block pattern tells exactly — but a camera graph in which most
//! cameras share points (S at least a quarter full) is well connected and needs tens (the
//! margin is [`ITERATIVE_MARGIN_CONNECTED`]), a long street of cameras hundreds
//! ([`ITERATIVE_MARGIN`]). The iterative solver always fits. When
//! `Auto` took it and a step needs more than `CgOptions::switch_after` iterations, the
//! solver moves to the factorization for the rest of the adjustment (the `fallback`), and
//! says so in the summary. An explicit choice that does not fit is refused with the memory
//! it would need.
//!
//! The iterative solver then applies S implicitly or explicitly ([`SchurProduct`]), judged
//! once its preconditioner's clusters are known ([`schur_product`]), by what differs
//! between the two in a step of k iterations (the preconditioner's inversion and
//! application are the same in both):
//!
//! | product | memory (bytes) | work per step (flops) | rate |
//! |---|---|---|---|
//! | implicit | none beyond the Jacobians | `P + k · Σ_o (4·m_o + 16)` | P at `BUILD_RATE`, products at `IMPLICIT_PRODUCT_RATE` |
//! | explicit | `8·nnz·(1 + workers) + 8·Σ_o 3 m_o` | `A + k · 4·nnz` | A at `BUILD_RATE`, products at `EXPLICIT_PRODUCT_RATE` |
//!
//! with P the work of the preconditioner's cluster matrices built from the observations,
//! `Σ_o 4 Σ_c m_oc² + Σ_f 6 Σ_c m_fc²` (m_oc, m_fc the columns of observation o, of point f's
//! observations, in cluster c): A with only the pairs inside a cluster. On a street the
//! clusters hold most pairs, P ≈ A, and the explicit product (a few neighbours per image)
//! wins; on a dense camera graph P ≪ A and S is dense, and the implicit one wins.

use super::clusters::Clusters;
use super::layout::Layout;
use super::linear::LinearSolverKind;

/// Flop rates (per second and thread) that turn the work estimates into time.
const ASSEMBLY_RATE: f64 = 0.6e9;
const DENSE_RATE: f64 = 12e9;
const SPARSE_RATE: f64 = 6e9;
const IMPLICIT_RATE: f64 = 1.0e9;
/// The rates of the choice between the implicit and the explicit product (per second and
/// thread), measured with this code on `pingcal ba --synthetic 200x30000` (banded and
/// random visibility, one thread): the assembly of S and the building of the cluster
/// matrices ran at 3–6 Gflop/s, the implicit product at 1.9–2.3, the explicit one at 3.7
/// (on a dense S; less on a street's short columns, where it is cheap anyway). They are
/// above the rates of the factorizations' estimates, which were measured on earlier code
/// and with which the margins above were set; here only their ratios matter.
const BUILD_RATE: f64 = 3.0e9;
const IMPLICIT_PRODUCT_RATE: f64 = 2.0e9;
const EXPLICIT_PRODUCT_RATE: f64 = 3.0e9;
/// Conjugate-gradient iterations assumed per step.
const CG_ITERATIONS: f64 = 40.0;
/// Below this dimension the dense factorization is taken without estimating anything else.
const SMALL: usize = 600;
/// How much faster the iterative estimate must be than the best factorization's for `Auto`
/// to take it on a sparse camera graph: the 40 iterations assumed per step can be off by
/// 10× there.
pub const ITERATIVE_MARGIN: f64 = 4.0;
/// The same margin on a well-connected camera graph (S at least 25 % full), where the
/// 40 iterations were measured to hold (`bench/ba`, random visibility).
pub const ITERATIVE_MARGIN_CONNECTED: f64 = 1.5;

/// The solver chosen and why.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SolverChoice {
    /// Dense, sparse or iterative (never `Auto`).
    pub kind: LinearSolverKind,
    /// One line: the estimates that decided it.
    pub reason: String,
    /// Estimated peak memory of the linear algebra of the chosen solver, bytes.
    pub memory_bytes: f64,
    /// When `Auto` took the iterative solver: the factorization it moves to if the
    /// conjugate gradients need too many iterations (`None`: none fits in memory).
    pub fallback: Option<LinearSolverKind>,
}

/// Why a solver that was asked for cannot run.
#[derive(Clone, Debug, thiserror::Error)]
#[error(
    "the {what} needs about {} of memory for a reduced system of {n} unknowns, \
     but {} is available: {advice}",
    gib(*.needs), gib(*.limit)
)]
pub struct TooLarge {
    /// What was asked for, e.g. "dense solver".
    pub what: String,
    /// What to ask for instead.
    pub advice: &'static str,
    /// Unknowns of the reduced camera system (the dimension of S).
    pub n: usize,
    /// Estimated peak memory of what was asked for, bytes.
    pub needs: f64,
    /// The memory limit it exceeds, bytes.
    pub limit: f64,
}

fn gib(bytes: f64) -> String {
    if bytes >= 1e9 {
        format!("{:.1} GB", bytes / 1e9)
    } else {
        format!("{:.0} MB", bytes / 1e6)
    }
}

/// The memory the system reports available (Linux: `MemAvailable`), if it can be read.
pub fn available_memory() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024.0)
}

struct Estimate {
    memory: f64,
    seconds: f64,
}

/// Chooses the solver for `layout`. `requested` other than `Auto` is honoured when it fits
/// in `memory_limit` (bytes; `None`: no limit known).
pub fn choose(
    layout: &Layout,
    requested: LinearSolverKind,
    workers: usize,
    memory_limit: Option<f64>,
) -> Result<SolverChoice, TooLarge> {
    let n = layout.n_reduced;
    let nnz = layout.nnz() as f64;
    let w = workers.max(1) as f64;
    let limit = memory_limit.unwrap_or(f64::INFINITY);
    let fits = |e: &Estimate| e.memory <= limit;
    let assembly = assembly_flops(layout);
    let dense = || {
        let nf = n as f64;
        Estimate {
            memory: 8.0 * nnz * (1.0 + w) + 8.0 * nf * nf,
            seconds: assembly / (ASSEMBLY_RATE * w)
                + nf * nf * nf / 3.0 / (DENSE_RATE * w.powf(0.8)),
        }
    };
    let iterative = || Estimate {
        memory: 8.0 * (layout.n_reduced as f64 * (6.0 + w))
            + 8.0 * layout.block_dim.iter().map(|d| (d * d) as f64).sum::<f64>(),
        seconds: CG_ITERATIONS * implicit_flops(layout) / (IMPLICIT_RATE * w),
    };
    let too_large = |kind, e: &Estimate| TooLarge {
        what: format!("{kind} solver"),
        advice: "use `--solver iterative` (or `auto`)",
        n,
        needs: e.memory,
        limit,
    };
    let pick = |kind, e: Estimate, reason: String| SolverChoice {
        kind,
        reason,
        memory_bytes: e.memory,
        fallback: None,
    };
    match requested {
        LinearSolverKind::Dense => {
            let e = dense();
            if !fits(&e) {
                return Err(too_large(LinearSolverKind::Dense, &e));
            }
            return Ok(pick(LinearSolverKind::Dense, e, "asked for".into()));
        }
        LinearSolverKind::Sparse => {
            let e = sparse(layout, w, assembly);
            if !fits(&e) {
                return Err(too_large(LinearSolverKind::Sparse, &e));
            }
            return Ok(pick(LinearSolverKind::Sparse, e, "asked for".into()));
        }
        LinearSolverKind::Iterative => {
            return Ok(pick(
                LinearSolverKind::Iterative,
                iterative(),
                "asked for".into(),
            ));
        }
        LinearSolverKind::Auto => {}
    }
    let d = dense();
    if n <= SMALL && fits(&d) {
        return Ok(pick(
            LinearSolverKind::Dense,
            d,
            format!("{n} unknowns in the reduced system (≤ {SMALL})"),
        ));
    }
    let fill = nnz / ((n * (n + 1) / 2).max(1) as f64);
    let s = sparse(layout, w, assembly);
    let it = iterative();
    let summary = format!(
        "{n} unknowns, S {:.0} % full; estimated per step: dense {:.2} s / {}, sparse {:.2} s / {}, iterative {:.2} s / {}",
        100.0 * fill,
        d.seconds,
        gib(d.memory),
        s.seconds,
        gib(s.memory),
        it.seconds,
        gib(it.memory)
    );
    let direct = [(LinearSolverKind::Sparse, s), (LinearSolverKind::Dense, d)]
        .into_iter()
        .filter(|(_, e)| fits(e))
        .min_by(|a, b| a.1.seconds.total_cmp(&b.1.seconds));
    let margin = if fill >= 0.25 {
        ITERATIVE_MARGIN_CONNECTED
    } else {
        ITERATIVE_MARGIN
    };
    let limit_note = if limit.is_finite() {
        format!("; memory limit {}", gib(limit))
    } else {
        String::new()
    };
    Ok(match direct {
        Some((kind, e)) if e.seconds <= margin * it.seconds => {
            pick(kind, e, format!("{summary}{limit_note}"))
        }
        direct => {
            let fallback = direct.map(|(kind, _)| kind);
            let note = match fallback {
                Some(k) => format!("; {k} if a step needs too many CG iterations"),
                None => "; no factorization fits in memory".into(),
            };
            SolverChoice {
                fallback,
                ..pick(
                    LinearSolverKind::Iterative,
                    it,
                    format!("{summary}{limit_note}{note}"),
                )
            }
        }
    })
}

/// The work of assembling S explicitly: `Σ_o 4 m_o² + Σ_f 6 (Σ_{o∈f} m_o)²`.
fn assembly_flops(layout: &Layout) -> f64 {
    pair_flops(layout, |_| 0)
}

/// The work of forming S's entries from the observations over the pairs of columns whose
/// blocks `group` puts together: `Σ_o 4 Σ_g m_og² + Σ_f 6 Σ_g m_fg²`, with m_og the columns
/// of observation o in group g and m_fg those of free point f's observations. One group is
/// the whole assembly A; the preconditioner's clusters give its build P (the module doc).
fn pair_flops(layout: &Layout, group: impl Fn(usize) -> u32) -> f64 {
    // Columns per group of one set of segments, as (group, columns) pairs.
    fn add(acc: &mut Vec<(u32, f64)>, g: u32, m: f64) {
        match acc.iter_mut().find(|e| e.0 == g) {
            Some(e) => e.1 += m,
            None => acc.push((g, m)),
        }
    }
    let squares = |acc: &[(u32, f64)]| acc.iter().map(|e| e.1 * e.1).sum::<f64>();
    let (mut obs, mut point) = (Vec::new(), Vec::new());
    let mut total = 0.0;
    for (p, run) in layout.point_runs(0..layout.obs_point.len()) {
        let free = layout.free_point_index[p as usize] != u32::MAX;
        point.clear();
        for o in run {
            obs.clear();
            for s in layout.segs(o) {
                let g = group(s.block as usize);
                add(&mut obs, g, s.len as f64);
                if free {
                    add(&mut point, g, s.len as f64);
                }
            }
            total += 4.0 * squares(&obs);
        }
        total += 6.0 * squares(&point);
    }
    total
}

/// How the conjugate gradients multiply by S.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SchurProduct {
    /// The cheaper of the two by the estimates of the block pattern, among those that fit in
    /// memory.
    Auto,
    /// One pass over the observations per product; S is never formed.
    Implicit,
    /// S is assembled once per step (its upper triangle, `8·nnz·(1 + workers)` bytes while
    /// assembling) and multiplied as a sparse matrix.
    Explicit,
}

impl std::fmt::Display for SchurProduct {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SchurProduct::Auto => "auto",
            SchurProduct::Implicit => "implicit",
            SchurProduct::Explicit => "explicit",
        })
    }
}

/// How the iterative solver applies S, and why.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProductChoice {
    /// Implicit or explicit (never `Auto`).
    pub product: SchurProduct,
    /// One line: the estimates that decided it.
    pub reason: String,
}

/// The iterative solver's product for `layout` with the preconditioner's `clusters`: the
/// one `requested`, or under `Auto` the cheaper by the module doc's estimates among those
/// that fit in `memory_limit` (the implicit one always does). An explicit product asked for
/// that does not fit is refused with the memory it would need.
pub fn schur_product(
    layout: &Layout,
    clusters: &Clusters,
    requested: SchurProduct,
    workers: usize,
    memory_limit: Option<f64>,
) -> Result<ProductChoice, TooLarge> {
    let w = workers.max(1) as f64;
    let nnz = layout.nnz() as f64;
    let per_obs: f64 = (layout.obs_ncols.iter())
        .map(|&m| 4.0 * m as f64 + 16.0)
        .sum();
    let implicit = pair_flops(layout, |b| clusters.of_block[b]) / (BUILD_RATE * w)
        + CG_ITERATIONS * per_obs / (IMPLICIT_PRODUCT_RATE * w);
    let explicit = assembly_flops(layout) / (BUILD_RATE * w)
        + CG_ITERATIONS * 4.0 * nnz / (EXPLICIT_PRODUCT_RATE * w);
    let memory = 8.0 * nnz * (1.0 + w) + 8.0 * layout.w_len as f64;
    let limit = memory_limit.unwrap_or(f64::INFINITY);
    let estimates = format!(
        "estimated per step (products and their set-up): implicit {implicit:.2} s, explicit {explicit:.2} s / {}",
        gib(memory)
    );
    let product = match requested {
        SchurProduct::Explicit if memory > limit => {
            return Err(TooLarge {
                what: "explicit Schur product".into(),
                advice: "use `--schur-product implicit` (or `auto`)",
                n: layout.n_reduced,
                needs: memory,
                limit,
            })
        }
        SchurProduct::Auto if explicit < implicit && memory <= limit => SchurProduct::Explicit,
        SchurProduct::Auto => SchurProduct::Implicit,
        asked => asked,
    };
    let why = if requested == SchurProduct::Auto {
        ""
    } else {
        "asked for; "
    };
    let fit = if requested == SchurProduct::Auto && memory > limit {
        "; the explicit one does not fit in memory"
    } else {
        ""
    };
    Ok(ProductChoice {
        product,
        reason: format!("{why}{estimates}{fit}"),
    })
}

/// The work of one implicit product S·x.
fn implicit_flops(layout: &Layout) -> f64 {
    let per_obs: f64 = (layout.obs_ncols.iter())
        .map(|&m| 4.0 * m as f64 + 16.0)
        .sum();
    per_obs + layout.block_dim.iter().map(|d| (d * d) as f64).sum::<f64>()
}

/// The sparse factorization's estimate: the fill of L from a symbolic factorization of the
/// block graph under the same ordering as the numeric one.
fn sparse(layout: &Layout, w: f64, assembly: f64) -> Estimate {
    let n = layout.n_reduced as f64;
    let nnz = layout.nnz() as f64;
    let nb = layout.num_blocks();
    let mean_d2 = layout.block_dim.iter().map(|d| (d * d) as f64).sum::<f64>() / nb.max(1) as f64;
    let l_scalar = super::linear::block_factor_entries(layout).map_or(n * n / 2.0, |l| l * mean_d2);
    Estimate {
        memory: 8.0 * nnz * (2.0 + w) + 8.0 * l_scalar,
        seconds: assembly / (ASSEMBLY_RATE * w)
            + l_scalar * l_scalar / n.max(1.0) / (SPARSE_RATE * w.powf(0.8)),
    }
}
