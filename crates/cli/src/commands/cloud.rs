//! `pingcal cloud SCAN... [--out FILE.ply] [--diameter-mm 38] [--balls FILE] [--mount-offset-mm
//! x,y,z] [--tilt-x-deg a] [--tilt-z-deg b] [--servo-zero-deg c] | --lrf-model results.json]`: the LRF cloud (paper eq. 2,
//! with the mount model of `pingcal_lrf::cloud`) from scan files (or PLY/XYZ clouds), the
//! balls found and fitted in it.
//! The PLY holds the cloud in grey with each ball's inlier points in one colour per ball,
//! and the fitted spheres as an element of their own (`element sphere N`: x y z radius and
//! the colour), so that the file reads back as exactly the scan points; `--balls` writes the centres as `id x y z sx sy sz`, the input format
//! of `pingcal register`.

use super::CmdResult;
use pingcal_lrf::ball_finder::{find_balls, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::cloud_file::{extent_mm, read_lrf_model, CloudPath, CloudUnit};
use pingcal_lrf::sensor::NoiseProfile;
use pingcal_lrf::RangeNoise;
use std::path::PathBuf;

/// Arguments of `pingcal cloud`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Scan files (`pingcal-scan` CSV), or PLY / PCD / XYZ clouds.
    #[arg(required = true)]
    pub scans: Vec<PathBuf>,
    /// Write the cloud with the fitted spheres as binary PLY.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Ball diameter, mm.
    #[arg(long, allow_hyphen_values = true, default_value_t = 38.0)]
    pub diameter_mm: f64,
    /// Write the ball centres with their σ's (`id x y z sx sy sz`, mm).
    #[arg(long)]
    pub balls: Option<PathBuf>,
    /// Unit of the cloud files' coordinates (PLY, PCD, XYZ): `mm` (the default, as before)
    /// or `m` (what PCL, ROS and most scanners write). Scan files are always mm.
    #[arg(long, default_value = "mm")]
    pub unit: CloudUnit,
    /// Range-noise profile of the sensor (σ of each range, which weighs the sphere fits
    /// and their σ0): URG-04LX (the default, as before), UTM-30LX, UST-10LX or VLP-16.
    #[arg(long, conflicts_with = "noise_sigma")]
    pub noise: Option<String>,
    /// A linear range-noise profile σ = A + B·r (`A,B`: A in mm, B per mm of range).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub noise_sigma: Option<Vec<f64>>,
    /// The sensor's longest range, mm: ranges beyond it are masked as no return and counted
    /// in a warning. By default the named profile's sensor's for scan files (URG-04LX:
    /// 5600; UTM-30LX 60000, UST-10LX 30000, VLP-16 100000) and none for clouds (PLY, PCD,
    /// XYZ) or with `--noise-sigma`; given, it applies to every file.
    #[arg(long)]
    pub max_range_mm: Option<f64>,
    /// Seed of the RANSAC choices.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print every candidate not used, with the reason.
    #[arg(long)]
    pub why: bool,
    /// Mount model: the scanner centre seen from the servo shaft, in the rotating frame
    /// (mm, `x,y,z`, e.g. `-1.5,0,2`; eq. 2 assumes 0,0,0).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "0,0,0"
    )]
    pub mount_offset_mm: Vec<f64>,
    /// Mount model: tilt of the scan plane about the rotating frame's X axis (degrees).
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub tilt_x_deg: f64,
    /// Mount model: tilt of the scan plane about the rotating frame's Z axis (degrees).
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub tilt_z_deg: f64,
    /// Mount model: servo reading at which the scan plane is the LRF frame's X–Y plane.
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub servo_zero_deg: f64,
    /// Mount model: scale error of the servo angle (β = servo · (1 + s)), as `lrf_mount`'s
    /// `servo_scale` in results.json.
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub servo_scale: f64,
    /// Range model: the sensor reports `true · (1 + range_scale) + range_offset` (mm), as
    /// `lrf_mount`'s `range_offset` in results.json.
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub range_offset_mm: f64,
    /// Range model: the range scale error (see `--range-offset-mm`).
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub range_scale: f64,
    /// Servo timing: how much later the servo's stamps are than the scanner's (seconds), as
    /// `lrf_mount`'s `time_offset_s` in results.json; each beam of a continuous sweep is
    /// turned by the servo's rate times it (no effect on a stop-and-go sweep).
    #[arg(long, allow_hyphen_values = true, default_value_t = 0.0)]
    pub servo_time_offset_s: f64,
    /// The whole LRF model (mount and range) of a calibration: its `results.json` (the
    /// `lrf_model` block: the joint adjustment's estimate, or the project's mount), or the
    /// `mount.json` of `pingcal lrf-mount`, so that any later scan gets the cloud the
    /// calibration's extrinsic is valid for.
    #[arg(long, conflicts_with_all = ["mount_offset_mm", "tilt_x_deg", "tilt_z_deg", "servo_zero_deg", "servo_scale", "range_offset_mm", "range_scale", "servo_time_offset_s"])]
    pub lrf_model: Option<PathBuf>,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    if !(args.diameter_mm > 0.0 && args.diameter_mm.is_finite()) {
        return Err(format!(
            "--diameter-mm: expected a positive number, found {}",
            args.diameter_mm
        )
        .into());
    }
    let m = &args.mount_offset_mm;
    if m.len() != 3 {
        return Err(format!(
            "--mount-offset-mm: expected three numbers x,y,z, found {}",
            m.len()
        )
        .into());
    }
    let values = [
        m[0],
        m[1],
        m[2],
        args.tilt_x_deg,
        args.tilt_z_deg,
        args.servo_zero_deg,
        args.servo_scale,
        args.range_offset_mm,
        args.range_scale,
        args.servo_time_offset_s,
    ];
    if values.iter().any(|v| !v.is_finite()) {
        return Err("mount model: --mount-offset-mm, --tilt-x-deg, --tilt-z-deg, --servo-zero-deg, --servo-scale, --range-offset-mm, --range-scale and --servo-time-offset-s must be finite numbers".into());
    }
    if !(args.servo_scale.abs() < 0.5 && args.range_scale.abs() < 0.5) {
        return Err(format!(
            "mount model: --servo-scale {} / --range-scale {}: expected a scale error, a small fraction (e.g. 0.003), not a factor",
            args.servo_scale, args.range_scale
        )
        .into());
    }
    let mount = mount_of(&args)?;
    let (noise, profile) = noise_of(&args.noise, &args.noise_sigma)?;
    for (option, file) in [("--out", &args.out), ("--balls", &args.balls)] {
        if let Some(f) = file {
            super::preflight::check_out_file(option, f)?;
        }
    }
    if let Some(m) = args.max_range_mm {
        if !(m > 0.0) {
            return Err(
                format!("--max-range-mm: expected a positive range in mm, found {m}").into(),
            );
        }
    }
    // the sensor's reach: the named profile's (URG-04LX's by default), none for a line
    let profile_max = match (profile, &args.noise_sigma) {
        (Some(p), _) => Some(p.max_range_mm()),
        (None, Some(_)) => None,
        (None, None) => Some(NoiseProfile::Urg04lx.max_range_mm()),
    };
    let cloud = read_clouds(&args, &mount, profile_max)?;
    let extent = extent_mm(&cloud);
    if args.diameter_mm > extent {
        let names: Vec<String> = args.scans.iter().map(|f| f.display().to_string()).collect();
        eprintln!(
            "pingcal: warning: {}: --diameter-mm {} is larger than the cloud ({extent:.3} mm across): no ball can be found (wrong --unit?)",
            names.join(", "),
            args.diameter_mm
        );
    }
    let opt = FinderOptions {
        noise,
        diameter_mm: args.diameter_mm,
        seed: args.seed,
        ..Default::default()
    };
    let found = find_balls(&cloud, &opt);
    if found.balls.is_empty() {
        warn_other_sizes(&cloud, &opt);
    }
    if let Some(out) = &args.out {
        let comments = vec![format!(
            "pingcal cloud: {} points, {} balls of {} mm",
            cloud.len(),
            found.balls.len(),
            args.diameter_mm
        )];
        let mut bytes = Vec::new();
        pingcal_lrf::ply::write_cloud_with_spheres(
            &mut bytes,
            &cloud,
            &found.balls,
            args.diameter_mm / 2.0,
            &comments,
        )?;
        super::write_atomic(out, &bytes)?;
    }
    if let Some(path) = &args.balls {
        let text = centres_text(&found.balls);
        super::write_atomic(path, text.as_bytes())?;
    }
    if args.why {
        print_why(&found, args.diameter_mm);
    }
    println!(
        "cloud: {} points from {} file(s), {} plane(s), {} ball(s) of {} mm, {} candidate(s) not used{}",
        cloud.len(),
        args.scans.len(),
        found.planes.len(),
        found.balls.len(),
        args.diameter_mm,
        found.rejected.len(),
        args.out.as_ref().map_or(String::new(), |o| format!(" → {}", o.display()))
    );
    Ok(())
}

