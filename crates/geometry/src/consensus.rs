//! Robust estimation by random sample consensus: one loop for every RANSAC of pingcal.
//!
//! A problem is an [`Estimator`]: `len()` data items, a minimal solver that turns a sample of
//! `sample_size()` items into zero or more candidate models (none for a degenerate sample:
//! the per-sample tests of a problem live there), a residual of any item under a model (in
//! the units of the threshold τ; divide by a per-item σ for per-item thresholds), and
//! optionally a least-squares refit on a larger set (the local optimisation of LO-RANSAC,
//! Chum, Matas & Kittler 2003).
//!
//! [`find`] draws samples from a seeded [`SeededRng`], scores every candidate over all items
//! and keeps the best. Scores compare the squared residual `rᵢ²` (the estimator may give it
//! directly, [`Estimator::residual_squared`], to spare a square root) with `τ²`:
//! - [`Scoring::InlierCount`] (RANSAC): the number of items with `rᵢ² ≤ τ²`, more is
//!   better;
//! - [`Scoring::Msac`] (Torr & Zisserman 2000): `Σ min(rᵢ², τ²)`, less is better, so that
//!   among models with as many inliers the one that fits them better wins.
//!
//! Samples are drawn as [`Sampling`] says: `k` distinct items (a repeat drawn again, the
//! default), `k` independent draws that may repeat an item (the estimator's `fit` rejects
//! such a sample as degenerate, and it counts as drawn), or `k` independent draws of which a
//! sample with a repeat is drawn again whole (not counted). With
//! [`ConsensusOptions::exhaustive`], when there are no more `k`-subsets than
//! `max_iterations`, every subset is tried once in lexicographic order instead, and the
//! generator is not touched.
//!
//! A candidate replaces the best only when it scores strictly better, so the first of equal
//! models is kept and the result is a function of the seed alone. When a new best is found
//! and `local_refits > 0` it is refitted on its inliers up to that many times, each refit
//! kept only if it scores better (LO-RANSAC). With `confidence = Some(p)` the loop stops once
//! the probability of never having drawn an all-inlier sample falls below `1 − p`, i.e.
//! after `N = ln(1 − p) / ln(1 − wᵏ)` samples for the best model's inlier ratio `w` and
//! sample size `k` (never before `min_iterations`, never after `max_iterations`). Finally
//! the best model is refitted on its inliers `final_refits` times, as a closing
//! least-squares polish; [`RefitRule`] says which refits are kept (by default those that
//! leave at least `sample_size()` inliers), and the polish stops at the first refused or
//! failed one (refitting the same inliers again would give the same model).
//!
//! ## Seeds and streams
//!
//! Every random choice of pingcal comes from [`rng`] (or [`rng_stream`] for independent
//! streams under one seed): ChaCha with 12 rounds, seeded through `rand_core`'s documented
//! `seed_from_u64` expansion. That stream is fixed by the ChaCha algorithm, not by a crate
//! version, so the same seed gives the same result on any machine and after any upgrade
//! (rand's `StdRng` makes no such promise). It is also the stream rand 0.9's `StdRng` gave,
//! which pingcal used before, so results from before the switch are reproduced exactly.

use rand::{Rng, SeedableRng};

/// The generator of every random choice in pingcal (see the module doc).
pub type SeededRng = rand_chacha::ChaCha12Rng;

/// The generator for `seed`.
pub fn rng(seed: u64) -> SeededRng {
    SeededRng::seed_from_u64(seed)
}

/// An independent stream `stream` under `seed` (ChaCha's stream counter): several random
/// consumers of one run draw from their own streams and do not shift each other.
pub fn rng_stream(seed: u64, stream: u64) -> SeededRng {
    let mut r = rng(seed);
    r.set_stream(stream);
    r
}

