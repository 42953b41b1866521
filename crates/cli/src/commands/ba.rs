//! `pingcal ba PROBLEM`: a bundle adjustment on its own.
//!
//! * A BAL file (plain or `.bz2`): prints a per-iteration log (as Ceres does) and a
//!   one-line summary; `--out FILE` writes the JSON of docs/formats.md, with cost = ½ Σ r² in
//!   pixels so that it compares with Ceres.
//! * pingcal's measurement file (`.json`, see `pingcal_ba::io::measurements`), or DBAT's
//!   `markpts.txt` with its camera (`--dbat-camera FILE`) and control (`--dbat CONTROL`,
//!   or `--free-network` without control): initial values from the measurements alone, a
//!   self-calibrating adjustment with distances and control, optional data snooping, and
//!   the report laid out like Australis's (text on stdout or `--report FILE`; JSON with
//!   `--out FILE`). The datum is diagnosed before solving for DBAT's files (too little:
//!   no control and no free network; too much: control and a free network), and the
//!   points the initial intersection refuses for their small ray angle
//!   (`--min-intersection-angle`) are listed.

use super::preflight::{check_out_file, check_threads};
use super::{write_atomic, CmdResult};
use pingcal_ba::loss::Loss;
use pingcal_ba::solver::{self, Iteration, LinearSolverKind, Options};
use pingcal_ba::workflow::WorkflowError;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `pingcal ba`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// The problem: a BAL file (`.bal`, `.txt`, optionally `.bz2`).
    #[arg(required_unless_present = "synthetic")]
    pub problem: Option<PathBuf>,
    /// Instead of a file, a synthetic BAL problem of CAMERASxPOINTS (6 observations per
    /// point, σ = 0.5 px, seed 1), e.g. `200x30000`.
    #[arg(long, conflicts_with = "problem")]
    pub synthetic: Option<String>,
    /// Write the result summary as JSON here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Solver of the reduced camera system.
    #[arg(long, value_enum, default_value_t = SolverArg::Auto)]
    pub solver: SolverArg,
    /// The iterative solver's forcing constant η (Ceres' `eta`): each step's conjugate
    /// gradients stop when the quadratic model's relative decrease falls below η/i.
    #[arg(long, default_value_t = 0.1)]
    pub eta: f64,
    /// The iterative solver's preconditioner.
    #[arg(long, value_enum, default_value_t = PreconditionerArg::ClusterJacobi)]
    pub preconditioner: PreconditionerArg,
    /// With `--preconditioner cluster-jacobi`: the largest cluster, in unknowns (9 per BAL
    /// camera).
    #[arg(long, default_value_t = solver::DEFAULT_CLUSTER_DIM)]
    pub cluster_max_dim: usize,
    /// How the iterative solver multiplies by the reduced camera system: `implicit` (never
    /// formed), `explicit` (assembled each step, a sparse product) or `auto` (the cheaper
    /// by the block pattern; printed with the solver).
    #[arg(long, value_enum, default_value_t = SchurProductArg::Auto)]
    pub schur_product: SchurProductArg,
    /// With `--synthetic`: which cameras see a point, `banded` (neighbours along a street)
    /// or `random` (any 6 of all cameras: a dense camera graph).
    #[arg(long, value_enum, default_value_t = super::gen_bal::VisibilityArg::Banded)]
    pub visibility: super::gen_bal::VisibilityArg,
    /// Most Levenberg–Marquardt iterations.
    #[arg(long, default_value_t = 50)]
    pub max_iterations: usize,
    /// Relative cost-change tolerance (Ceres' function_tolerance).
    #[arg(long, allow_hyphen_values = true, default_value_t = 1e-6)]
    pub function_tolerance: f64,
    /// Gradient max-norm tolerance (Ceres' gradient_tolerance).
    #[arg(long, allow_hyphen_values = true, default_value_t = 1e-10)]
    pub gradient_tolerance: f64,
    /// Relative step tolerance (Ceres' parameter_tolerance).
    #[arg(long, allow_hyphen_values = true, default_value_t = 1e-8)]
    pub parameter_tolerance: f64,
    /// Robust loss: `huber:SCALE` or `cauchy:SCALE` (scale in pixels); none by default.
    #[arg(long)]
    pub loss: Option<String>,
    /// Do not print the per-iteration log.
    #[arg(long)]
    pub quiet: bool,
    /// PROBLEM is DBAT's `markpts.txt`; this is DBAT's control file (metres).
    #[arg(long, value_name = "CONTROL")]
    pub dbat: Option<PathBuf>,
    /// PROBLEM is DBAT's `markpts.txt`; this is its camera: DBAT's camera XML (e.g.
    /// `c4040z.xml`) or a DBAT script with the camera inline. Needed for DBAT's files.
    #[arg(long, value_name = "FILE")]
    pub dbat_camera: Option<PathBuf>,
    /// The datum by inner constraints on the points (a free network), for a network
    /// without control (DBAT's files without `--dbat CONTROL`); refused with control.
    #[arg(long)]
    pub free_network: bool,
    /// BAL problems: also compute the precision of the adjusted network (a free network,
    /// its datum by inner constraints on the points): σ0 and every camera's and point's σ,
    /// dense up to 6,000 reduced unknowns and by a sparse selected inversion above.
    #[arg(long)]
    pub precision: bool,
    /// Smallest largest angle between a point's rays, degrees, for the initial
    /// intersection to take it (points below are refused and listed); default 2.
    #[arg(long, value_name = "DEG")]
    pub min_intersection_angle: Option<f64>,
    /// Reject gross errors by data snooping (standardized residual above this, e.g. 3.29).
    #[arg(long, allow_hyphen_values = true, value_name = "W")]
    pub snoop: Option<f64>,
    /// Self-calibrate these intrinsics of every camera (comma separated, e.g.
    /// `c,xp,yp,K1,K2,K3,P1,P2,B1`), overriding the file. DBAT files default to that list.
    #[arg(long, value_delimiter = ',')]
    pub calibrate: Option<Vec<String>>,
    /// Write the text report here (measurement files) instead of printing it.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// Linear solver choice on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum SolverArg {
    /// Chosen from the size and fill of the reduced camera system (the choice and its
    /// reason are printed).
    Auto,
    /// Dense Cholesky of the reduced camera system.
    Dense,
    /// Sparse Cholesky of the reduced camera system.
    Sparse,
    /// Conjugate gradients on the reduced camera system (see `--preconditioner` and
    /// `--schur-product`).
    Iterative,
}

