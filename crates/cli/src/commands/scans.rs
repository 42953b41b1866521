//! `pingcal scans BAG... --scan-topic T --servo-topic T [--servo-joint NAME | --servo-scale S
//! --servo-offset O | --servo-tf-child F --servo-axis x,y,z] [--servo-motion auto|stop-and-go|continuous]
//! --out scans.csv`: the LRF's scans read from ROS 1 bags and ROS 2 bags (MCAP, sqlite3, or
//! a bag folder) in one pass, as drivers publish them (empty scans, no-return ranges,
//! messages stored twice, stamps that repeat or go back: counted in the summary), the servo
//! angle held (stop-and-go) or interpolated at each beam's time (continuous), written as
//! `pingcal-scan` v2 CSV (one servo angle at the first and one at the last beam of each
//! scan), v3 when the scans carry intensities. `pingcal scans BAG... --list` prints each
//! bag's topics, types and message counts, and the joints of JointState topics and the
//! frames of tf topics.
//!
//! A driver may change the beam geometry (count, first angle, step) between messages: no
//! scan is dropped or resampled for it; the scans of the first geometry go to `--out`, those
//! of each further one to a file of its own beside it (`scans.g2.csv`, `scans.g3.csv`, …),
//! since a `pingcal-scan` file has one geometry; the project lists them all.
//!
//! The output is written to `.NAME.partial` beside it and renamed when complete, as the
//! other commands write theirs: a failed run leaves an earlier file untouched.

use super::CmdResult;
use pingcal_lrf::scan::{ScanHeader, ScanWriter};
use pingcal_lrf::settings::{KeyStyle, ServoKeys};
use pingcal_rosbag::assemble::{names_on_topic, read_scans, ServoMotion, ServoSource, Topics};
use pingcal_rosbag::{bag_files, Bag};
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
    /// How the servo moves: `stop-and-go` holds its last angle before each scan,
    /// `continuous` interpolates it at each beam's time, `auto` tells them apart from the
    /// servo messages and says which it used.
    #[arg(long, default_value = "auto", value_parser = ServoMotion::parse)]
    pub servo_motion: ServoMotion,
    /// The scan file to write (`pingcal-scan` v2 CSV).
    #[arg(long, required_unless_present = "list")]
    pub out: Option<PathBuf>,
}

/// The bags the paths name (files, or a ROS 2 bag folder's storage files), opened.
pub(crate) fn open_bags(paths: &[PathBuf]) -> Result<Vec<Bag>, super::CmdError> {
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
            let names = names_on_topic(bag, &t.name, &t.msg_type)?;
            if !names.is_empty() {
                let what = if t.msg_type.ends_with("JointState") {
                    "joints"
                } else {
                    "frames"
                };
                println!("    {what}: {}", names.join(", "));
            }
            n += 1;
        }
    }
    println!("scans: {n} topic(s) in {} bag(s)", bags.len());
    Ok(())
}