/// A robust-estimation problem (see the module doc).
pub trait Estimator {
    /// What is estimated.
    type Model;
    /// Number of data items.
    fn len(&self) -> usize;
    /// Whether there are no data items.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Size of a minimal sample.
    fn sample_size(&self) -> usize;
    /// Candidate models from the minimal sample `sample` (item indices, distinct unless
    /// [`Sampling::Independent`]), appended to `models` (none for a degenerate sample).
    fn fit(&self, sample: &[usize], models: &mut Vec<Self::Model>);
    /// Residual of item `i` under `model`, ≥ 0, in the units of the threshold (∞ when the
    /// model cannot explain the item at all).
    fn residual(&self, model: &Self::Model, i: usize) -> f64;
    /// The squared residual, which the scores use: by default `residual²`; an estimator
    /// whose residual is a norm gives its square directly (no square root, and the same
    /// sums as a loop written on squared norms).
    fn residual_squared(&self, model: &Self::Model, i: usize) -> f64 {
        let r = self.residual(model, i);
        r * r
    }
    /// A least-squares model on `inliers` (more than a minimal sample), starting from
    /// `model`; `None` when the estimator has no refit or it fails. Used by local
    /// optimisation and by the final polish.
    fn refit(&self, _inliers: &[usize], _model: &Self::Model) -> Option<Self::Model> {
        None
    }
}

/// How candidates are scored (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scoring {
    /// RANSAC: the number of items within the threshold.
    InlierCount,
    /// MSAC: the sum of squared residuals truncated at the threshold.
    Msac,
}

/// How a sample of `k` items is drawn (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sampling {
    /// `k` distinct items, each by `random_range(0..n)`, a repeat drawn again
    /// ([`sample_distinct`]).
    #[default]
    Distinct,
    /// `k` independent `random_range(0..n)`; the sample may repeat an item, which the
    /// estimator's `fit` must treat as degenerate. Every sample counts as drawn.
    Independent,
    /// `k` independent `random_range(0..n)`; a sample that repeats an item is discarded
    /// whole and drawn again, and does not count as drawn.
    RejectRepeats,
}

/// Which refits of the final polish are kept (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RefitRule {
    /// A refit that leaves at least `sample_size()` inliers.
    #[default]
    EnoughInliers,
    /// A refit with at least as many inliers as the model it replaces.
    NotFewerInliers,
    /// Every refit that succeeds.
    Always,
}

/// Settings of [`find`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConsensusOptions {
    /// Inlier threshold τ on the residual.
    pub threshold: f64,
    /// Samples drawn at most.
    pub max_iterations: usize,
    /// Samples drawn at least (with `confidence`).
    pub min_iterations: usize,
    /// Stop adaptively at this confidence (e.g. 0.999); `None`: draw `max_iterations`.
    pub confidence: Option<f64>,
    /// Scoring of candidates.
    pub scoring: Scoring,
    /// Refits of each new best model on its inliers (LO-RANSAC); 0: plain.
    pub local_refits: usize,
    /// Refits of the final model on its inliers.
    pub final_refits: usize,
    /// Which of those refits are kept.
    pub final_refit_rule: RefitRule,
    /// How samples are drawn.
    pub sampling: Sampling,
    /// Try every `k`-subset once (lexicographic order, no random draws) when there are at
    /// most `max_iterations` of them.
    pub exhaustive: bool,
}

impl ConsensusOptions {
    /// `iterations` samples, MSAC scoring, no local optimisation or refit.
    pub fn msac(threshold: f64, iterations: usize) -> Self {
        Self {
            threshold,
            max_iterations: iterations,
            min_iterations: 0,
            confidence: None,
            scoring: Scoring::Msac,
            local_refits: 0,
            final_refits: 0,
            final_refit_rule: RefitRule::EnoughInliers,
            sampling: Sampling::Distinct,
            exhaustive: false,
        }
    }

    /// `iterations` samples, inlier-count scoring, no local optimisation or refit.
    pub fn ransac(threshold: f64, iterations: usize) -> Self {
        Self {
            scoring: Scoring::InlierCount,
            ..Self::msac(threshold, iterations)
        }
    }
}

/// The result of [`find`].
#[derive(Clone, Debug, PartialEq)]
pub struct Consensus<M> {
    /// The best model.
    pub model: M,
    /// Indices of the items within the threshold of it, ascending.
    pub inliers: Vec<usize>,
    /// Its score as a cost (lower is better): `−count` for inlier counting, the truncated
    /// sum for MSAC.
    pub cost: f64,
    /// Samples drawn.
    pub iterations: usize,
}

