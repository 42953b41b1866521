//! Precision of an adjusted network, as Australis reports it: σ0, redundancy, RMS image
//! residual, standard deviations and correlations of the intrinsics, standard deviations
//! of every pose and every point.
//!
//! Computed from the Schur structure without inverting the full normal matrix: the
//! cofactor matrix of the camera-side unknowns is `Q_cc = S⁻¹` (S undamped), and that of a
//! point eliminated by the Schur complement is
//! `Q_pp = V⁻¹ + (W V⁻¹)ᵀ S⁻¹ (W V⁻¹)`, which needs only the blocks of S⁻¹ of the images
//! that see the point. Covariances are `σ0² · Q`, σ0 the a-posteriori standard deviation
//! of unit weight, `σ0² = 2·cost / redundancy` (cost = ½ Σ of the whitened residuals).
//!
//! Only the entries of S⁻¹ between unknowns that share an observation, a point or a
//! constraint are needed, all inside the pattern of S's sparse Cholesky factor: they come
//! from a selected inversion of that factor (`selected_inverse`), at about the cost of the
//! factorization on a sparse camera graph and with memory proportional to the factor. A
//! camera graph so dense that the factor is nearly full is inverted whole from a dense
//! Cholesky factorization instead (blocked and parallel: faster there, 3 n² values); the
//! choice is made from the block pattern before S is assembled, and a system too large for
//! both is refused with what each would need. The eigenvectors of the dense S (up to
//! [`MAX_DENSE_PRECISION`] reduced unknowns) count and name a datum defect
//! ([`CofactorMethod`]).
//!
//! A network whose datum is not fully defined (free position, orientation or scale) has a
//! singular S: this is diagnosed and named, never solved. A free network (no datum at all)
//! gets the minimum-trace datum of inner constraints on its points: the reduced system
//! bordered by them, whose inverse is formed densely or, at any size, from a minimal
//! datum's selected inverse by an S-transformation ([`Transformed`]).

use super::evaluate::{linearize, Linearization};
use super::layout::Layout;
use super::schur::Schur;
use super::selected_inverse::{
    CofactorLookup, DenseInverse, Factored, SelectedError, SelectedInverse,
};
use super::sigma::{
    intrinsics_precision, parameters_covariance, pose_sigmas, rig_covariances,
    rigs_and_parameters_covariance, Precision, PrecisionError, BORDERED_DENSE, DENSE,
    DENSE_CHOLESKY, MAX_DENSE_PRECISION, SELECTED, TRANSFORMED, TRANSFORMED_DENSE,
};
use crate::problem::Problem;
use nalgebra::{DMatrix, Matrix2, Matrix2x3, Matrix3};

/// How the cofactors of the reduced unknowns are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CofactorMethod {
    /// Sparse; a camera graph too dense for the sparse factor by the dense Cholesky inverse;
    /// a datum defect counted and named by the dense eigenvectors (up to
    /// [`MAX_DENSE_PRECISION`] reduced unknowns).
    Auto,
    /// S⁻¹ formed densely (refused above [`MAX_DENSE_PRECISION`] reduced unknowns). A free
    /// network: the dense inner-constraint solution up to
    /// [`MAX_FREE_NETWORK_UNKNOWNS`](super::MAX_FREE_NETWORK_UNKNOWNS) unknowns, the
    /// bordered reduced system above.
    Dense,
    /// The entries of S⁻¹ on the pattern of its sparse Cholesky factor (a selected
    /// inversion); a free network by the S-transformation of a minimal datum's cofactors.
    Sparse,
    /// S⁻¹ whole from a dense Cholesky factorization (faer, parallel; 3 n² values), as Auto
    /// does for a camera graph too dense for the sparse factor; a free network by the
    /// S-transformation.
    DenseCholesky,
}

/// What both [`precision`] and [`points_covariance`] start from: the linearization at the
/// estimate, the undamped Schur complement and `Q_cc = S⁻¹`.
struct Cofactors {
    layout: Layout,
    lin: Linearization,
    schur: Schur,
    q_cc: Box<dyn CofactorLookup>,
    /// How q_cc was had ([`Precision::cofactors`]).
    how: &'static str,
}

/// The linearization of `problem` at its estimate; an observation that does not project is
/// named.
pub(super) fn linearized(
    problem: &Problem,
    layout: &Layout,
) -> Result<Linearization, PrecisionError> {
    let mut lin = Linearization::new(layout);
    linearize(problem, layout, &mut lin).map_err(|u| u.describe(problem))?;
    Ok(lin)
}

/// The cofactors of `problem`; `Ok(None)` for a free network (inner constraints needed).
fn cofactors(
    problem: &Problem,
    method: CofactorMethod,
) -> Result<Option<Cofactors>, PrecisionError> {
    problem.validate()?;
    let layout = Layout::new(problem);
    let n = layout.n_reduced;
    if method != CofactorMethod::Dense && super::free_network::is_free(problem) {
        // S is singular by the similarity: the free network's own forms.
        return Ok(None);
    }
    if method == CofactorMethod::Dense && n > MAX_DENSE_PRECISION {
        return Err(PrecisionError::TooLarge(format!(
            "the reduced camera system has {n} unknowns; its inverse is formed densely for at most {MAX_DENSE_PRECISION}"
        )));
    }
    // The form is chosen, and one too large refused, before S is assembled.
    let route = match method {
        CofactorMethod::Dense => None,
        _ => Some(route(&layout, problem, method)?),
    };
    let lin = linearized(problem, &layout)?;
    let schur = reduced_schur(problem, &layout, &lin)?;
    let dense = |schur: &Schur| -> Result<Option<Box<dyn CofactorLookup>>, PrecisionError> {
        match invert_or_diagnose(&dense_s(&layout, schur), problem, &layout) {
            Ok(q) => Ok(Some(Box::new(q))),
            Err(PrecisionError::DatumDefect(_)) if super::free_network::is_free(problem) => {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    };
    let (q_cc, how): (Box<dyn CofactorLookup>, _) = match route {
        None => match dense(&schur)? {
            Some(q) => (q, DENSE),
            None => return Ok(None),
        },
        Some(route) => {
            let held = vec![false; n];
            match factored(route, &layout, &schur.values, &held, problem) {
                Ok(q) => (q as Box<dyn CofactorLookup>, route.name()),
                // A defect is counted and named by the dense eigenvectors where they can be
                // had.
                Err(PrecisionError::DatumDefect(_))
                    if method == CofactorMethod::Auto && n <= MAX_DENSE_PRECISION =>
                {
                    match dense(&schur)? {
                        Some(q) => (q, DENSE),
                        None => return Ok(None),
                    }
                }
                Err(e) => return Err(e),
            }
        }
    };
    Ok(Some(Cofactors {
        layout,
        lin,
        schur,
        q_cc,
        how,
    }))
}

/// The form of S⁻¹ under a datum: a selected inversion of the sparse factor, or the whole
/// inverse from a dense Cholesky factorization.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Route {
    Selected,
    DenseCholesky,
}

impl Route {
    fn name(self) -> &'static str {
        match self {
            Route::Selected => SELECTED,
            Route::DenseCholesky => DENSE_CHOLESKY,
        }
    }
}

