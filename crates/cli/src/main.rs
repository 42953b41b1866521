//! `pingcal`: calibrate a camera (mono or stereo) against a rotating 2D laser range finder.
//!
//! Each subcommand lives in its own file under `commands/`; this file only parses the
//! command line and turns errors into a one-line message and a non-zero exit code: 1 for
//! an error, 2 for a usage error (clap's own), and the codes a command chooses through
//! [`commands::Exit`] (`calibrate`: 3 doubtful, 4 failed verdict).

use clap::{Parser, Subcommand};

use pingcal::commands;

#[derive(Parser)]
#[command(
    name = "pingcal",
    version,
    about = "Camera to rotating-2D-LRF calibration with a photogrammetric test field and ping-pong balls"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate the paper's test field and sensors, calibrate, print the check-point table.
    Demo(commands::demo::Args),
    /// Write a complete simulated project directory with ground truth.
    Simulate(commands::simulate::Args),
    /// Run the whole calibration pipeline on a project file.
    Calibrate(commands::calibrate::Args),
    /// Plan a field before building it: simulate and calibrate it many times, print the σ to expect and what matters most.
    Plan(commands::plan::Args),
    /// Find targets and balls in images.
    Detect(commands::detect::Args),
    /// Draw printable AICON-style coded targets (SVG).
    Targets(commands::targets::Args),
    /// Run a bundle adjustment on its own (BAL or pingcal measurement file).
    Ba(commands::ba::Args),
    /// Generate a synthetic BAL problem (for tests and benchmarks).
    GenBal(commands::gen_bal::Args),
    /// Build the LRF cloud from scans and fit the spheres.
    Cloud(commands::cloud::Args),
    /// The rotating LRF's mount and range errors from the room it scanned (no camera, no balls).
    LrfMount(commands::lrf_mount::Args),
    /// Read the LRF's scans from ROS 1 / ROS 2 bags into a pingcal-scan CSV, or list a bag's topics.
    Scans(commands::scans::Args),
    /// Frames for sphere-calib from a bag's PointCloud2 and Image / CompressedImage topics.
    Frames(commands::frames::Args),
    /// 3D conformal transform between two files of labelled points, with check points.
    Register(commands::register::Args),
    /// Camera against any lidar from one large sphere moved between frames (Tóth et al. 2020).
    SphereCalib(commands::sphere_calib::Args),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(a) => commands::demo::run(a),
        Command::Simulate(a) => commands::simulate::run(a),
        Command::Calibrate(a) => commands::calibrate::run(a),
        Command::Plan(a) => commands::plan::run(a),
        Command::Detect(a) => commands::detect::run(a),
        Command::Targets(a) => commands::targets::run(a),
        Command::Ba(a) => commands::ba::run(a),
        Command::GenBal(a) => commands::gen_bal::run(a),
        Command::Cloud(a) => commands::cloud::run(a),
        Command::LrfMount(a) => commands::lrf_mount::run(a),
        Command::Scans(a) => commands::scans::run(a),
        Command::Frames(a) => commands::frames::run(a),
        Command::Register(a) => commands::register::run(a),
        Command::SphereCalib(a) => commands::sphere_calib::run(a),
    };
    match result {
        Ok(()) => {}
        // `calibrate`'s verdicts end with codes of their own (3 doubtful, 4 failed)
        Err(commands::CmdError::Exit(x)) => {
            if !x.message.is_empty() {
                eprintln!("pingcal: {}", x.message);
            }
            std::process::exit(x.code);
        }
        Err(e) => {
            eprintln!("pingcal: error: {e}");
            std::process::exit(1);
        }
    }
}