/// How the iterative solver applies the reduced camera system, on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum SchurProductArg {
    /// The cheaper form by the estimates of the block pattern.
    Auto,
    /// Never formed: one pass over the observations per product (memory proportional to
    /// the observations).
    Implicit,
    /// Assembled at every step and multiplied as a sparse matrix (cheaper where each image
    /// shares points with few others, as along a street).
    Explicit,
}

/// The largest cluster `--cluster-max-dim` takes: its inverse is a dense matrix, inverted
/// at every step (4096 unknowns: 134 MB and 2·10¹⁰ operations).
const MAX_CLUSTER_DIM: usize = 4096;

/// Preconditioner of the iterative solver on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum PreconditionerArg {
    /// S's diagonal blocks, one per image or camera (Ceres' SCHUR_JACOBI).
    SchurJacobi,
    /// S's block diagonal over clusters of images that see the same points (Ceres'
    /// CLUSTER_JACOBI); the clusters are printed. Where no two images see enough of the
    /// same points (a dense, random camera graph) every image is its own cluster: Schur–Jacobi.
    ClusterJacobi,
}

fn parse_loss(s: &str) -> Result<Loss, String> {
    let (kind, scale) = s
        .split_once(':')
        .ok_or_else(|| format!("--loss '{s}': expected huber:SCALE or cauchy:SCALE"))?;
    let a: f64 = scale
        .parse()
        .map_err(|_| format!("--loss '{s}': scale '{scale}' is not a number"))?;
    if !(a > 0.0 && a.is_finite()) {
        return Err(format!("--loss '{s}': the scale must be positive"));
    }
    match kind {
        "huber" => Ok(Loss::Huber(a)),
        "cauchy" => Ok(Loss::Cauchy(a)),
        _ => Err(format!(
            "--loss '{s}': unknown loss '{kind}', expected huber or cauchy"
        )),
    }
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    check_threads(args.threads)?;
    if !(1..=MAX_CLUSTER_DIM).contains(&args.cluster_max_dim) {
        return Err(format!(
            "--cluster-max-dim {}: expected 1 to {MAX_CLUSTER_DIM} unknowns per cluster",
            args.cluster_max_dim
        )
        .into());
    }
    // Written as `!(ok)` so that NaN is refused with the rest.
    if !(args.eta > 0.0 && args.eta < 1.0) {
        return Err(format!(
            "--eta {}: expected a forcing constant strictly between 0 and 1 (Ceres uses 0.1)",
            args.eta
        )
        .into());
    }
    let measurements = args
        .problem
        .as_ref()
        .filter(|path| path.extension().is_some_and(|e| e == "json") || is_dbat(&args));
    if measurements.is_none() {
        refuse_measurement_options(&args)?;
    }
    for (option, file) in [("--out", &args.out), ("--report", &args.report)] {
        if let Some(f) = file {
            check_out_file(option, f)?;
        }
    }
    if let Some(path) = measurements {
        if args.precision {
            return Err(format!(
                "--precision is for BAL problems: the precision of {} is always computed",
                path.display()
            )
            .into());
        }
        return run_measurements(path, &args);
    }
    let t_read = Instant::now();
    let (mut problem, source) = read_bal_problem(&args)?;
    if let Some(l) = &args.loss {
        problem.loss = parse_loss(l)?;
    }
    let read_s = t_read.elapsed().as_secs_f64();
    let options = bal_options(&args);
    let quiet = args.quiet;
    if !quiet {
        println!(
            "{}: {} cameras, {} points, {} observations (read in {:.2} s)",
            source,
            problem.images.len(),
            problem.points.len(),
            problem.observations.len(),
            read_s
        );
        println!("iter      cost      cost_change  |gradient|   |step|    tr_ratio  tr_radius  ls_time  iter_time  cg_iter");
    }
    let summary = solver::solve(&mut problem, &options, |it: &Iteration| {
        if !quiet {
            println!(
                "{:4} {:12.6e} {:11.4e} {:11.4e} {:10.3e} {:9.2e} {:9.2e} {:8.3} {:9.3} {:8}{}",
                it.iteration,
                it.cost,
                it.cost_change,
                it.gradient_max_norm,
                it.step_norm,
                it.relative_decrease,
                it.trust_region_radius,
                it.linear_solver_time_s,
                it.iteration_time_s,
                it.linear_iterations,
                if it.accepted { "" } else { "  (rejected)" }
            );
        }
    })?;
    let rms = problem.rms_px();
    if !quiet {
        print_solver_details(&summary);
    }
    println!(
        "pingcal ba: cost {:.6e} -> {:.6e} in {} iterations ({} accepted), {:.3} s ({} linear solver, reduced system {} x {}), RMS {:.4} px; {}",
        summary.initial_cost,
        summary.final_cost,
        summary.iterations,
        summary.successful_steps,
        summary.time_s,
        summary.linear_solver.kind,
        summary.reduced_dimension,
        summary.reduced_dimension,
        rms,
        summary.termination
    );
    // A precision that cannot be had is said after the adjustment's results are written.
    let precision = args
        .precision
        .then(|| bal_precision(&problem, &source, quiet));
    if let Some(out) = &args.out {
        write_bal_json(out, &problem, &summary, &precision, args.threads)?;
    }
    match precision {
        Some(Err(e)) => Err(e.into()),
        _ => Ok(()),
    }
}