/// The form `method` asks for (Auto: the selected inversion where its factor fits, else the
/// dense Cholesky inverse where that fits in memory), judged before S is assembled; refused
/// with the figures of both when neither can be had.
fn route(
    layout: &Layout,
    problem: &Problem,
    method: CofactorMethod,
) -> Result<Route, PrecisionError> {
    let dense_fits = || {
        let bytes = DenseInverse::bytes(layout.n_reduced) + 16.0 * layout.nnz() as f64;
        match memory_limit() {
            Some(m) if bytes > m => Err(format!(
                "the dense inverse would need {:.1} GiB of the {:.1} GiB available",
                bytes / 1073741824.0,
                m / 1073741824.0
            )),
            _ => Ok(()),
        }
    };
    match method {
        CofactorMethod::Sparse => selected_fits(layout, problem).map(|_| Route::Selected),
        CofactorMethod::DenseCholesky => dense_fits()
            .map(|()| Route::DenseCholesky)
            .map_err(PrecisionError::TooLarge),
        _ => match (selected_fits(layout, problem), dense_fits()) {
            (Ok(work), Ok(())) => {
                // Both fit: the faster, by the work of each.
                let n = layout.n_reduced as f64;
                Ok(if work > DENSE_ABOVE_WORK_SHARE * n * n * n {
                    Route::DenseCholesky
                } else {
                    Route::Selected
                })
            }
            (Ok(_), Err(_)) => Ok(Route::Selected),
            (Err(PrecisionError::TooLarge(_)), Ok(())) => Ok(Route::DenseCholesky),
            (Err(PrecisionError::TooLarge(why)), Err(dense)) => {
                Err(PrecisionError::TooLarge(format!("{why}; {dense}")))
            }
            (Err(e), _) => Err(e),
        },
    }
}

/// A selected inversion's step (`Σⱼ |column j|²`, scattered reads) against a dense
/// Cholesky inverse's (n³ in all, blocked and parallel): measured on 2 cores, 5.2e10 steps
/// in 92 s (random 600-camera graph) against 13,500³ in about 80 s, a step costs about 60
/// dense ones: the dense inverse is taken when the selected work exceeds n³/60.
const DENSE_ABOVE_WORK_SHARE: f64 = 1.0 / 60.0;

/// S⁻¹ under `held` by `route`, its failures named.
fn factored(
    route: Route,
    layout: &Layout,
    values: &[f64],
    held: &[bool],
    problem: &Problem,
) -> Result<Box<dyn Factored>, PrecisionError> {
    Ok(match route {
        Route::Selected => Box::new(selected(layout, values, held, problem)?),
        Route::DenseCholesky => {
            let limit = memory_limit();
            let q = DenseInverse::new(layout, values, held, limit, faer::Par::rayon(0))
                .map_err(|e| selected_error(e, layout, problem, limit))?;
            Box::new(q)
        }
    })
}

/// The selected inverse of S (`values` in the layout's order) with `held` unknowns, its
/// failures named.
pub(super) fn selected(
    layout: &Layout,
    values: &[f64],
    held: &[bool],
    problem: &Problem,
) -> Result<SelectedInverse, PrecisionError> {
    let limit = memory_limit();
    SelectedInverse::new(layout, values, held, limit, faer::Par::Seq)
        .map_err(|e| selected_error(e, layout, problem, limit))
}

/// 80 % of the memory the system reports available.
fn memory_limit() -> Option<f64> {
    super::available_memory().map(|m| 0.8 * m)
}

/// [`selected_inverse::precheck`](super::selected_inverse::precheck) with its refusal named:
/// called before S is assembled.
/// `Ok(work)`: the selected inversion's work `Σⱼ |column j|²`.
pub(super) fn selected_fits(layout: &Layout, problem: &Problem) -> Result<f64, PrecisionError> {
    let limit = memory_limit();
    super::selected_inverse::precheck(layout, limit)
        .map_err(|e| selected_error(e, layout, problem, limit))
}

fn selected_error(
    e: SelectedError,
    layout: &Layout,
    problem: &Problem,
    limit: Option<f64>,
) -> PrecisionError {
    let n = layout.n_reduced;
    match e {
        SelectedError::NotPositive(i) => PrecisionError::DatumDefect(format!(
            "the observations and the datum do not determine {} (the reduced system of {n} unknowns is singular there; the open degrees of freedom are counted for at most {MAX_DENSE_PRECISION})",
            describe_unknown(i, problem, layout)
        )),
        SelectedError::TooLarge {
            bytes,
            work,
            factor_entries,
        } => PrecisionError::TooLarge(format!(
            "the reduced camera system has {n} unknowns and its sparse factor about {factor_entries} entries: the precision would need {:.1} GiB and about {work:.1e} operations (at most {:.1} GiB{} and {:.0e}); a camera graph this dense is inverted densely only up to {MAX_DENSE_PRECISION} unknowns",
            bytes / 1073741824.0,
            limit.unwrap_or(f64::INFINITY) / 1073741824.0,
            if limit.is_some() { " available" } else { "" },
            super::MAX_SELECTED_WORK
        )),
        SelectedError::Internal(e) => PrecisionError::TooLarge(format!(
            "the sparse factorization of the reduced camera system ({n} unknowns) failed: {e}"
        )),
    }
}

/// The number of scalar observations: two per image point, and every constraint's
/// components.
pub(crate) fn observation_count(problem: &Problem) -> usize {
    2 * problem.observations.len() + problem.constraints().map(|(r, _)| r.dim()).sum::<usize>()
}

