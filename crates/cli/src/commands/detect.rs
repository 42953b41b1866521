//! `pingcal detect IMAGE... [--out FILE] [--debug DIR]`: targets (coded, plain) and balls found
//! in images, as the JSON of SPEC.md (pixel origin at the centre of the top-left pixel, x to the
//! right, y down).

use super::CmdResult;
use pingcal_targets::detect::BallMode;
use pingcal_targets::{load_image, DetectParams, Detector};
use std::path::PathBuf;

/// Arguments of `pingcal detect`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Images (TIFF, PNG or JPEG; 8 or 16 bit; grey or colour).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Write the detections as JSON to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write an overlay PNG per image (ellipses, centres, IDs) into this folder.
    #[arg(long)]
    pub debug: Option<PathBuf>,
    /// Ring-code bit counts to read, comma separated (AICON: 14 or 12).
    #[arg(long, value_delimiter = ',', default_value = "14")]
    pub bits: Vec<u32>,
    /// The printed code ring's inner and outer radius in dot radii, as `[targets]
    /// ring_inner` and `ring_outer` of project.toml (AICON: 2,3).
    #[arg(long, value_delimiter = ',', num_args = 2, default_values_t = [2.0, 3.0])]
    pub ring: Vec<f64>,
    /// The images contain no ping-pong balls (do not classify large blobs as balls).
    #[arg(long)]
    pub no_balls: bool,
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let mut params = DetectParams {
        code_bits: args.bits.clone(),
        ring: (args.ring[0], args.ring[1]),
        ..DetectParams::default()
    };
    if args.no_balls {
        params.balls = BallMode::Off;
    }
    let det = Detector::new(params)?;
    if let Some(dir) = &args.debug {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("{}: cannot create folder: {e}", dir.display()))?;
    }
    // without overlays, images are decoded and measured in parallel (decoding of one
    // overlaps detection in others); overlays need each image kept, one at a time
    let detections: Vec<pingcal_targets::ImageDetections> = match &args.debug {
        None => pingcal_targets::detect_files(&args.images, &det)
            .into_iter()
            .collect::<Result<_, _>>()?,
        Some(dir) => {
            let mut v = Vec::with_capacity(args.images.len());
            for path in &args.images {
                let img = load_image(path)?;
                let d = det.detect(&img);
                let stem = path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "image".into());
                let out = dir.join(format!("{stem}.overlay.png"));
                pingcal_targets::overlay::draw_detections(&img, &d).save(&out)?;
                v.push(d);
            }
            v
        }
    };
    let mut images = Vec::new();
    let (mut n_coded, mut n_ids, mut n_plain, mut n_balls) = (0, 0, 0, 0);
    for (path, d) in args.images.iter().zip(&detections) {
        let targets: Vec<serde_json::Value> = d
            .targets
            .iter()
            .map(|t| {
                serde_json::json!({
                    "id": t.id,
                    "kind": t.kind,
                    "x": t.x,
                    "y": t.y,
                    "sigma_px": t.sigma_px,
                })
            })
            .collect();
        for t in &d.targets {
            match t.kind {
                pingcal_targets::TargetKind::Coded => {
                    n_coded += 1;
                    n_ids += t.id.is_some() as usize;
                }
                pingcal_targets::TargetKind::Plain => n_plain += 1,
                pingcal_targets::TargetKind::Ball => n_balls += 1,
            }
        }
        images.push(serde_json::json!({
            "file": path.display().to_string(),
            "width": d.width,
            "height": d.height,
            "targets": targets,
        }));
    }
    if let Some(out) = &args.out {
        let text = serde_json::to_string_pretty(&serde_json::json!({ "images": images }))?;
        super::write_atomic(out, text.as_bytes())?;
    }
    println!(
        "detect: {} images; {n_coded} coded targets ({n_ids} identified), {n_plain} plain, {n_balls} balls{}",
        args.images.len(),
        args.out.as_ref().map(|p| format!("; written to {}", p.display())).unwrap_or_default()
    );
    Ok(())
}