/// The BAL problem: PROBLEM read, or generated by `--synthetic CAMERASxPOINTS`; with its
/// name for the messages.
fn read_bal_problem(
    args: &Args,
) -> Result<(pingcal_ba::problem::Problem, String), super::CmdError> {
    Ok(match (&args.problem, &args.synthetic) {
        (Some(path), _) => (pingcal_ba::bal::read_bal(path)?, path.display().to_string()),
        (None, Some(size)) => {
            let (c, p) = size
                .split_once('x')
                .and_then(|(c, p)| Some((c.parse::<usize>().ok()?, p.parse::<usize>().ok()?)))
                .ok_or_else(|| {
                    format!("--synthetic '{size}': expected CAMERASxPOINTS, e.g. 200x30000")
                })?;
            let spec = pingcal_ba::synthetic::SyntheticBal {
                cameras: c,
                points: p,
                obs_per_point: 6.min(c),
                visibility: args.visibility.into(),
                ..Default::default()
            };
            (spec.generate()?.problem, format!("synthetic {c}x{p}"))
        }
        (None, None) => return Err("give a BAL file or --synthetic CAMERASxPOINTS".into()),
    })
}

/// The solver's options of a BAL problem, from the command line.
fn bal_options(args: &Args) -> Options {
    Options {
        max_iterations: args.max_iterations,
        function_tolerance: args.function_tolerance,
        gradient_tolerance: args.gradient_tolerance,
        parameter_tolerance: args.parameter_tolerance,
        linear_solver: match args.solver {
            SolverArg::Auto => LinearSolverKind::Auto,
            SolverArg::Dense => LinearSolverKind::Dense,
            SolverArg::Sparse => LinearSolverKind::Sparse,
            SolverArg::Iterative => LinearSolverKind::Iterative,
        },
        cg: solver::CgOptions {
            eta: args.eta,
            preconditioner: match args.preconditioner {
                PreconditionerArg::SchurJacobi => solver::Preconditioner::SchurJacobi,
                PreconditionerArg::ClusterJacobi => solver::Preconditioner::ClusterJacobi {
                    max_dim: args.cluster_max_dim,
                },
            },
            product: match args.schur_product {
                SchurProductArg::Auto => solver::SchurProduct::Auto,
                SchurProductArg::Implicit => solver::SchurProduct::Implicit,
                SchurProductArg::Explicit => solver::SchurProduct::Explicit,
            },
            ..Default::default()
        },
        threads: args.threads,
        ..Options::default()
    }
}