/// Observations minus unknowns, and σ0 (`σ0² = 2·cost / redundancy`).
fn redundancy_and_sigma0(
    problem: &Problem,
    c: &Cofactors,
) -> Result<(usize, usize, i64, f64), PrecisionError> {
    let n_obs = observation_count(problem);
    let unknowns = c.layout.n_reduced + 3 * c.layout.free_points.len();
    let redundancy = n_obs as i64 - unknowns as i64;
    if redundancy <= 0 {
        return Err(PrecisionError::NoRedundancy(redundancy));
    }
    Ok((
        n_obs,
        unknowns,
        redundancy,
        (2.0 * c.lin.cost / redundancy as f64).sqrt(),
    ))
}

/// The joint covariance `σ0² Q` of the coordinates of `points` (problem indices), a 3k × 3k
/// matrix in their order, the correlations between the points included (a fixed point has
/// zero rows, and so has a held coordinate).
///
/// A point in the reduced system moves as `δp = E δc` (E selects the rows of its free
/// coordinates in the camera-side update δc, a held coordinate has none); a point eliminated by the Schur complement as `δp = V⁻¹ b_p − Mᵀ δc` with
/// `M = W V⁻¹`. So `Q_pq = A_p Q_cc A_qᵀ` with `A_p = E` or `−Mᵀ`, plus `V_p⁻¹` on the diagonal
/// block of an eliminated point (which is [`Precision::point_covariances`]' `Q_pp`).
/// Not available for a free network (an error says so).
pub fn points_covariance(
    problem: &Problem,
    points: &[usize],
) -> Result<DMatrix<f64>, PrecisionError> {
    points_covariance_with(problem, points, CofactorMethod::Auto)
}

/// [`points_covariance`] with the cofactors computed by `method` (a pair of points outside
/// the factor's pattern costs one solve per row).
pub fn points_covariance_with(
    problem: &Problem,
    points: &[usize],
    method: CofactorMethod,
) -> Result<DMatrix<f64>, PrecisionError> {
    let c = cofactors(problem, method)?.ok_or_else(|| {
        PrecisionError::DatumDefect("a free network: joint point covariances need a datum".into())
    })?;
    let (_, _, _, sigma0) = redundancy_and_sigma0(problem, &c)?;
    // A_p as (row of δc, the 3 columns' values), and V_p⁻¹ for an eliminated point (the
    // rows as positions in Q_cc's restriction below, once that is made).
    type PointRows = (Vec<(usize, [f64; 3])>, Option<Matrix3<f64>>);
    let rows: Vec<PointRows> = points
        .iter()
        .map(|&p| {
            if c.layout.point_slot[p].is_some() {
                let unit = |a: usize| std::array::from_fn(|b| f64::from(u8::from(a == b)));
                let rows = c.layout.point_rows(p).map(|(a, row)| (row, unit(a)));
                (rows.collect(), None)
            } else {
                match c.layout.free_point_index[p] {
                    u32::MAX => (Vec::new(), None),
                    f => {
                        let ep = EliminatedPoint::new(&c.layout, &c.schur, &*c.q_cc, f as usize);
                        let neg = ep.rows.iter().map(|&(r, y)| (r, y.map(|v| -v))).collect();
                        (neg, Some(c.schur.vinv[f as usize]))
                    }
                }
            }
        })
        .collect();
    let k = points.len();
    let s02 = sigma0 * sigma0;
    // Q_cc on every row the points touch (far-apart points: outside S's pattern).
    let mut all: Vec<usize> = rows
        .iter()
        .flat_map(|(r, _)| r.iter().map(|&(i, _)| i))
        .collect();
    all.sort_unstable();
    all.dedup();
    let sub = c.q_cc.restricted(&all);
    // Each point's rows as positions in `all`, looked up once.
    let at = |i: usize| all.binary_search(&i).expect("a row of the points");
    let rows: Vec<PointRows> = rows
        .into_iter()
        .map(|(r, v)| (r.into_iter().map(|(i, y)| (at(i), y)).collect(), v))
        .collect();
    // Block (a, b) is Y_aᵀ Q Y_b. With T_a = Q Y_a (all rows × 3, Q symmetric), made once
    // per point a, each block is Y_bᵀ T_a over b's rows only.
    let mut q = DMatrix::<f64>::zeros(3 * k, 3 * k);
    let mut t = vec![[0.0; 3]; all.len()];
    for (a, (ra, va)) in rows.iter().enumerate() {
        t.iter_mut().for_each(|r| *r = [0.0; 3]);
        for &(i, yi) in ra {
            for (tm, &qmi) in t.iter_mut().zip(sub.column(i).iter()) {
                for u in 0..3 {
                    tm[u] += qmi * yi[u];
                }
            }
        }
        for (b, (rb, _)) in rows.iter().enumerate().skip(a) {
            let mut block = Matrix3::<f64>::zeros();
            for &(j, yj) in rb {
                block += Matrix3::from_fn(|u, v| t[j][u] * yj[v]);
            }
            if a == b {
                block += va.unwrap_or_else(Matrix3::zeros);
            }
            for (u, v) in (0..3).flat_map(|u| (0..3).map(move |v| (u, v))) {
                q[(3 * a + u, 3 * b + v)] = s02 * block[(u, v)];
                q[(3 * b + v, 3 * a + u)] = s02 * block[(u, v)];
            }
        }
    }
    Ok(q)
}

/// Computes the precision of `problem` at its current (adjusted) estimate.
pub fn precision(problem: &Problem) -> Result<Precision, PrecisionError> {
    precision_with(problem, CofactorMethod::Auto)
}

/// [`precision`] with the cofactors computed by `method` (all methods give the same
/// figures where more than one can be used; the tests compare them).
pub fn precision_with(
    problem: &Problem,
    method: CofactorMethod,
) -> Result<Precision, PrecisionError> {
    let Some(c) = cofactors(problem, method)? else {
        // A free network: the datum by inner constraints on the points.
        let layout = Layout::new(problem);
        let lin = linearized(problem, &layout)?;
        let unknowns = layout.n_reduced + 3 * layout.free_points.len();
        if method == CofactorMethod::Dense
            && unknowns <= super::free_network::MAX_FREE_NETWORK_UNKNOWNS
        {
            return super::free_network::precision(problem, &layout, &lin);
        }
        return free_network_bordered(problem, &layout, &lin, method);
    };
    let (n_obs, unknowns, redundancy, _) = redundancy_and_sigma0(problem, &c)?;
    let eliminated: Vec<EliminatedPoint> = (0..c.layout.free_points.len())
        .map(|f| EliminatedPoint::new(&c.layout, &c.schur, &*c.q_cc, f))
        .collect();
    let counts = (n_obs, unknowns, redundancy);
    Ok(assemble(
        problem,
        &c.layout,
        &c.lin,
        &*c.q_cc,
        &eliminated,
        counts,
        c.how,
    ))
}