/// The servo source the flags give ([`ServoSource::from_keys`], as a project's `[lrf.bag]`).
fn source(args: &Args) -> Result<ServoSource, String> {
    let a = &args.servo_axis;
    let &[x, y, z] = a.as_slice() else {
        return Err(format!(
            "--servo-axis: expected three numbers x,y,z, found {}",
            a.len()
        ));
    };
    let keys = ServoKeys {
        joint: args.servo_joint.as_deref(),
        scale: args.servo_scale,
        offset: args.servo_offset,
        tf_child: args.servo_tf_child.as_deref(),
        // the flag has a default: it is the axis only of a tf servo topic
        axis: args.servo_tf_child.is_some().then_some([x, y, z]),
    };
    ServoSource::from_keys(&keys, KeyStyle::Flags)
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

/// The file of the `k`-th beam geometry (from 2): `scans.csv` → `scans.g2.csv`.
fn geometry_path(out: &Path, k: usize) -> PathBuf {
    let stem = out
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let name = match out.extension() {
        Some(e) => format!("{stem}.g{k}.{}", e.to_string_lossy()),
        None => format!("{stem}.g{k}"),
    };
    out.with_file_name(name)
}

/// One output file: the scans of one beam geometry.
struct GeometryFile {
    header: ScanHeader,
    beams: usize,
    /// v3: the scans carry intensities.
    intensities: bool,
    /// The path named on the output.
    path: PathBuf,
    /// The file written: a temporary one, or a device or FIFO written straight.
    tmp: PathBuf,
    /// What `tmp` is renamed onto once complete (the file behind any symlink); None when
    /// written straight.
    target: Option<PathBuf>,
    scans: u64,
    writer: ScanWriter<std::io::BufWriter<std::fs::File>>,
}

impl GeometryFile {
    fn create(
        header: &ScanHeader,
        beams: usize,
        intensities: bool,
        path: PathBuf,
        extra: &str,
    ) -> Result<Self, String> {
        super::preflight::check_out_file("--out", &path)?;
        // through symlinks the file behind them is replaced; a device or FIFO is written
        // straight
        let (tmp, target) = match super::write_target(&path).map_err(|e| e.to_string())? {
            super::WriteTarget::Direct(p) => (p, None),
            super::WriteTarget::Replace(t) => {
                (super::partial_path(&t).map_err(|e| e.to_string())?, Some(t))
            }
        };
        let cannot = |e: std::io::Error| format!("{}: cannot write: {e}", path.display());
        let file = std::fs::File::create(&tmp).map_err(cannot)?;
        let w = std::io::BufWriter::with_capacity(1 << 16, file);
        let writer = if intensities {
            ScanWriter::new_v3(w, header, beams, &[extra])
        } else {
            ScanWriter::new_v2(w, header, beams, &[extra])
        }
        .map_err(cannot)?;
        Ok(Self {
            header: *header,
            beams,
            intensities,
            path,
            tmp,
            target,
            scans: 0,
            writer,
        })
    }

    /// Completes the file; gives (temporary file, its target) when it is to be renamed.
    fn finish(self) -> Result<Option<(PathBuf, PathBuf)>, String> {
        let cannot = |e: std::io::Error| format!("{}: cannot write: {e}", self.path.display());
        let w = self.writer.finish().map_err(cannot)?;
        let file = w.into_inner().map_err(|e| cannot(e.into_error()))?;
        match self.target {
            Some(t) => {
                file.sync_all().map_err(cannot)?;
                Ok(Some((self.tmp, t)))
            }
            None => Ok(None),
        }
    }

    /// The temporary file to remove on a failure (none when written straight).
    fn partial(&self) -> Option<&Path> {
        self.target.as_ref().map(|_| self.tmp.as_path())
    }
}

/// What [`write_scans`] wrote: per file its path, scans, beams and first angle, and what
/// the reading met.
struct Written {
    files: Vec<(PathBuf, u64, usize, f64)>,
    done: pingcal_rosbag::assemble::Assembled,
}

/// Writes the scans of `bags` to `out`'s temporary file, and the scans of every further beam
/// geometry (a driver may change it between messages) to a file of its own
/// ([`geometry_path`]); renames them all once every one is complete, and removes them on a
/// failure.
fn write_scans(
    bags: &[Bag],
    topics: &Topics,
    motion: ServoMotion,
    out: &Path,
) -> Result<Written, super::CmdError> {
    let names: Vec<&str> = bags.iter().map(Bag::name).collect();
    let extra = format!(
        "source=pingcal scans {} (scans {}, servo {})",
        names.join(" "),
        topics.scan,
        topics.servo
    );
    let mut files: Vec<GeometryFile> = Vec::new();
    let result = read_scans(bags, topics, motion, &mut |h, line| {
        let beams = line.ranges_mm.len();
        let with_i = !line.intensities.is_empty();
        let k = match files
            .iter()
            .position(|f| f.header == *h && f.beams == beams && f.intensities == with_i)
        {
            Some(k) => k,
            None => {
                let path = match files.len() {
                    0 => out.to_path_buf(),
                    n => geometry_path(out, n + 1),
                };
                let f = GeometryFile::create(h, beams, with_i, path, &extra).map_err(|msg| {
                    pingcal_rosbag::RosbagError::Io {
                        file: out.display().to_string(),
                        msg,
                    }
                })?;
                files.push(f);
                files.len() - 1
            }
        };
        let f = &mut files[k];
        f.scans += 1;
        f.writer
            .write_line(&line)
            .map_err(|e| pingcal_rosbag::RosbagError::Io {
                file: f.path.display().to_string(),
                msg: format!("cannot write: {e}"),
            })
    });
    // every temporary file, removed on any failure from here on
    let partials: Vec<PathBuf> = files
        .iter()
        .filter_map(|f| f.partial().map(Path::to_path_buf))
        .collect();
    let cleanup = |e: super::CmdError| {
        for p in &partials {
            let _ = std::fs::remove_file(p);
        }
        e
    };
    let done = result.map_err(|e| cleanup(e.into()))?;
    if files.is_empty() {
        return Err(format!(
            "{}: topic {}: no scan lies within the servo messages ({} before the first, {} after the last, {} empty)",
            names.join(", "), topics.scan, done.before_servo, done.after_servo, done.empty_scans
        )
        .into());
    }
    let summary: Vec<_> = files
        .iter()
        .map(|f| (f.path.clone(), f.scans, f.beams, f.header.angle_min_deg))
        .collect();
    let mut finished = Vec::new();
    for f in files {
        finished.extend(f.finish().map_err(|e| cleanup(e.into()))?);
    }
    for (tmp, target) in finished {
        std::fs::rename(&tmp, &target)
            .map_err(|e| cleanup(format!("{}: cannot write: {e}", target.display()).into()))?;
    }
    Ok(Written {
        files: summary,
        done,
    })
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
    let Written { files, done } = write_scans(&bags, &topics, args.servo_motion, out)?;
    let Some((first, more)) = files.split_first() else {
        return Err(format!("topic {scan}: no scan written").into());
    };
    println!(
        "scans: {} scans of {} beams from {} bag(s), servo from {servo} → {} (pingcal-scan v{}); {} skipped before the servo messages, {} after, {} empty, {} duplicate(s), {} ranges masked",
        first.1,
        first.2,
        bags.len(),
        first.0.display(),
        if done.with_intensities > 0 { 3 } else { 2 },
        done.before_servo,
        done.after_servo,
        done.empty_scans,
        done.duplicate_scans,
        done.masked.total()
    );
    for note in done.notes() {
        match note.strip_prefix("warning: ") {
            Some(w) => eprintln!("pingcal: warning: topic {scan}: {w}"),
            None => println!("scans: {note}"),
        }
    }
    if !more.is_empty() {
        eprintln!(
            "pingcal: warning: topic {scan}: the beam geometry changes between scans; the scans of each other geometry are in a file of their own (list them all in [lrf] scans):"
        );
        for (path, n, beams, a0) in more {
            println!(
                "scans: {n} scans of {beams} beams from {a0}° → {}",
                path.display()
            );
        }
    }
    Ok(())
}
