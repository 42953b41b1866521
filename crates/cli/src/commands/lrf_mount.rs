//! `pingcal lrf-mount SCANS... [--out mount.json] [--lrf-model START.json] [--noise P |
//! --noise-sigma A,B] [--seed N]`: the rotating LRF's mount and range errors from the room it
//! scanned, with no camera and no ball (`pingcal_lrf::room`): the walls, floor and ceiling
//! seen at several servo angles (both halves of a full turn, a nod, any sweep) made to
//! coincide. Prints the sweep, every parameter with its σ or why the sweep or the room does
//! not determine it, and the planes; `--out` writes them as JSON whose `lrf_model` block
//! `pingcal cloud --lrf-model` and a project's `[lrf] lrf_model` read. When no wall is found,
//! the refusal names the surfaces the search refused and why.

use super::CmdResult;
use pingcal_lrf::ball_finder::{find_walls, find_walls_explained, FinderOptions};
use pingcal_lrf::cloud::{Cloud, MountModel};
use pingcal_lrf::cloud_file::{read_cloud_file_in, read_lrf_model, CloudUnit};
use pingcal_lrf::room::{
    mount_from_room_refinding, room_finder, why_no_walls, RoomMount, RoomOptions,
};
use pingcal_lrf::sensor::MountParam;
use std::path::PathBuf;

/// Arguments of `pingcal lrf-mount`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Scan files (`pingcal-scan` CSV) of the servo's sweep in a room: a full turn, a nod or
    /// any sweep that sees a plane at several servo angles.
    #[arg(required = true)]
    pub scans: Vec<PathBuf>,
    /// Write the estimate as JSON (its `lrf_model` block is what `pingcal cloud --lrf-model`
    /// and `[lrf] lrf_model` read).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Start from this LRF model (a results.json or a mount.json) instead of eq. 2's; the
    /// parameters the room does not determine stay at its values.
    #[arg(long)]
    pub lrf_model: Option<PathBuf>,
    /// Range-noise profile of the sensor: URG-04LX (the default), UTM-30LX, UST-10LX or VLP-16.
    #[arg(long, conflicts_with = "noise_sigma")]
    pub noise: Option<String>,
    /// A linear range-noise profile σ = A + B·r (`A,B`: A in mm, B per mm of range).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub noise_sigma: Option<Vec<f64>>,
    /// Seed of the RANSAC that finds the planes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let (noise, _) = super::cloud::noise_of(&args.noise, &args.noise_sigma)?;
    let start = match &args.lrf_model {
        Some(p) => read_lrf_model(p)?,
        None => MountModel::default(),
    };
    if let Some(out) = &args.out {
        super::preflight::check_out_file("--out", out)?;
    }
    let mut cloud = Cloud::default();
    for f in &args.scans {
        let (c, warnings) = read_cloud_file_in(f, &start, CloudUnit::Mm)?;
        for w in warnings {
            eprintln!("pingcal: warning: {w}");
        }
        if c.readings.is_none() && !c.is_empty() {
            return Err(format!(
                "{}: a point cloud: lrf-mount needs the scans as the LRF reported them (pingcal-scan files), with each beam's servo angle, beam angle and range",
                f.display()
            )
            .into());
        }
        cloud.extend(c);
    }
    let finder = room_finder(FinderOptions {
        noise,
        seed: args.seed,
        ..FinderOptions::default()
    });
    let names: Vec<String> = args.scans.iter().map(|p| p.display().to_string()).collect();
    let (walls, refused) = find_walls_explained(&cloud, &finder);
    if walls.is_empty() {
        let why = why_no_walls(cloud.len(), &refused, finder.plane_min_fraction);
        return Err(format!("{}: {why}", names.join(", ")).into());
    }
    let opts = RoomOptions {
        noise,
        ..RoomOptions::default()
    };
    let r = mount_from_room_refinding(&cloud, &walls, &start, &opts, |c| find_walls(c, &finder))
        .map_err(|e| format!("{}: {e}", names.join(", ")))?;
    println!("sweep: {}", r.sweep.describe());
    print_estimate(&r);
    if let Some(out) = &args.out {
        let json = estimate_json(&r, &names);
        let text = serde_json::to_string_pretty(&json)? + "\n";
        super::write_atomic(out, text.as_bytes())?;
    }
    let determined = r.parameters.iter().filter(|p| p.sigma.is_some()).count();
    println!(
        "lrf-mount: {} planes, {} beams ({} rejected), sigma0 {:.3}; {determined} of {} parameters determined{}",
        r.planes.len(),
        r.beams,
        r.rejected,
        r.sigma0,
        r.parameters.len(),
        args.out
            .as_ref()
            .map_or(String::new(), |o| format!(" → {}", o.display()))
    );
    Ok(())
}

/// The unit of a parameter in print.
fn unit(name: &str) -> &'static str {
    MountParam::named(name).map_or(" mm", MountParam::unit)
}

fn print_estimate(r: &RoomMount) {
    for p in &r.parameters {
        match (p.sigma, &p.held) {
            (Some(s), _) => println!(
                "{:<13} {:>10.4}{u} ± {:.4}{u}",
                p.name,
                p.value,
                s,
                u = unit(p.name)
            ),
            (None, why) => println!(
                "{:<13} {:>10.4}{} held: {}",
                p.name,
                p.value,
                unit(p.name),
                why.as_deref().unwrap_or("")
            ),
        }
    }
    if r.wall_searches > 1 {
        println!(
            "the walls were found again through the estimate ({} searches): the start's cloud showed fewer",
            r.wall_searches
        );
    }
    for (k, p) in r.planes.iter().enumerate() {
        let n = p.normal;
        println!(
            "plane {}: {:.4} x + {:.4} y + {:.4} z = {:.1} mm, {} beams, RMS {:.1} mm, bent by up to {:.1} mm",
            k + 1,
            n.x,
            n.y,
            n.z,
            p.offset_mm,
            p.beams,
            p.rms_mm,
            p.bend_mm
        );
    }
}

/// The JSON of `--out`: the model, every parameter, the planes and the fit.
fn estimate_json(r: &RoomMount, scans: &[String]) -> serde_json::Value {
    let params: Vec<serde_json::Value> = r
        .parameters
        .iter()
        .map(|p| {
            serde_json::json!({
                "name": p.name,
                "value": p.value,
                "sigma": p.sigma,
                "held": p.held,
            })
        })
        .collect();
    let planes: Vec<serde_json::Value> = r
        .planes
        .iter()
        .map(|p| {
            serde_json::json!({
                "normal": [p.normal.x, p.normal.y, p.normal.z],
                "offset_mm": p.offset_mm,
                "beams": p.beams,
                "rms_mm": p.rms_mm,
                "bend_mm": p.bend_mm,
            })
        })
        .collect();
    let mut model = serde_json::to_value(r.mount).expect("a mount model is plain numbers");
    model["source"] = "lrf-mount (the room's planes)".into();
    serde_json::json!({
        "generator": format!("pingcal {} lrf-mount", env!("CARGO_PKG_VERSION")),
        "scans": scans,
        "lrf_model": model,
        "parameters": params,
        "planes": planes,
        "sigma0": r.sigma0,
        "redundancy": r.redundancy,
        "beams": r.beams,
        "beams_rejected": r.rejected,
        "wall_searches": r.wall_searches,
        "sweep_deg": [r.sweep.min_deg, r.sweep.max_deg],
    })
}