/// The precision of a free network of any number of points: the inner constraints on the
/// points border the reduced system (see `free_network`'s module doc); every cofactor
/// follows as for a network with a datum, the d multipliers taking part like d more reduced
/// unknowns. [`CofactorMethod::Dense`]: the bordered system is inverted densely; otherwise its
/// inverse is had from a minimal datum's inverse (selected or dense Cholesky) by an
/// S-transformation ([`Transformed`]).
fn free_network_bordered(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
    method: CofactorMethod,
) -> Result<Precision, PrecisionError> {
    let n = layout.n_reduced;
    let dense = method == CofactorMethod::Dense;
    if dense && n > MAX_DENSE_PRECISION {
        return Err(PrecisionError::TooLarge(format!(
            "the reduced camera system has {n} unknowns; its bordered inverse is formed densely for at most {MAX_DENSE_PRECISION}"
        )));
    }
    let route = match dense {
        true => None,
        false => Some(route(layout, problem, method)?),
    };
    let schur = reduced_schur(problem, layout, lin)?;
    let d = if problem.distances.is_empty() { 7 } else { 6 };
    let diag_mean = (0..n)
        .map(|c| layout.diagonal(&schur.values, c))
        .sum::<f64>()
        / n.max(1) as f64;
    let border = Border::new(problem, layout, &schur, d, diag_mean)?;
    let (q, how): (Box<dyn CofactorLookup>, _) = if dense {
        let mut k = DMatrix::<f64>::zeros(n + d, n + d);
        k.view_mut((0, 0), (n, n))
            .copy_from(&dense_s(layout, &schur));
        k.view_mut((0, n), (n, d)).copy_from(&border.b);
        k.view_mut((n, 0), (d, n)).copy_from(&border.b.transpose());
        k.view_mut((n, n), (d, d)).copy_from(&border.d);
        let Some(q) = super::free_network::bordered_inverse(&k, n) else {
            return Err(still_free());
        };
        (Box::new(q), BORDERED_DENSE)
    } else {
        let route = route.expect("a route unless dense");
        let t = Transformed::new(problem, layout, &schur, &border, d, route)?;
        let how = match route {
            Route::Selected => TRANSFORMED,
            Route::DenseCholesky => TRANSFORMED_DENSE,
        };
        (Box::new(t), how)
    };
    let n_obs = observation_count(problem);
    let unknowns = n + 3 * layout.free_points.len();
    let redundancy = n_obs as i64 - unknowns as i64 + d as i64;
    if redundancy <= 0 {
        return Err(PrecisionError::NoRedundancy(redundancy));
    }
    let eliminated: Vec<EliminatedPoint> = border
        .point_rows
        .into_iter()
        .enumerate()
        .map(|(f, rows)| EliminatedPoint::from_rows(&schur, &*q, f, rows))
        .collect();
    let counts = (n_obs, unknowns, redundancy);
    Ok(assemble(
        problem,
        layout,
        lin,
        &*q,
        &eliminated,
        counts,
        how,
    ))
}

fn still_free() -> PrecisionError {
    PrecisionError::DatumDefect(
        "the network is free and, beyond position, orientation and scale, still not determined (too few points per image, or disconnected pieces)".into(),
    )
}

/// The border of a free network's reduced system `[S B; Bᵀ D]`: with C the inner
/// constraints (about the points' centroid, scaled to the size of S; the bordered inverse's
/// upper-left block does not depend on their basis), `B = C_c − W V⁻¹ C_p` and
/// `D = −C_pᵀ V⁻¹ C_p`; and each eliminated point's rows of M = W V⁻¹ with the d rows of
/// the multipliers, `(V⁻¹ C_f)ᵀ`, appended.
struct Border {
    b: DMatrix<f64>,
    d: DMatrix<f64>,
    point_rows: Vec<Vec<(usize, [f64; 3])>>,
}

impl Border {
    fn new(
        problem: &Problem,
        layout: &Layout,
        schur: &Schur,
        d: usize,
        diag_mean: f64,
    ) -> Result<Self, PrecisionError> {
        let n = layout.n_reduced;
        let mut centroid = nalgebra::Vector3::zeros();
        let mut count = 0.0;
        for (p, pt) in problem.points.iter().enumerate() {
            if layout.point_slot[p].is_some() || layout.free_point_index[p] != u32::MAX {
                centroid += pt.position;
                count += 1.0;
            }
        }
        if count < 3.0 {
            return Err(PrecisionError::DatumDefect(
                "the inner constraints do not fix the datum (fewer than 3 points)".into(),
            ));
        }
        centroid /= count;
        let scale = (diag_mean.max(f64::MIN_POSITIVE) / count).sqrt();
        let constraints = |p: usize| {
            // About the centroid: the same constraint space, better conditioned.
            let c =
                super::free_network::point_constraints(&(problem.points[p].position - centroid), d);
            c.map(|row| row.map(|v| v * scale))
        };
        let mut b = DMatrix::<f64>::zeros(n, d);
        let mut dd = DMatrix::<f64>::zeros(d, d);
        for p in 0..layout.point_slot.len() {
            let c = constraints(p);
            for (a, row) in layout.point_rows(p) {
                for (j, &v) in c[a].iter().enumerate().take(d) {
                    b[(row, j)] += v;
                }
            }
        }
        // Per eliminated point: B −= (W V⁻¹)_f C_f, D −= C_fᵀ V_f⁻¹ C_f.
        let mut point_rows = Vec::with_capacity(layout.free_points.len());
        for (f, &p) in layout.free_points.iter().enumerate() {
            let c = constraints(p);
            let cm = nalgebra::Matrix3xX::from_fn(d, |a, j| c[a][j]);
            let vc = schur.vinv[f] * &cm; // 3 × d: V⁻¹ C_f
            let rows = point_y_rows(layout, schur, f);
            for &(r, y) in &rows {
                let y = nalgebra::Vector3::from(y);
                for j in 0..d {
                    b[(r, j)] -= y.dot(&cm.column(j));
                }
            }
            dd -= cm.transpose() * &vc;
            // The multipliers' rows of M = Y V⁻¹: (V⁻¹ C_f)ᵀ.
            let mut all = rows;
            all.extend((0..d).map(|j| (n + j, [vc[(0, j)], vc[(1, j)], vc[(2, j)]])));
            point_rows.push(all);
        }
        Ok(Self {
            b,
            d: dd,
            point_rows,
        })
    }
}