/// The LRF's mount model: `--lrf-model`'s file, or the options.
fn mount_of(args: &Args) -> Result<MountModel, super::CmdError> {
    let m = &args.mount_offset_mm;
    let mount = match &args.lrf_model {
        Some(path) => read_lrf_model(path)?,
        None => MountModel {
            offset_mm: [m[0], m[1], m[2]],
            tilt_x_deg: args.tilt_x_deg,
            tilt_z_deg: args.tilt_z_deg,
            servo_zero_deg: args.servo_zero_deg,
            servo_scale: args.servo_scale,
            range_offset_mm: args.range_offset_mm,
            range_scale: args.range_scale,
            servo_time_offset_s: args.servo_time_offset_s,
        },
    };
    mount.check([
        "--mount-offset-mm",
        "--tilt-x-deg",
        "--tilt-z-deg",
        "--servo-zero-deg",
        "--servo-scale",
        "--range-offset-mm",
        "--range-scale",
    ])?;
    Ok(mount)
}

/// The range noise of `--noise` (a profile's name) or `--noise-sigma A,B`, or the
/// URG-04LX's when neither is given ([`pingcal_lrf::settings::range_noise`], as a project's
/// `[lrf]`); with the named profile, if any. `pingcal lrf-mount` reads its flags with it
/// too.
pub(crate) fn noise_of(
    noise: &Option<String>,
    noise_sigma: &Option<Vec<f64>>,
) -> Result<(RangeNoise, Option<NoiseProfile>), String> {
    let profile = noise
        .as_deref()
        .map(str::parse::<NoiseProfile>)
        .transpose()
        .map_err(|e| format!("--noise: {e}"))?;
    let line = match noise_sigma.as_deref() {
        None => None,
        Some(&[a, b]) => Some([a, b]),
        Some(v) => {
            return Err(format!(
                "--noise-sigma: expected two numbers A,B, found {}",
                v.len()
            ))
        }
    };
    let noise = pingcal_lrf::settings::range_noise(profile, line, ["--noise", "--noise-sigma"])?
        .unwrap_or_else(RangeNoise::urg_04lx);
    Ok((noise, profile))
}