/// Draws `k` distinct indices below `n` into `out` (cleared first), each by
/// `rng.random_range(0..n)` with repeats drawn again. `false` (and `out` empty) if `k > n`.
pub fn sample_distinct(rng: &mut impl Rng, n: usize, k: usize, out: &mut Vec<usize>) -> bool {
    out.clear();
    if k > n {
        return false;
    }
    while out.len() < k {
        let c = rng.random_range(0..n);
        if !out.contains(&c) {
            out.push(c);
        }
    }
    true
}

/// Draws `k` independent indices below `n` into `out` (cleared first), each by
/// `rng.random_range(0..n)`; they may repeat. `false` (and `out` empty) if `n == 0`.
pub fn sample_independent(rng: &mut impl Rng, n: usize, k: usize, out: &mut Vec<usize>) -> bool {
    out.clear();
    if n == 0 {
        return false;
    }
    out.extend((0..k).map(|_| rng.random_range(0..n)));
    true
}

/// Number of `k`-subsets of `n` items, `None` when it does not fit a `usize`.
fn subsets(n: usize, k: usize) -> Option<usize> {
    let mut c = 1usize;
    for i in 0..k.min(n + 1) {
        // C(n, i + 1) = C(n, i) (n − i) / (i + 1), exact in integers.
        c = c.checked_mul(n - i)? / (i + 1);
    }
    Some(if k > n { 0 } else { c })
}

/// The `k`-subset after `c` in lexicographic order (`c` ascending), in place; `false` after
/// the last.
fn next_subset(c: &mut [usize], n: usize) -> bool {
    let k = c.len();
    for i in (0..k).rev() {
        if c[i] < n - k + i {
            c[i] += 1;
            for j in i + 1..k {
                c[j] = c[j - 1] + 1;
            }
            return true;
        }
    }
    false
}

/// Where the samples of one run come from.
enum Sampler {
    /// Every subset in turn; `None` before the first.
    Exhaustive(Option<Vec<usize>>),
    /// Random draws.
    Random(Sampling),
}

impl Sampler {
    /// The next sample into `out`; `false` when there is none (all subsets tried).
    fn next(&mut self, rng: &mut impl Rng, n: usize, k: usize, out: &mut Vec<usize>) -> bool {
        match self {
            Sampler::Exhaustive(c) => {
                let more = match c {
                    None => {
                        *c = Some((0..k).collect());
                        true
                    }
                    Some(c) => next_subset(c, n),
                };
                out.clear();
                out.extend(c.iter().flatten());
                more
            }
            Sampler::Random(Sampling::Distinct) => sample_distinct(rng, n, k, out),
            Sampler::Random(Sampling::Independent) => sample_independent(rng, n, k, out),
            Sampler::Random(Sampling::RejectRepeats) => loop {
                if !sample_independent(rng, n, k, out) || k > n {
                    out.clear();
                    return false;
                }
                if (1..k).all(|a| !out[..a].contains(&out[a])) {
                    return true;
                }
            },
        }
    }
}

/// Scores `model` over all items: (cost, inlier count).
pub fn score<E: Estimator>(est: &E, model: &E::Model, opts: &ConsensusOptions) -> (f64, usize) {
    let tau2 = opts.threshold * opts.threshold;
    let (mut cost, mut count) = (0.0, 0usize);
    for i in 0..est.len() {
        let r2 = est.residual_squared(model, i);
        if r2 <= tau2 {
            count += 1;
        }
        if opts.scoring == Scoring::Msac {
            cost += if r2 <= tau2 { r2 } else { tau2 };
        }
    }
    if opts.scoring == Scoring::InlierCount {
        cost = -(count as f64);
    }
    (cost, count)
}

/// The items within the threshold of `model` (`r² ≤ τ²`), ascending.
pub fn inliers<E: Estimator>(est: &E, model: &E::Model, threshold: f64) -> Vec<usize> {
    let tau2 = threshold * threshold;
    (0..est.len())
        .filter(|&i| est.residual_squared(model, i) <= tau2)
        .collect()
}

/// Samples needed for confidence `p` with inlier ratio `w` and sample size `k`.
fn needed(p: f64, w: f64, k: usize) -> usize {
    let all_in = w.powi(k as i32);
    if all_in >= 1.0 {
        return 0;
    }
    if all_in <= 0.0 {
        return usize::MAX;
    }
    let n = (1.0 - p).ln() / (1.0 - all_in).ln();
    if n.is_finite() && n >= 0.0 {
        n.ceil().min(usize::MAX as f64) as usize
    } else {
        usize::MAX
    }
}