/// The inverse of a free network's bordered system `K = [S B; Bᵀ D]` from the selected
/// inverse `Q₀` of S under a minimal datum (d held unknowns), without forming K.
///
/// With `G` (n × d) the null space of S (the similarity's effect on the reduced unknowns)
/// and `A = (GᵀB)⁻¹`, the blocks of `K⁻¹ = [Q R; Rᵀ E]` are `E = 0`, `R = G Aᵀ` and
/// `Q = Πᵀ Q₀ Π − R D Rᵀ` with `Π = I − B A Gᵀ` (from `S Q + B Rᵀ = I`, `S R + B E = 0`,
/// `Bᵀ Q + D Rᵀ = 0` and `S Q₀ Π = Π`, which holds because Π maps into the range of S):
/// Baarda's S-transformation of `Q₀` to the inner-constraint datum. Entry by entry, with
/// `aᵢ = A gᵢ` and `uᵢ` the rows of `U = Q₀ B` (d solves with the factor):
///
/// ```text
///   Q_ij = Q₀_ij − aᵢ·uⱼ − uᵢ·aⱼ + aᵢᵀ (BᵀU − D) aⱼ,    R_ik = (aᵢ)_k
/// ```
struct Transformed {
    base: Box<dyn Factored>,
    n: usize,
    /// Per reduced unknown: aᵢ, uᵢ and aᵢᵀ(BᵀU − D) (d ≤ 7 entries each, zero beyond).
    a: Vec<[f64; 7]>,
    u: Vec<[f64; 7]>,
    ae: Vec<[f64; 7]>,
}

impl Transformed {
    fn new(
        problem: &Problem,
        layout: &Layout,
        schur: &Schur,
        border: &Border,
        d: usize,
        route: Route,
    ) -> Result<Self, PrecisionError> {
        let n = layout.n_reduced;
        let g = super::free_network::reduced_null_space(problem, layout, d);
        let diag = |c: usize| layout.diagonal(&schur.values, c);
        let held = minimal_datum(&g, diag).ok_or_else(|| {
            PrecisionError::DatumDefect(
                "the inner constraints do not fix the datum (the cameras do not move under a similarity?)".into(),
            )
        })?;
        let mut is_held = vec![false; n];
        for &h in &held {
            is_held[h] = true;
        }
        let base =
            factored(route, layout, &schur.values, &is_held, problem).map_err(|e| match e {
                PrecisionError::DatumDefect(_) => still_free(),
                e => e,
            })?;
        let mut u = border.b.clone();
        for mut col in u.column_iter_mut() {
            let mut x: Vec<f64> = col.iter().copied().collect();
            base.solve_in_place(&mut x);
            col.copy_from_slice(&x);
        }
        let Some(amat) = (g.transpose() * &border.b).try_inverse() else {
            return Err(PrecisionError::DatumDefect(
                "the inner constraints do not fix the datum (all points coincide?)".into(),
            ));
        };
        let a = &g * amat.transpose(); // row i: (A gᵢ)ᵀ
        let e = border.b.transpose() * &u - &border.d;
        let ae = &a * &e;
        if !(a
            .iter()
            .chain(u.iter())
            .chain(e.iter())
            .all(|v| v.is_finite()))
        {
            return Err(still_free());
        }
        let rows = |m: &DMatrix<f64>| -> Vec<[f64; 7]> {
            (0..n)
                .map(|i| std::array::from_fn(|k| if k < d { m[(i, k)] } else { 0.0 }))
                .collect()
        };
        Ok(Self {
            base,
            n,
            a: rows(&a),
            u: rows(&u),
            ae: rows(&ae),
        })
    }

    /// `Q_ij − Q₀_ij`.
    #[inline]
    fn correction(&self, i: usize, j: usize) -> f64 {
        let (ai, aj, ui, uj, ei) = (&self.a[i], &self.a[j], &self.u[i], &self.u[j], &self.ae[i]);
        (0..7)
            .map(|k| -ai[k] * uj[k] - ui[k] * aj[k] + ei[k] * aj[k])
            .sum()
    }
}

impl CofactorLookup for Transformed {
    fn at(&self, i: usize, j: usize) -> f64 {
        match (i < self.n, j < self.n) {
            (true, true) => self.base.at(i, j) + self.correction(i, j),
            (true, false) => self.a[i][j - self.n],
            (false, true) => self.a[j][i - self.n],
            (false, false) => 0.0,
        }
    }

    fn restricted(&self, rows: &[usize]) -> DMatrix<f64> {
        let inner: Vec<usize> = rows.iter().copied().filter(|&r| r < self.n).collect();
        let sub = self.base.restricted(&inner);
        let mut k = 0;
        let place: Vec<Option<usize>> = rows
            .iter()
            .map(|&r| {
                (r < self.n).then(|| {
                    k += 1;
                    k - 1
                })
            })
            .collect();
        DMatrix::from_fn(rows.len(), rows.len(), |x, y| match (place[x], place[y]) {
            (Some(a), Some(b)) => sub[(a, b)] + self.correction(rows[x], rows[y]),
            _ => self.at(rows[x], rows[y]),
        })
    }
}