/// Every `--scans` file read through `mount` into one cloud; ranges beyond the sensor's
/// reach masked (`--max-range-mm`, or the noise profile's for scan files), with warnings.
fn read_clouds(
    args: &Args,
    mount: &MountModel,
    profile_max: Option<f64>,
) -> Result<Cloud, super::CmdError> {
    let mut cloud = Cloud::default();
    for f in &args.scans {
        let file = CloudPath::new(f.clone());
        let (mut c, warnings) = file.read_in(mount, args.unit)?;
        for w in warnings {
            eprintln!("pingcal: warning: {w}");
        }
        if let Some(max) = args
            .max_range_mm
            .or(profile_max.filter(|_| file.is_scans()))
        {
            let n = c.mask_beyond(max);
            if n > 0 {
                eprintln!(
                    "pingcal: warning: {}: {n} range(s) beyond the sensor's {max} mm masked as no return (--max-range-mm to change)",
                    f.display()
                );
            }
        }
        cloud.extend(c);
    }
    Ok(cloud)
}

/// No ball of the given size: the sizes of the spheres evident in the cloud, if any.
fn warn_other_sizes(cloud: &Cloud, opt: &FinderOptions) {
    let evident = pingcal_lrf::sphere_size::evident_spheres(cloud, opt);
    if let Some(best) = evident.first() {
        let all: Vec<String> = evident
            .iter()
            .map(|e| {
                let b = &e.found.balls[0];
                format!(
                    "{:.0} mm ({} ball(s), the first at ({:.0}, {:.0}, {:.0}) mm on {} rays)",
                    e.diameter_mm,
                    e.found.balls.len(),
                    b.centre.x,
                    b.centre.y,
                    b.centre.z,
                    b.inliers.len()
                )
            })
            .collect();
        eprintln!(
            "pingcal: warning: no ball of {} mm found, but spheres of another size are evident: {}: --diameter-mm {:.0}?",
            opt.diameter_mm,
            all.join("; "),
            best.diameter_mm
        );
    }
}