/// Refits `best` on its inliers up to `times`, keeping a refit only if it scores better.
fn locally_optimise<E: Estimator>(
    est: &E,
    opts: &ConsensusOptions,
    best: &mut (f64, usize, E::Model),
    times: usize,
) {
    for _ in 0..times {
        let inl = inliers(est, &best.2, opts.threshold);
        if inl.len() <= est.sample_size() {
            return;
        }
        let Some(m) = est.refit(&inl, &best.2) else {
            return;
        };
        let (c, n) = score(est, &m, opts);
        if c < best.0 {
            *best = (c, n, m);
        } else {
            return;
        }
    }
}

/// The best model by random sample consensus (see the module doc), or `None` when there
/// are fewer items than a sample or no sample gave a model.
pub fn find<E: Estimator>(
    est: &E,
    opts: &ConsensusOptions,
    rng: &mut impl Rng,
) -> Option<Consensus<E::Model>> {
    let (n, k) = (est.len(), est.sample_size());
    if n < k || k == 0 {
        return None;
    }
    let mut best: Option<(f64, usize, E::Model)> = None;
    let mut sample = Vec::with_capacity(k);
    let mut models = Vec::new();
    let mut limit = opts.max_iterations;
    let mut sampler = match subsets(n, k) {
        Some(all) if opts.exhaustive && all <= opts.max_iterations => {
            limit = all;
            Sampler::Exhaustive(None)
        }
        _ => Sampler::Random(opts.sampling),
    };
    let mut drawn = 0;
    while drawn < limit {
        if !sampler.next(rng, n, k, &mut sample) {
            break;
        }
        drawn += 1;
        models.clear();
        est.fit(&sample, &mut models);
        let mut improved = false;
        for m in models.drain(..) {
            let (c, cnt) = score(est, &m, opts);
            if best.as_ref().is_none_or(|b| c < b.0) {
                best = Some((c, cnt, m));
                improved = true;
            }
        }
        if improved {
            if let Some(b) = best.as_mut() {
                locally_optimise(est, opts, b, opts.local_refits);
                if let Some(p) = opts.confidence {
                    let w = b.1 as f64 / n as f64;
                    limit = needed(p, w, k).clamp(opts.min_iterations, opts.max_iterations);
                }
            }
        }
    }
    let mut best = best?;
    for _ in 0..opts.final_refits {
        let inl = inliers(est, &best.2, opts.threshold);
        if inl.len() < k {
            break;
        }
        let Some(m) = est.refit(&inl, &best.2) else {
            break;
        };
        let (c, cnt) = score(est, &m, opts);
        let keep = match opts.final_refit_rule {
            RefitRule::EnoughInliers => cnt >= k,
            RefitRule::NotFewerInliers => cnt >= best.1,
            RefitRule::Always => true,
        };
        if !keep {
            break;
        }
        best = (c, cnt, m);
    }
    let inliers = inliers(est, &best.2, opts.threshold);
    Some(Consensus {
        model: best.2,
        inliers,
        cost: best.0,
        iterations: drawn,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2D line `y = a x + b` through noisy points with outliers.
    struct Line<'a>(&'a [(f64, f64)]);

    impl Estimator for Line<'_> {
        type Model = (f64, f64);
        fn len(&self) -> usize {
            self.0.len()
        }
        fn sample_size(&self) -> usize {
            2
        }
        fn fit(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
            let ((x0, y0), (x1, y1)) = (self.0[s[0]], self.0[s[1]]);
            if (x1 - x0).abs() > 1e-12 {
                let a = (y1 - y0) / (x1 - x0);
                out.push((a, y0 - a * x0));
            }
        }
        fn residual(&self, m: &(f64, f64), i: usize) -> f64 {
            let (x, y) = self.0[i];
            (y - m.0 * x - m.1).abs()
        }
        fn refit(&self, inl: &[usize], _: &(f64, f64)) -> Option<(f64, f64)> {
            let n = inl.len() as f64;
            let (sx, sy) = inl
                .iter()
                .fold((0.0, 0.0), |a, &i| (a.0 + self.0[i].0, a.1 + self.0[i].1));
            let (mx, my) = (sx / n, sy / n);
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for &i in inl {
                let (x, y) = self.0[i];
                sxy += (x - mx) * (y - my);
                sxx += (x - mx) * (x - mx);
            }
            (sxx > 0.0).then(|| (sxy / sxx, my - sxy / sxx * mx))
        }
    }

    fn data(seed: u64) -> Vec<(f64, f64)> {
        let mut r = rng(seed);
        (0..200)
            .map(|i| {
                let x = i as f64 * 0.1;
                if i % 3 == 0 {
                    (x, r.random_range(-50.0..50.0))
                } else {
                    (x, 2.0 * x - 1.0 + r.random_range(-0.05..0.05))
                }
            })
            .collect()
    }

    #[test]
    fn finds_the_line_among_a_third_of_outliers_with_every_scoring() {
        let d = data(3);
        for scoring in [Scoring::InlierCount, Scoring::Msac] {
            let opts = ConsensusOptions {
                confidence: Some(0.999),
                min_iterations: 10,
                local_refits: 3,
                final_refits: 2,
                scoring,
                ..ConsensusOptions::msac(0.1, 1000)
            };
            let c = find(&Line(&d), &opts, &mut rng(7)).unwrap();
            assert!(
                (c.model.0 - 2.0).abs() < 0.01 && (c.model.1 + 1.0).abs() < 0.05,
                "{c:?}"
            );
            assert!(
                c.inliers.len() >= 130
                    && c.inliers.iter().all(|&i| i % 3 != 0 || d[i].1.abs() < 50.0)
            );
            assert!(c.iterations < 1000, "adaptive stop: {}", c.iterations);
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_result_and_another_seed_its_own_draws() {
        let d = data(5);
        let opts = ConsensusOptions::ransac(0.1, 50);
        let a = find(&Line(&d), &opts, &mut rng(11)).unwrap();
        let b = find(&Line(&d), &opts, &mut rng(11)).unwrap();
        assert_eq!(a, b);
        let mut s1 = Vec::new();
        let mut s2 = Vec::new();
        sample_distinct(&mut rng_stream(11, 0), 100, 5, &mut s1);
        sample_distinct(&mut rng_stream(11, 1), 100, 5, &mut s2);
        assert_ne!(s1, s2);
        assert!(!sample_distinct(&mut rng(1), 3, 4, &mut s1) && s1.is_empty());
    }

    #[test]
    fn too_few_items_or_no_model_gives_none() {
        let d = [(1.0, 1.0)];
        assert!(find(&Line(&d), &ConsensusOptions::msac(0.1, 10), &mut rng(1)).is_none());
        let same_x = [(1.0, 1.0), (1.0, 2.0), (1.0, 3.0)];
        assert!(find(
            &Line(&same_x),
            &ConsensusOptions::msac(0.1, 10),
            &mut rng(1)
        )
        .is_none());
    }

    /// Records every sample `find` hands to `fit`, and fits nothing unless asked.
    struct Recorder {
        n: usize,
        k: usize,
        seen: std::cell::RefCell<Vec<Vec<usize>>>,
    }

    impl Estimator for Recorder {
        type Model = usize;
        fn len(&self) -> usize {
            self.n
        }
        fn sample_size(&self) -> usize {
            self.k
        }
        fn fit(&self, s: &[usize], out: &mut Vec<usize>) {
            self.seen.borrow_mut().push(s.to_vec());
            out.push(s[0]);
        }
        fn residual(&self, m: &usize, i: usize) -> f64 {
            (*m as f64 - i as f64).abs()
        }
    }

    fn recorded(n: usize, k: usize, opts: &ConsensusOptions, seed: u64) -> Vec<Vec<usize>> {
        let est = Recorder {
            n,
            k,
            seen: Default::default(),
        };
        find(&est, opts, &mut rng(seed)).unwrap();
        est.seen.into_inner()
    }

    #[test]
    fn exhaustive_tries_every_subset_once_in_order_when_few() {
        let opts = ConsensusOptions {
            exhaustive: true,
            ..ConsensusOptions::msac(0.5, 10)
        };
        let all = recorded(5, 3, &opts, 1);
        let mut expected = Vec::new();
        for a in 0..5 {
            for b in a + 1..5 {
                for c in b + 1..5 {
                    expected.push(vec![a, b, c]);
                }
            }
        }
        assert_eq!(all, expected);
        // 35 subsets of 7 are more than 10 samples: drawn at random instead
        let drawn = recorded(7, 3, &opts, 1);
        assert_eq!(drawn, recorded(7, 3, &ConsensusOptions::msac(0.5, 10), 1));
        assert_eq!(subsets(40, 3), Some(9880));
        assert_eq!(subsets(3, 4), Some(0));
        assert_eq!(subsets(1 << 40, 5), None);
    }

    #[test]
    fn each_sampling_draws_as_it_says() {
        let (n, k) = (4, 3);
        let mut r = rng(2);
        let raw: Vec<usize> = (0..3000).map(|_| r.random_range(0..n)).collect();
        let opts = |sampling| ConsensusOptions {
            sampling,
            ..ConsensusOptions::ransac(0.5, 40)
        };
        // independent: the raw stream cut in threes, repeats and all
        let ind = recorded(n, k, &opts(Sampling::Independent), 2);
        assert_eq!(ind.concat(), raw[..120]);
        assert!(ind
            .iter()
            .any(|s| s[0] == s[1] || s[1] == s[2] || s[0] == s[2]));
        // reject repeats: the raw triples without a repeat, in order
        let distinct_triples: Vec<Vec<usize>> = raw
            .chunks(3)
            .filter(|s| s[0] != s[1] && s[1] != s[2] && s[0] != s[2])
            .take(40)
            .map(<[usize]>::to_vec)
            .collect();
        assert_eq!(
            recorded(n, k, &opts(Sampling::RejectRepeats), 2),
            distinct_triples
        );
        // distinct: each repeat drawn again
        let mut by_hand = Vec::new();
        let mut s = Vec::new();
        let mut r = rng(2);
        for _ in 0..40 {
            sample_distinct(&mut r, n, k, &mut s);
            by_hand.push(s.clone());
        }
        assert_eq!(recorded(n, k, &opts(Sampling::Distinct), 2), by_hand);
    }

    /// A "model" is a set of accepted items; the refit drops the largest inlier, so each
    /// refit has one inlier fewer.
    struct Shrinking;

    impl Estimator for Shrinking {
        type Model = usize;
        fn len(&self) -> usize {
            10
        }
        fn sample_size(&self) -> usize {
            2
        }
        fn fit(&self, s: &[usize], out: &mut Vec<usize>) {
            if s.contains(&0) {
                out.push(5);
            }
        }
        fn residual(&self, m: &usize, i: usize) -> f64 {
            if i < *m {
                0.0
            } else {
                1.0
            }
        }
        fn refit(&self, inl: &[usize], _: &usize) -> Option<usize> {
            Some(inl.len() - 1)
        }
    }

    #[test]
    fn the_refit_rule_decides_which_refits_are_kept() {
        let run = |rule| {
            let opts = ConsensusOptions {
                final_refits: 4,
                final_refit_rule: rule,
                exhaustive: true,
                ..ConsensusOptions::ransac(0.5, 100)
            };
            find(&Shrinking, &opts, &mut rng(1)).unwrap().inliers.len()
        };
        assert_eq!(run(RefitRule::NotFewerInliers), 5);
        assert_eq!(run(RefitRule::Always), 1);
        assert_eq!(run(RefitRule::EnoughInliers), 2);
    }

    /// The stream is ChaCha12's: fixed values, whatever the crate versions (and the stream
    /// that rand 0.9's `StdRng` gave, which pingcal used before).
    #[test]
    fn the_stream_of_a_seed_is_fixed() {
        let mut r = rng(42);
        let v: Vec<u64> = (0..3).map(|_| r.random::<u64>()).collect();
        let mut std = rand::rngs::StdRng::seed_from_u64(42);
        let w: Vec<u64> = (0..3).map(|_| std.random::<u64>()).collect();
        assert_eq!(v, w);
        assert_eq!(v, KNOWN_42);
    }

    const KNOWN_42: [u64; 3] = [
        9713269763989775522,
        10011513049433592189,
        11740708795755607249,
    ];
}