/// d reduced unknowns whose holding removes the null space G (rows of G scaled by √S_ii,
/// as the Jacobi-scaled system sees them): pivoted Gram–Schmidt on the rows, the largest
/// remaining row at each step. `None` when G has rank below d.
fn minimal_datum(g: &DMatrix<f64>, diag: impl Fn(usize) -> f64) -> Option<Vec<usize>> {
    let (n, d) = g.shape();
    let mut r = DMatrix::from_fn(n, d, |i, k| g[(i, k)] * diag(i).max(0.0).sqrt());
    let first = (0..n).map(|i| r.row(i).norm()).fold(0.0, f64::max);
    let mut held = Vec::with_capacity(d);
    for _ in 0..d {
        let (best, norm) = (0..n)
            .filter(|i| !held.contains(i))
            .map(|i| (i, r.row(i).norm()))
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        if !(norm > 1e-8 * first) {
            return None;
        }
        let q = r.row(best).transpose() / norm;
        for i in 0..n {
            let c = r.row(i).dot(&q.transpose());
            for k in 0..d {
                r[(i, k)] -= c * q[k];
            }
        }
        held.push(best);
    }
    Some(held)
}

/// The precision from the cofactors: `q` those of the reduced unknowns (possibly bordered
/// by more rows, which take part only through the eliminated points' rows), `eliminated`
/// the eliminated points', and `(observations, unknowns, redundancy)`.
fn assemble(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
    q: &dyn CofactorLookup,
    eliminated: &[EliminatedPoint],
    (n_obs, unknowns, redundancy): (usize, usize, i64),
    cofactors: &'static str,
) -> Precision {
    let sigma0 = (2.0 * lin.cost / redundancy as f64).sqrt();
    let s02 = sigma0 * sigma0;
    let mut point_covariances = vec![None; problem.points.len()];
    for (p, slot) in layout.point_slot.iter().enumerate() {
        if slot.is_some() {
            // A held coordinate's rows and columns are 0.
            let mut cov = Matrix3::zeros();
            for (a, i) in layout.point_rows(p) {
                for (b, j) in layout.point_rows(p) {
                    cov[(a, b)] = s02 * q.at(i, j);
                }
            }
            point_covariances[p] = Some(cov);
        }
    }
    for (ep, &p) in eliminated.iter().zip(&layout.free_points) {
        point_covariances[p] = Some(ep.q * s02);
    }
    let (standardized_residuals, redundancy_numbers) =
        standardized_residuals(layout, lin, q, eliminated);
    let constraint_q: Vec<Vec<f64>> = (0..lin.constraints.len())
        .map(|k| {
            let aqa =
                super::constraints::cofactor_diagonal(layout, &lin.constraints[k], k, q, |f| {
                    eliminated[f].q
                });
            aqa.iter().map(|v| (1.0 - v).max(0.0)).collect()
        })
        .collect();
    let by_kind = super::sigma::split_constraint_redundancy(problem, lin, constraint_q);
    let (parameters_covariance, parameter_offsets) = parameters_covariance(problem, layout, s02, q);
    Precision {
        cofactors,
        sigma0,
        redundancy,
        observations: n_obs,
        unknowns,
        rms_image_px: problem.rms_px(),
        intrinsics: intrinsics_precision(problem, layout, s02, |i, j| q.at(i, j)),
        poses: pose_sigmas(problem, layout, s02, |i, j| q.at(i, j)),
        rig_covariances: rig_covariances(layout, s02, |i, j| q.at(i, j)),
        point_covariances,
        standardized_residuals,
        redundancy_numbers,
        distance_redundancy_numbers: by_kind.distance_redundancy_numbers,
        distance_standardized: by_kind.distance_standardized,
        control_redundancy_numbers: by_kind.control_redundancy_numbers,
        control_standardized: by_kind.control_standardized,
        residual_redundancy_numbers: by_kind.residual_redundancy_numbers,
        residual_standardized: by_kind.residual_standardized,
        parameters_covariance,
        parameter_offsets,
        rigs_and_parameters_covariance: rigs_and_parameters_covariance(problem, layout, s02, q),
    }
}

/// The rows of M = W V⁻¹ of free point `f`: (row of the reduced system, its 3 values), one
/// per row of each observation's segments (a row may repeat: the entries add up).
fn point_y_rows(layout: &Layout, schur: &Schur, f: usize) -> Vec<(usize, [f64; 3])> {
    let mut rows: Vec<(usize, [f64; 3])> = Vec::new();
    for &o in layout.point_obs(f) {
        let o = o as usize;
        for sg in layout.segs(o) {
            let y = layout.w_cols(&schur.y, o, sg);
            let base = layout.block_offset[sg.block as usize] + sg.block_off as usize;
            rows.extend((0..sg.len as usize).map(|k| (base + k, [y[0][k], y[1][k], y[2][k]])));
        }
    }
    rows
}

/// The precision of a free network always by bordering the reduced system (what
/// [`precision`] does for free networks above
/// [`MAX_FREE_NETWORK_UNKNOWNS`](super::MAX_FREE_NETWORK_UNKNOWNS) unknowns, whatever the
/// number of points), so that it can be checked against the dense inner-constraint form on
/// a network small enough for both. Refused for a network that has a datum of its own.
pub fn free_network_precision_bordered(problem: &Problem) -> Result<Precision, PrecisionError> {
    problem.validate()?;
    if !super::free_network::is_free(problem) {
        return Err(PrecisionError::DatumDefect(
            "not a free network: it has a fixed image, fixed points, control, held coordinates or a fixed rig".into(),
        ));
    }
    let layout = Layout::new(problem);
    let lin = linearized(problem, &layout)?;
    free_network_bordered(problem, &layout, &lin, CofactorMethod::Dense)
}

/// The undamped Schur complement at the linearization and S as a dense symmetric matrix;
/// refused when an eliminated point is not determined by its own observations.
pub(super) fn reduced_system(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
) -> Result<(Schur, DMatrix<f64>), PrecisionError> {
    let schur = reduced_schur(problem, layout, lin)?;
    let s = dense_s(layout, &schur);
    Ok((schur, s))
}

/// The undamped Schur complement at the linearization (S in its sparse values); refused
/// when an eliminated point is not determined by its own observations.
pub(super) fn reduced_schur(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
) -> Result<Schur, PrecisionError> {
    let mut schur = Schur::new(layout);
    schur.prepare(layout, lin);
    // Eliminated points must be determined on their own.
    for (f, v) in schur.v.iter().enumerate() {
        let scale = v.diagonal().max().max(f64::MIN_POSITIVE);
        let eig = v.symmetric_eigenvalues();
        if !(eig.min() > 1e-10 * scale) {
            return Err(PrecisionError::PointUndetermined(
                problem.points[layout.free_points[f]].name.clone(),
            ));
        }
    }
    if let Some(p) = undetermined_distance_point(problem, layout, lin) {
        return Err(PrecisionError::PointUndetermined(
            problem.points[p].name.clone(),
        ));
    }
    schur.assemble(layout, lin, 0.0).map_err(|f| {
        PrecisionError::PointUndetermined(problem.points[layout.free_points[f]].name.clone())
    })?;
    Ok(schur)
}

