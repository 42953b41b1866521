//! `pingcal scans BAG... --scan-topic T --servo-topic T [--servo-joint NAME | --servo-scale S
//! --servo-offset O | --servo-tf-child F --servo-axis x,y,z] --out scans.csv`: the LRF's
//! scans read from ROS 1 bags and ROS 2 bags (MCAP, sqlite3, or a bag folder), the servo
//! angle interpolated at each beam's time, written as `pingcal-scan` v2 CSV (one servo
//! angle at the first and one at the last beam of each scan). `pingcal scans BAG... --list`
//! prints each bag's topics, types and message counts.
//!
//! The output is written to `.NAME.partial` beside it and renamed when complete, as the
//! other commands write theirs: a failed run leaves an earlier file untouched.

use super::CmdResult;
use pingcal_lrf::scan::ScanWriter;
use pingcal_rosbag::assemble::{assemble, servo_series, ServoSource, Topics};
use pingcal_rosbag::{bag_files, Bag};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `pingcal scans`.
#[derive(clap::Args)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Bags: ROS 1 `.bag`, ROS 2 `.mcap` or `.db3`, or a ROS 2 bag folder.
    #[arg(required = true)]
    pub bags: Vec<PathBuf>,
    /// Print the topics, their types and message counts, and stop.
    #[arg(long)]
    pub list: bool,
    /// The `sensor_msgs/LaserScan` topic.
    #[arg(long, required_unless_present = "list")]
    pub scan_topic: Option<String>,
    /// The servo topic: `sensor_msgs/JointState` (with --servo-joint), `tf2_msgs/TFMessage`
    /// (with --servo-tf-child) or a numeric `std_msgs` type (Float32, Float64, Int32, UInt16).
    #[arg(long, required_unless_present = "list")]
    pub servo_topic: Option<String>,
    /// The servo's joint name in the JointState messages (positions in radians).
    #[arg(long, conflicts_with_all = ["servo_scale", "servo_offset", "servo_tf_child"])]
    pub servo_joint: Option<String>,
    /// Numeric servo topic: degrees per unit (e.g. 0.087890625 for Dynamixel ticks).
    #[arg(long, allow_hyphen_values = true, conflicts_with = "servo_tf_child")]
    pub servo_scale: Option<f64>,
    /// Numeric servo topic: degrees at value 0.
    #[arg(long, allow_hyphen_values = true, conflicts_with = "servo_tf_child")]
    pub servo_offset: Option<f64>,
    /// tf servo topic: the child frame that turns with the servo.
    #[arg(long)]
    pub servo_tf_child: Option<String>,
    /// tf servo topic: the servo axis in the parent frame (`x,y,z`).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        default_value = "0,1,0"
    )]
    pub servo_axis: Vec<f64>,
    /// The scan file to write (`pingcal-scan` v2 CSV).
    #[arg(long, required_unless_present = "list")]
    pub out: Option<PathBuf>,
}

fn open_bags(paths: &[PathBuf]) -> Result<Vec<Bag>, super::CmdError> {
    let mut bags = Vec::new();
    for p in paths {
        for f in bag_files(p)? {
            bags.push(Bag::open(&f)?);
        }
    }
    Ok(bags)
}

fn list(bags: &[Bag]) -> CmdResult {
    let mut n = 0;
    for bag in bags {
        println!("{} ({:?})", bag.name(), bag.format());
        for t in bag.topics()? {
            println!("  {:<32} {:<28} {}", t.name, t.msg_type, t.count);
            n += 1;
        }
    }
    println!("scans: {n} topic(s) in {} bag(s)", bags.len());
    Ok(())
}

fn source(args: &Args) -> Result<ServoSource, String> {
    if let Some(j) = &args.servo_joint {
        return Ok(ServoSource::Joint(j.clone()));
    }
    if let Some(child) = &args.servo_tf_child {
        let a = &args.servo_axis;
        let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
        if a.len() != 3 || !(norm > 0.0) || !norm.is_finite() {
            return Err("--servo-axis: expected three numbers x,y,z, not all 0".into());
        }
        let axis = [a[0] / norm, a[1] / norm, a[2] / norm];
        return Ok(ServoSource::Tf {
            child: child.clone(),
            axis,
        });
    }
    let scale = args.servo_scale.unwrap_or(1.0);
    let offset = args.servo_offset.unwrap_or(0.0);
    if !(scale.is_finite() && scale != 0.0 && offset.is_finite()) {
        return Err(format!("--servo-scale {scale} / --servo-offset {offset}: expected finite numbers, the scale not 0"));
    }
    Ok(ServoSource::Numeric { scale, offset })
}