/// `--balls`: the centres in the LRF frame (mm) with their σ's, one line per ball.
fn centres_text(balls: &[pingcal_lrf::ball_finder::Ball]) -> String {
    let mut text =
        String::from("# pingcal cloud: ball centres in the LRF frame, mm: id x y z sx sy sz\n");
    for (k, b) in balls.iter().enumerate() {
        let c = b.centre;
        let s = b.cov.diagonal().map(|v| v.max(0.0).sqrt());
        text += &format!(
            "L{} {:.3} {:.3} {:.3} {:.3} {:.3} {:.3}\n",
            k + 1,
            c.x,
            c.y,
            c.z,
            s.x,
            s.y,
            s.z
        );
    }
    text
}

/// `--why`: the walls removed, every ball's support and every candidate not used.
fn print_why(found: &pingcal_lrf::ball_finder::FindResult, diameter_mm: f64) {
    for (n, d) in &found.planes {
        println!(
            "wall removed: {:.4} x + {:.4} y + {:.4} z = {:.1} mm",
            n.x, n.y, n.z, d
        );
    }
    for (k, b) in found.balls.iter().enumerate() {
        let (c, s) = (b.centre, &b.support);
        // the free fit fails or runs off where the range noise is a fair part of the
        // radius (see `ball_finder`): the radius is then not determined by the cap
        let nominal = diameter_mm / 2.0;
        let free_radius = if s.free_radius_determined(nominal) {
            format!("{:.1} ± {:.1} mm", s.free_radius_mm, s.sigma_free_radius_mm)
        } else {
            format!(
                "not determined (range σ {:.1} mm against a {nominal:.1} mm radius)",
                s.range_sigma_mm
            )
        };
        println!(
            "ball L{}: ({:.1}, {:.1}, {:.1}) mm, {} of {} cluster points on it, σ₀ {:.2}; free radius {free_radius}; {} beams meet it, {} pass through; {} of 8 sectors covered; ring beside it at its front's depth {:08b}",
            k + 1,
            c.x,
            c.y,
            c.z,
            b.inliers.len(),
            b.cluster_points,
            b.sigma0,
            s.on_surface,
            s.through,
            s.coverage,
            s.beside
        );
    }
    for r in &found.rejected {
        let c = r.centre;
        println!(
            "not used: ({:.1}, {:.1}, {:.1}) mm, {} points: {}",
            c.x, c.y, c.z, r.cluster_points, r.reason
        );
    }
}