/// `--out` of a BAL problem ([`pingcal_ba::workflow::run_json`]).
fn write_bal_json(
    out: &std::path::Path,
    problem: &pingcal_ba::problem::Problem,
    summary: &solver::Summary,
    precision: &Option<Result<pingcal_ba::workflow::PrecisionSummary, WorkflowError>>,
    threads: usize,
) -> CmdResult {
    let json = pingcal_ba::workflow::run_json(problem, summary, precision.as_ref(), threads)?;
    write_atomic(out, serde_json::to_string_pretty(&json)?.as_bytes())?;
    Ok(())
}

/// The linear solver, the Schur product, the preconditioner's clusters and the times.
fn print_solver_details(summary: &solver::Summary) {
    println!(
        "linear solver: {} ({})",
        summary.linear_solver.kind, summary.linear_solver.reason
    );
    if let Some(p) = &summary.schur_product {
        println!("Schur product: {} ({})", p.product, p.reason);
    }
    if let Some(c) = summary.clusters.filter(|c| c.too_large_bytes > 0.0) {
        println!(
            "preconditioner: Schur–Jacobi: the {} clusters' matrices would need {:.1} GB, more than the memory limit (try a smaller --cluster-max-dim)",
            c.clusters,
            c.too_large_bytes / 1e9
        );
    } else if let Some(c) = summary.clusters.filter(|c| c.clusters == c.blocks) {
        println!(
            "preconditioner: cluster-Jacobi found no images similar enough to merge: Schur–Jacobi ({} blocks)",
            c.blocks
        );
    } else if let Some(c) = &summary.clusters {
        println!(
            "preconditioner: cluster-Jacobi, {} clusters of {} blocks (largest {} unknowns), holding {:.0} % of the blocks' similarity",
            c.clusters,
            c.blocks,
            c.largest_dim,
            100.0 * c.captured
        );
    }
    println!(
        "time: setup {:.3} s, evaluation {:.3} s, Schur complement {:.3} s, linear solver {:.3} s, total {:.3} s",
        summary.setup_time_s,
        summary.evaluation_time_s, summary.schur_time_s, summary.linear_solver_time_s, summary.time_s
    );
}