/// S as a dense symmetric matrix.
fn dense_s(layout: &Layout, schur: &Schur) -> DMatrix<f64> {
    let n = layout.n_reduced;
    let mut s = DMatrix::<f64>::zeros(n, n);
    for ((i, j), &v) in layout.entries().zip(&schur.values) {
        s[(i, j)] = v;
        s[(j, i)] = v;
    }
    s
}

/// The first point of a distance (a point kept in the reduced system) that its own rays do not
/// determine, as an eliminated point must be: a distance gives one equation, so a point whose
/// rays data snooping has taken away would otherwise show as a datum defect of two degrees of
/// freedom in that point instead of as the undetermined point it is. A point with a prior is
/// determined by it; one with held coordinates needs its rays to determine only the free
/// ones (the normal matrix of its rays restricted to them).
fn undetermined_distance_point(
    problem: &Problem,
    layout: &Layout,
    lin: &Linearization,
) -> Option<usize> {
    let mut v = vec![Matrix3::<f64>::zeros(); problem.points.len()];
    for (o, jp) in lin.jp.iter().enumerate() {
        let p = layout.obs_point[o] as usize;
        if layout.point_slot[p].is_some() {
            v[p] += jp.transpose() * jp;
        }
    }
    let with_prior: Vec<usize> = problem.point_priors.iter().map(|c| c.point.0).collect();
    (0..problem.points.len()).find(|&p| {
        if layout.point_slot[p].is_none() || with_prior.contains(&p) {
            return false;
        }
        let axes = &layout.point_axes[p];
        let vf = DMatrix::from_fn(axes.len(), axes.len(), |a, b| v[p][(axes[a], axes[b])]);
        let scale = vf.diagonal().max();
        !(scale > 0.0 && vf.symmetric_eigenvalues().min() > 1e-10 * scale)
    })
}

/// A point eliminated by the Schur complement: M = W V⁻¹ restricted to the camera-side
/// rows it touches, and its cofactor matrix `Q_pp = V⁻¹ + Mᵀ Q_cc M`.
struct EliminatedPoint {
    /// (row of the reduced system, the 3 values of M in that row), sorted by row, each row
    /// once (the entries of the observations' segments added up).
    rows: Vec<(usize, [f64; 3])>,
    /// Q_pp.
    q: Matrix3<f64>,
}

impl EliminatedPoint {
    /// Free point `f` of the layout, with the Schur complement's Y = W V⁻¹.
    fn new(layout: &Layout, schur: &Schur, q_cc: &dyn CofactorLookup, f: usize) -> Self {
        Self::from_rows(schur, q_cc, f, point_y_rows(layout, schur, f))
    }

    /// Free point `f` with the rows of M given (those of a bordered system included).
    fn from_rows(
        schur: &Schur,
        q_cc: &dyn CofactorLookup,
        f: usize,
        rows: Vec<(usize, [f64; 3])>,
    ) -> Self {
        // The distinct rows (repeated ones add up), and Q_cc on them.
        let mut merged = rows;
        merged.sort_unstable_by_key(|r| r.0);
        merged.dedup_by(|b, a| {
            let same = a.0 == b.0;
            if same {
                for k in 0..3 {
                    a.1[k] += b.1[k];
                }
            }
            same
        });
        let index: Vec<usize> = merged.iter().map(|r| r.0).collect();
        let sub = q_cc.restricted(&index);
        let mut extra = Matrix3::zeros();
        for (x, &(_, yi)) in merged.iter().enumerate() {
            for (y, &(_, yj)) in merged.iter().enumerate() {
                let q = sub[(x, y)];
                for a in 0..3 {
                    for b in 0..3 {
                        extra[(a, b)] += yi[a] * q * yj[b];
                    }
                }
            }
        }
        Self {
            rows: merged,
            q: schur.vinv[f] + extra,
        }
    }
}

/// The standardized residuals of the image observations (in the problem's order):
/// `r / √q_vv` with `q_vv = 1 − (A Q Aᵀ)_ii`; NaN where q_vv vanishes. Beside them the
/// redundancy numbers `q_vv` themselves (0 where the observation has no redundancy).
fn standardized_residuals(
    layout: &Layout,
    lin: &Linearization,
    q_cc: &dyn CofactorLookup,
    eliminated: &[EliminatedPoint],
) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let mut standardized = vec![[f64::NAN; 2]; layout.obs_order.len()];
    let mut redundancy = vec![[0.0; 2]; layout.obs_order.len()];
    let mut put = |o: usize, aqa: Matrix2<f64>| {
        let r = lin.r[o];
        let q = layout.obs_order[o] as usize;
        for a in 0..2 {
            let qvv = 1.0 - aqa[(a, a)];
            if qvv > 1e-9 {
                standardized[q][a] = r[a] / qvv.sqrt();
                redundancy[q][a] = qvv;
            }
        }
    };
    // An eliminated point's observations: Q_cc on its rows (which hold every observation's
    // camera-side columns, in the same order) gathered once.
    for (f, point) in eliminated.iter().enumerate() {
        let index: Vec<usize> = point.rows.iter().map(|r| r.0).collect();
        let sub = q_cc.restricted(&index);
        for &o in layout.point_obs(f) {
            let o = o as usize;
            put(
                o,
                observation_cofactor(layout, lin, &sub, &index, Some(point), o),
            );
        }
    }
    for o in 0..layout.obs_order.len() {
        if layout.free_point_index[layout.obs_point[o] as usize] == u32::MAX {
            let mut index: Vec<usize> = observation_columns(layout, lin, o)
                .iter()
                .map(|c| c.0)
                .collect();
            index.sort_unstable();
            index.dedup();
            let sub = q_cc.restricted(&index);
            put(o, observation_cofactor(layout, lin, &sub, &index, None, o));
        }
    }
    (standardized, redundancy)
}