/// Refuses an output file that is one of the bags (it would be replaced).
fn check_not_an_input(out: &Path, bags: &[PathBuf]) -> Result<(), String> {
    let Ok(o) = out.canonicalize() else {
        return Ok(());
    };
    for b in bags {
        if b.canonicalize().is_ok_and(|b| b == o || o.starts_with(&b)) {
            return Err(format!("--out {}: is one of the bags read", out.display()));
        }
    }
    Ok(())
}

/// Writes the scans of `bags` to `tmp`; returns (scans, beams, skipped before, after).
fn write_scans(
    bags: &[Bag],
    topics: &Topics,
    tmp: &Path,
    out: &Path,
) -> Result<[u64; 4], super::CmdError> {
    let series = servo_series(bags, topics)?;
    let file =
        std::fs::File::create(tmp).map_err(|e| format!("{}: cannot write: {e}", out.display()))?;
    let names: Vec<&str> = bags.iter().map(Bag::name).collect();
    let extra = format!(
        "source=pingcal scans {} (scans {}, servo {})",
        names.join(" "),
        topics.scan,
        topics.servo
    );
    let mut writer = None;
    let mut beams = 0;
    let io = |e: std::io::Error| pingcal_rosbag::RosbagError::Io {
        file: out.display().to_string(),
        msg: format!("cannot write: {e}"),
    };
    let done = assemble(bags, topics, &series, &mut |h, line| {
        if writer.is_none() {
            beams = line.ranges_mm.len();
            let w = std::io::BufWriter::with_capacity(1 << 16, file.try_clone().map_err(io)?);
            writer = Some(ScanWriter::new_v2(w, h, beams, &[extra.as_str()]).map_err(io)?);
        }
        writer
            .as_mut()
            .map_or(Ok(()), |w| w.write_line(&line))
            .map_err(io)
    })?;
    let Some(w) = writer else {
        return Err(format!(
            "{}: topic {}: no scan lies within the servo messages ({} before the first, {} after the last)",
            names.join(", "), topics.scan, done.before_servo, done.after_servo
        )
        .into());
    };
    w.finish().and_then(|mut w| w.flush()).map_err(io)?;
    file.sync_all().map_err(io)?;
    Ok([
        done.scans,
        beams as u64,
        done.before_servo,
        done.after_servo,
    ])
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let bags = open_bags(&args.bags)?;
    if args.list {
        return list(&bags);
    }
    let (Some(scan), Some(servo), Some(out)) = (&args.scan_topic, &args.servo_topic, &args.out)
    else {
        return Err("--scan-topic, --servo-topic and --out are needed (or --list)".into());
    };
    super::preflight::check_out_file("--out", out)?;
    check_not_an_input(out, &args.bags)?;
    let topics = Topics {
        scan: scan.clone(),
        servo: servo.clone(),
        source: source(&args)?,
    };
    // Through symlinks, the file behind them is replaced; a device or FIFO is written straight.
    let (tmp, target) = match super::write_target(out)? {
        super::WriteTarget::Direct(p) => (p, None),
        super::WriteTarget::Replace(t) => (super::partial_path(&t)?, Some(t)),
    };
    let result = write_scans(&bags, &topics, &tmp, out);
    let [n, beams, before, after] = match result {
        Ok(r) => r,
        Err(e) => {
            if target.is_some() {
                let _ = std::fs::remove_file(&tmp);
            }
            return Err(e);
        }
    };
    if let Some(t) = &target {
        std::fs::rename(&tmp, t).map_err(|e| format!("{}: cannot write: {e}", out.display()))?;
    }
    for (k, what) in [
        (before, "before the first servo message"),
        (after, "after the last servo message"),
    ] {
        if k > 0 {
            eprintln!("pingcal: warning: topic {scan}: {k} scan(s) {what} skipped (no servo angle to interpolate)");
        }
    }
    println!(
        "scans: {n} scans of {beams} beams from {} bag(s), servo from {servo} → {} (pingcal-scan v2); {before} skipped before the servo messages, {after} after",
        bags.len(),
        out.display()
    );
    Ok(())
}