/// `--precision` of a BAL problem ([`pingcal_ba::workflow::precision_summary`]), printed
/// unless quiet.
fn bal_precision(
    problem: &pingcal_ba::problem::Problem,
    source: &str,
    quiet: bool,
) -> Result<pingcal_ba::workflow::PrecisionSummary, WorkflowError> {
    let out = pingcal_ba::workflow::precision_summary(problem, source)?;
    if !quiet {
        println!(
            "precision ({}): sigma0 {:.4}, redundancy {}, median camera-centre sigma {:.3e}, median point sigma {:.3e}, in {:.2} s",
            out.method,
            out.sigma0,
            out.redundancy,
            out.median_camera_centre_sigma,
            out.median_point_sigma,
            out.time_s
        );
    }
    Ok(out)
}

/// Refuses the options of measurement files on a BAL problem, which would ignore them.
fn refuse_measurement_options(args: &Args) -> Result<(), String> {
    let given: Vec<&str> = [
        ("--snoop", args.snoop.is_some()),
        ("--calibrate", args.calibrate.is_some()),
        ("--report", args.report.is_some()),
        ("--free-network", args.free_network),
        (
            "--min-intersection-angle",
            args.min_intersection_angle.is_some(),
        ),
    ]
    .iter()
    .filter(|o| o.1)
    .map(|o| o.0)
    .collect();
    if given.is_empty() {
        return Ok(());
    }
    let problem = match (&args.problem, &args.synthetic) {
        (Some(p), _) => format!("the BAL file {}", p.display()),
        _ => "a synthetic BAL problem".into(),
    };
    Err(format!(
        "{} {} to measurement files (.json, or markpts.txt with --dbat-camera), not to {problem}",
        given.join(", "),
        if given.len() == 1 { "applies" } else { "apply" }
    ))
}

/// Whether PROBLEM is DBAT's mark-point file.
fn is_dbat(args: &Args) -> bool {
    args.dbat.is_some() || args.dbat_camera.is_some()
}

/// A photogrammetric adjustment of pingcal's measurement file or DBAT's files
/// ([`pingcal_ba::workflow::adjust`]).
fn run_measurements(path: &std::path::Path, args: &Args) -> CmdResult {
    use pingcal_ba::initial::intersection::IntersectionOptions;
    use pingcal_ba::io::printable;
    let min_angle = args
        .min_intersection_angle
        .unwrap_or(IntersectionOptions::default().min_angle_deg);
    if !(0.0..180.0).contains(&min_angle) {
        return Err(
            format!("--min-intersection-angle {min_angle}: expected degrees in [0, 180)").into(),
        );
    }
    let meas = read_measurements(path, args)?;
    // DBAT's control file is checked by its reader; what is left concerns the marks.
    let built = meas
        .to_problem()
        .map_err(|e| e.in_file(&path.display().to_string()))?;
    for w in &built.warnings {
        let w = printable(&w.to_string());
        eprintln!("pingcal ba: warning: {}: {w}", path.display());
    }
    let options = pingcal_ba::workflow::AdjustOptions {
        solver: Options {
            max_iterations: args.max_iterations,
            function_tolerance: args.function_tolerance,
            gradient_tolerance: args.gradient_tolerance,
            parameter_tolerance: args.parameter_tolerance,
            threads: args.threads,
            ..Options::default()
        },
        min_intersection_angle_deg: min_angle,
        snoop: args.snoop,
        loss: args.loss.as_deref().map(parse_loss).transpose()?,
        free_network: args.free_network,
        // DBAT's files say nothing of the datum but the control: diagnosed before solving
        check_datum: is_dbat(args),
    };
    let a = pingcal_ba::workflow::adjust(&built, &path.display().to_string(), &options)?;
    if a.arbitrary_scale {
        eprintln!(
            "pingcal ba: warning: {}: a free network without distances: its scale is arbitrary",
            path.display()
        );
    }
    print_start(&a, min_angle, args.quiet);
    match &args.report {
        Some(file) => write_atomic(file, a.report.to_text().as_bytes())?,
        None if !args.quiet => print!("{}", a.report.to_text()),
        None => {}
    }
    if let Some(out) = &args.out {
        let mut json = serde_json::to_value(&a.report)?;
        json["initial_cost"] = a.summary.initial_cost.into();
        json["final_cost"] = a.summary.final_cost.into();
        json["time_s"] = a.summary.time_s.into();
        json["rms_px"] = a.precision.rms_image_px.into();
        write_atomic(out, serde_json::to_string_pretty(&json)?.as_bytes())?;
    }
    println!(
        "pingcal ba: {} images, {} points, {} observations; sigma0 {:.4}, RMS {:.4} px, redundancy {}, {} rejected; {}",
        a.problem.images.len(),
        a.problem.points.len(),
        a.problem.observations.len(),
        a.precision.sigma0,
        a.precision.rms_image_px,
        a.precision.redundancy,
        a.rejected.len(),
        a.summary.termination
    );
    Ok(())
}