/// Observation `o`'s camera-side columns: (row of the reduced system, its two Jacobian
/// entries).
fn observation_columns(layout: &Layout, lin: &Linearization, o: usize) -> Vec<(usize, [f64; 2])> {
    let mut cols = Vec::new();
    for sg in layout.segs(o) {
        let (j0, j1) = layout.jc_rows(&lin.jc, o, sg);
        let base = layout.block_offset[sg.block as usize] + sg.block_off as usize;
        for k in 0..sg.len as usize {
            cols.push((base + k, [j0[k], j1[k]]));
        }
    }
    cols
}

/// A Q Aᵀ of observation `o` (internal order) in whitened units, with A = [J_c, J_p] and
/// Q_cp = −Q_cc M for an eliminated `point` (its own). `sub` is Q_cc on the sorted rows
/// `index`, which hold the observation's columns and are the point's rows when it has one.
fn observation_cofactor(
    layout: &Layout,
    lin: &Linearization,
    sub: &DMatrix<f64>,
    index: &[usize],
    point: Option<&EliminatedPoint>,
    o: usize,
) -> Matrix2<f64> {
    let cols: Vec<(usize, [f64; 2])> = observation_columns(layout, lin, o)
        .into_iter()
        .map(|(i, j)| {
            (
                index
                    .binary_search(&i)
                    .expect("a column of the observation"),
                j,
            )
        })
        .collect();
    let mut aqa = Matrix2::<f64>::zeros();
    for &(i, ji) in &cols {
        for &(j, jj) in &cols {
            let q = sub[(i, j)];
            for a in 0..2 {
                for b in 0..2 {
                    aqa[(a, b)] += ji[a] * q * jj[b];
                }
            }
        }
    }
    if let Some(point) = point {
        let jp = lin.jp[o];
        aqa += jp * point.q * jp.transpose();
        // Cross term: J_c Q_cp J_pᵀ with Q_cp = −Q_cc M.
        let mut jc_qcp = Matrix2x3::<f64>::zeros();
        for &(i, ji) in &cols {
            for (t, &(_, y)) in point.rows.iter().enumerate() {
                let q = sub[(i, t)];
                for a in 0..2 {
                    for b in 0..3 {
                        jc_qcp[(a, b)] -= ji[a] * q * y[b];
                    }
                }
            }
        }
        let cross = jc_qcp * jp.transpose();
        aqa += cross + cross.transpose();
    }
    aqa
}

/// The Jacobi scale `1/√S_ii` of each unknown (a zero diagonal taken as the smallest
/// positive number): `d_i S_ij d_j` has a unit diagonal, so that rank tests do not depend on
/// units.
pub(super) fn jacobi_scale(s: &DMatrix<f64>) -> Vec<f64> {
    (0..s.nrows())
        .map(|i| super::selected_inverse::jacobi_factor(s[(i, i)]))
        .collect()
}

/// S⁻¹, or a diagnosis of S's null space: how many degrees of freedom the datum leaves
/// open, and which unknowns they involve.
pub(super) fn invert_or_diagnose(
    s: &DMatrix<f64>,
    problem: &Problem,
    layout: &Layout,
) -> Result<DMatrix<f64>, PrecisionError> {
    let n = s.nrows();
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    // Jacobi scaling so that the rank test does not depend on units.
    let d = jacobi_scale(s);
    let scaled = DMatrix::from_fn(n, n, |i, j| s[(i, j)] * d[i] * d[j]);
    let eig = scaled.clone().symmetric_eigen();
    let max = eig.eigenvalues.max();
    let null: Vec<usize> = (0..n)
        .filter(|&k| eig.eigenvalues[k] < 1e-13 * max)
        .collect();
    if null.is_empty() {
        let inv = eig.eigenvectors.clone()
            * DMatrix::from_diagonal(&eig.eigenvalues.map(|v| 1.0 / v))
            * eig.eigenvectors.transpose();
        return Ok(DMatrix::from_fn(n, n, |i, j| inv[(i, j)] * d[i] * d[j]));
    }
    let fixed_images = problem.images.iter().filter(|i| i.fixed).count();
    let fixed_points = (problem.points.iter())
        .filter(|p| p.held().iter().any(|h| *h))
        .count();
    let what = match (null.len(), fixed_images, fixed_points + problem.point_priors.len(), problem.distances.len()) {
        (1, 1.., 0, 0) => "the scale is free: measure a distance between two points or give control points".to_string(),
        (7, 0, 0, 0) => "position, orientation and scale are free (7 degrees of freedom): fix one image and measure a distance, or give at least 3 control points".to_string(),
        (6, 0, 0, 1..) => "position and orientation are free (6 degrees of freedom): fix one image or give at least 3 control points".to_string(),
        (k, ..) => format!("{k} degrees of freedom are not determined by the observations and the datum"),
    };
    // Name the unknowns that take part most in the first null vector.
    let v = eig.eigenvectors.column(null[0]);
    let mut best = (0usize, 0.0f64);
    for i in 0..n {
        if v[i].abs() > best.1 {
            best = (i, v[i].abs());
        }
    }
    let who = describe_unknown(best.0, problem, layout);
    Err(PrecisionError::DatumDefect(format!(
        "{what} (it shows most in {who})"
    )))
}

fn describe_unknown(i: usize, problem: &Problem, layout: &Layout) -> String {
    for (im, slot) in layout.image_slot.iter().enumerate() {
        if let Some(s) = slot {
            let o = layout.slot_offset(*s);
            if (o..o + layout.pose_dim(im)).contains(&i) {
                return format!("the pose of image '{}'", problem.images[im].name);
            }
        }
    }
    for (c, slot) in layout.camera_slot.iter().enumerate() {
        if let Some(s) = slot {
            let o = layout.slot_offset(*s);
            let k = layout.camera_free[c].len();
            if (o..o + k).contains(&i) {
                let name = problem.cameras[c].model.parameter_names()[layout.camera_free[c][i - o]];
                return format!("intrinsic {name} of camera '{}'", problem.cameras[c].name);
            }
        }
    }
    for p in 0..layout.point_slot.len() {
        if let Some((axis, _)) = layout.point_rows(p).find(|&(_, row)| row == i) {
            let name = &problem.points[p].name;
            if layout.point_axes[p].len() == 3 {
                return format!("point '{name}'");
            }
            return format!("coordinate {} of point '{name}'", ["X", "Y", "Z"][axis]);
        }
    }
    format!("unknown {i}")
}
