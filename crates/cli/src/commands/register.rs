//! `pingcal register LRF_POINTS CAMERA_POINTS [--control ID,..] [--check ID,..] [--out FILE]`:
//! the 3D conformal transform alone, with the check-point table (docs/formats.md).

use super::preflight::{check_out_file, check_unique};
use super::CmdResult;
use pingcal_lrf::registration::{self, PointObs, RegistrationOptions};
use pingcal_lrf::xyz::{read_labelled_file, LabelledPoint};
use std::path::PathBuf;

/// Arguments of `pingcal register`.
#[derive(clap::Args)]
pub struct Args {
    /// Ball centres in the LRF frame: `id x y z [sx sy sz]` per line, mm.
    pub lrf_points: PathBuf,
    /// Ball centres in the camera (photogrammetric) frame, same format.
    pub camera_points: PathBuf,
    /// Control point ids, comma separated (default: every common point not a check point).
    #[arg(long, value_delimiter = ',')]
    pub control: Vec<String>,
    /// Check point ids, comma separated (default: none; leave-one-out judges every point).
    #[arg(long, value_delimiter = ',')]
    pub check: Vec<String>,
    /// Estimate a scale factor too (7-parameter transform).
    #[arg(long)]
    pub scale: bool,
    /// Write the result as JSON (the `extrinsic`, `check_points`, `mean_check_error_mm` keys).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn to_obs(points: &[LabelledPoint]) -> Vec<PointObs> {
    points.iter().map(LabelledPoint::to_obs).collect()
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    check_unique("--control", &args.control)?;
    check_unique("--check", &args.check)?;
    if let Some(out) = &args.out {
        check_out_file("--out", out)?;
    }
    let lrf = read_labelled_file(&args.lrf_points)?;
    let cam = read_labelled_file(&args.camera_points)?;
    // without σ's in both files the weights are nominal: scale the covariance by σ₀²
    let posterior = lrf.iter().chain(&cam).any(|p| p.sigma.is_none());
    let opt = RegistrationOptions {
        estimate_scale: args.scale,
        posterior,
        ..Default::default()
    };
    let ev = registration::evaluate(
        &to_obs(&lrf),
        &to_obs(&cam),
        &args.control,
        &args.check,
        &opt,
    )
    .map_err(|e| {
        format!(
            "{} + {}: {e}",
            args.lrf_points.display(),
            args.camera_points.display()
        )
    })?;
    let names = (
        args.lrf_points.display().to_string(),
        args.camera_points.display().to_string(),
    );
    if let Some(w) = ev.unpaired.warning(&names.0, &names.1) {
        eprintln!("pingcal register: warning: {w}");
    }
    if let Some(out) = &args.out {
        let text = serde_json::to_string_pretty(&ev.to_json())?;
        super::write_atomic(out, text.as_bytes())?;
    }
    let r = &ev.registration;
    let t = r.camera_from_lrf.translation;
    let st = r.sigma_translation_mm;
    let e = r.camera_from_lrf.opk_deg();
    let (what, table) = if ev.check.rows.is_empty() {
        ("leave-one-out", &ev.leave_one_out)
    } else {
        ("check", &ev.check)
    };
    println!(
        "register: {} control, {} check points; t = ({:.1}, {:.1}, {:.1}) ± ({:.1}, {:.1}, {:.1}) mm, ω φ κ = ({:.3}, {:.3}, {:.3})°; mean {what} error {:.2} mm (sd {:.2}){}",
        r.ids.len(),
        ev.check.rows.len(),
        t.x,
        t.y,
        t.z,
        st.x,
        st.y,
        st.z,
        e[0],
        e[1],
        e[2],
        table.mean_mm,
        table.sd_mm,
        args.out.as_ref().map_or(String::new(), |o| format!(" → {}", o.display()))
    );
    Ok(())
}