/// PROBLEM read as pingcal's measurement file, or as DBAT's mark points with its camera
/// (and control); `--calibrate` replaces every camera's list of freed parameters.
fn read_measurements(
    path: &std::path::Path,
    args: &Args,
) -> Result<pingcal_ba::io::measurements::Measurements, super::CmdError> {
    use pingcal_ba::io::dbat;
    let mut meas = if is_dbat(args) {
        let Some(camera_file) = &args.dbat_camera else {
            return Err(format!(
                "{}: DBAT's mark points need their camera: --dbat-camera FILE (DBAT's camera XML, e.g. c4040z.xml)",
                path.display()
            )
            .into());
        };
        let camera = dbat::read_camera(camera_file)?;
        let mut m = dbat::read_dbat(path, args.dbat.as_deref(), &camera, 1000.0)?;
        // DBAT's camcal demo self-calibrates these (B1 plays its aspect parameter).
        for c in &mut m.cameras {
            c.calibrate = ["c", "xp", "yp", "K1", "K2", "K3", "P1", "P2", "B1"]
                .map(String::from)
                .to_vec();
        }
        m
    } else {
        pingcal_ba::io::measurements::Measurements::read(path)?
    };
    if let Some(list) = &args.calibrate {
        for c in &mut meas.cameras {
            c.calibrate = list.clone();
        }
    }
    Ok(meas)
}

/// What the start-up did and could not do: its steps on stdout (unless quiet), the images
/// and points it left out on stderr.
fn print_start(a: &pingcal_ba::workflow::Adjusted, min_angle: f64, quiet: bool) {
    use pingcal_ba::io::printable;
    if !quiet {
        for s in &a.steps {
            println!("  {s}");
        }
    }
    for (name, why) in &a.unoriented_images {
        eprintln!(
            "pingcal ba: warning: image '{}' not oriented: {why}",
            printable(name)
        );
    }
    for (name, why) in &a.undetermined_points {
        eprintln!(
            "pingcal ba: warning: point '{}' not determined: {why}",
            printable(name)
        );
    }
    if !a.refused_by_angle.is_empty() {
        let list: Vec<String> = a
            .refused_by_angle
            .iter()
            .map(|(name, angle)| format!("{} ({angle:.2}°)", printable(name)))
            .collect();
        eprintln!(
            "pingcal ba: {} point{} refused by the intersection angle (largest ray angle below {min_angle}°): {}",
            list.len(),
            if list.len() == 1 { "" } else { "s" },
            list.join(", ")
        );
    }
    if let (Some(n), false) = (a.estimability_not_checked, quiet) {
        println!(
            "  the intrinsics' estimability is judged after the adjustment ({n} reduced unknowns: too many to judge before)"
        );
    }
}
