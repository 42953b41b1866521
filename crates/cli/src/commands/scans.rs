//! `pingcal scans BAG... --scan-topic T --servo-topic T [--servo-joint NAME | --servo-scale S
//! --servo-offset O | --servo-tf-child F --servo-axis x,y,z] [--servo-motion auto|stop-and-go|continuous] [--stamps auto|header|record]
//! --out scans.csv`: the LRF's scans read from ROS 1 bags and ROS 2 bags (MCAP, sqlite3, or
//! a bag folder) in one pass, as drivers publish them (empty scans, no-return ranges,
//! messages stored twice, stamps that repeat or go back: counted in the summary), the servo
//! angle held (stop-and-go) or interpolated at each beam's time (continuous), written as
//! `pingcal-scan` v2 CSV (one servo angle at the first and one at the last beam of each
//! scan), v3 when the scans carry intensities. `pingcal scans BAG... --list` prints each
//! bag's topics, types and message counts, and the joints of JointState topics and the
//! frames of tf topics. `pingcal scans BAG... --scan-topic T --fixed --out S00.csv` reads a
//! fixed LRF's scans (no servo: every scan at servo 0), one file per station of the head.
//!
//! A driver may change the beam geometry (count, first angle, step) between messages: no
//! scan is dropped or resampled for it; every scan goes to `--out` in its own geometry, the
//! file then `pingcal-scan` v4 (a `# geometry` line where the geometry changes): one bag, one
//! file. Whose time the messages are taken at (`--stamps`: header stamps or record times) is
//! chosen as `pingcal_rosbag::clock` says, and printed with the reason.
//!
//! The output is written to `.NAME.partial` beside it and renamed when complete, as the
//! other commands write theirs: a failed run leaves an earlier file untouched.

use super::CmdResult;
use pingcal_lrf::scan::{ScanHeader, ScanLine, ScanWriter, VERSION_DIGIT_OFFSET};
use pingcal_lrf::settings::{KeyStyle, ServoKeys};
use pingcal_rosbag::assemble::{
    names_on_topic, read_fixed_scans, read_scans, ServoMotion, ServoSource, Stamps, Topics,
};
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
    #[arg(long, required_unless_present_any = ["list", "fixed"])]
    pub servo_topic: Option<String>,
    /// A fixed LRF (`[lrf] kind = "fixed"`): no servo topic; every scan is written at servo
    /// 0 (record one bag per station of the head and list each file with its station).
    #[arg(long, conflicts_with_all = ["servo_topic", "servo_joint", "servo_scale", "servo_offset", "servo_tf_child", "list"])]
    pub fixed: bool,
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
    /// Whose time the messages are taken at: `header` their header stamps (a topic
    /// without a header, e.g. std_msgs/Int32, has only its record times), `record` the
    /// bag's record times, `auto` the header stamps unless the two topics keep different
    /// clocks (it says which it used, and why).
    #[arg(long, default_value = "auto", value_parser = Stamps::parse)]
    pub stamps: Stamps,
    /// Only the scans from this many seconds after the first scan read on (the first a file
    /// can hold; with a servo, the first within its messages): one station of a robot that
    /// stopped at several in one recording.
    #[arg(long, value_parser = seconds)]
    pub from: Option<f64>,
    /// Only the scans up to this many seconds after the first scan read.
    #[arg(long, value_parser = seconds)]
    pub to: Option<f64>,
    /// The scan file to write (`pingcal-scan` v2 CSV; v3 with intensities, v4 when the beam
    /// geometry changes between scans).
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

/// The scan file being written: a temporary one renamed when complete.
struct ScanFile {
    /// The path named on the output.
    path: PathBuf,
    /// The file written: a temporary one, or a device or FIFO written straight.
    tmp: PathBuf,
    /// What `tmp` is renamed onto once complete (the file behind any symlink); None when
    /// written straight.
    target: Option<PathBuf>,
    /// The first scan's beams, first angle and version (2, or 3 with intensities).
    beams: usize,
    angle_min_deg: f64,
    version: u8,
    writer: ScanWriter<std::io::BufWriter<std::fs::File>>,
}

impl ScanFile {
    /// Starts the file with the geometry of its first scan, `line`.
    fn create(
        header: &ScanHeader,
        line: &ScanLine,
        path: &Path,
        extra: &str,
    ) -> Result<Self, String> {
        super::preflight::check_out_file("--out", path)?;
        // through symlinks the file behind them is replaced; a device or FIFO is written
        // straight
        let (tmp, target) = match super::write_target(path).map_err(|e| e.to_string())? {
            super::WriteTarget::Direct(p) => (p, None),
            super::WriteTarget::Replace(t) => {
                (super::partial_path(&t).map_err(|e| e.to_string())?, Some(t))
            }
        };
        let cannot = |e: std::io::Error| format!("{}: cannot write: {e}", path.display());
        let file = std::fs::File::create(&tmp).map_err(cannot)?;
        let w = std::io::BufWriter::with_capacity(1 << 16, file);
        let beams = line.ranges_mm.len();
        let intensities = !line.intensities.is_empty();
        let writer = if intensities {
            ScanWriter::new_v3(w, header, beams, &[extra])
        } else {
            ScanWriter::new_v2(w, header, beams, &[extra])
        }
        .map_err(cannot)?;
        Ok(Self {
            path: path.to_path_buf(),
            tmp,
            target,
            beams,
            angle_min_deg: header.angle_min_deg,
            version: if intensities { 3 } else { 2 },
            writer,
        })
    }

    /// Writes one scan in its own geometry (a `# geometry` line where it changes: the
    /// file becomes v4); a device or FIFO written straight cannot be made v4 afterwards and
    /// is refused then.
    fn write(&mut self, header: &ScanHeader, line: &ScanLine) -> Result<(), String> {
        let cannot = |e: std::io::Error| format!("{}: cannot write: {e}", self.path.display());
        let before = self.writer.needs_v4();
        self.writer.write_line_in(header, line).map_err(cannot)?;
        if !before && self.writer.needs_v4() && self.target.is_none() {
            return Err(format!(
                "{}: the beam geometry changes at scan message {}: the file must be pingcal-scan v4, which a device or pipe written straight cannot be made afterwards; write to a file",
                self.path.display(),
                line.line
            ));
        }
        Ok(())
    }

    /// The version the file has: v4 when scans of several geometries were written.
    fn version(&self) -> u8 {
        if self.writer.needs_v4() {
            4
        } else {
            self.version
        }
    }

    /// Completes the file (v4 put in its first line where needed); gives (temporary file,
    /// its target) when it is to be renamed.
    fn finish(self) -> Result<Option<(PathBuf, PathBuf)>, String> {
        use std::io::{Seek, SeekFrom, Write};
        let cannot = |e: std::io::Error| format!("{}: cannot write: {e}", self.path.display());
        let v4 = self.writer.needs_v4();
        let w = self.writer.finish().map_err(cannot)?;
        let mut file = w.into_inner().map_err(|e| cannot(e.into_error()))?;
        match self.target {
            Some(t) => {
                if v4 {
                    file.seek(SeekFrom::Start(VERSION_DIGIT_OFFSET))
                        .and_then(|_| file.write_all(b"4"))
                        .map_err(cannot)?;
                }
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

/// What [`write_scans`] wrote: the file, its scans, version, the first scan's beams and
/// first angle, and what the reading met.
struct Written {
    path: PathBuf,
    scans: u64,
    version: u8,
    beams: usize,
    angle_min_deg: f64,
    done: pingcal_rosbag::assemble::Assembled,
}

/// Writes the scans of `bags` to `out`'s temporary file, every scan in its own beam
/// geometry (a driver may change it between messages: the file is then v4), and renames it
/// once complete; removes it on a failure.
/// A `--from` / `--to` value: seconds, finite and not negative.
fn seconds(v: &str) -> Result<f64, String> {
    match v.parse::<f64>() {
        Ok(s) if s.is_finite() && s >= 0.0 => Ok(s),
        _ => Err(format!(
            "expected seconds after the first scan (0 or more), found {v:?}"
        )),
    }
}

/// How the scans are read: with a servo topic, or a fixed LRF's.
enum Reading {
    /// A rotating LRF: the topics and how the servo moves.
    Servo(Topics, ServoMotion),
    /// A fixed LRF: its scan topic, and whose time the messages are taken at.
    Fixed(String, Stamps),
}

fn write_scans(
    bags: &[Bag],
    reading: &Reading,
    window: [Option<f64>; 2],
    out: &Path,
) -> Result<Written, super::CmdError> {
    let names: Vec<&str> = bags.iter().map(Bag::name).collect();
    let (scan_topic, servo) = match reading {
        Reading::Servo(t, _) => (t.scan.as_str(), t.servo.as_str()),
        Reading::Fixed(scan, _) => (scan.as_str(), "none: a fixed LRF"),
    };
    let extra = format!(
        "source=pingcal scans {} (scans {scan_topic}, servo {servo})",
        names.join(" "),
    );
    let mut file: Option<ScanFile> = None;
    let mut scans = 0u64;
    let io = |msg: String| pingcal_rosbag::RosbagError::Io {
        file: out.display().to_string(),
        msg,
    };
    let (mut first, mut span) = (None::<f64>, 0.0f64);
    let mut write = |h: &ScanHeader, line: ScanLine| {
        // the window, in seconds after the first scan given
        let after = line.stamp_s - *first.get_or_insert(line.stamp_s);
        span = span.max(after);
        if window[0].is_some_and(|a| after < a) || window[1].is_some_and(|b| after > b) {
            return Ok(());
        }
        let f = match &mut file {
            Some(f) => f,
            None => file.insert(ScanFile::create(h, &line, out, &extra).map_err(io)?),
        };
        scans += 1;
        f.write(h, &line).map_err(io)
    };
    let result = match reading {
        Reading::Servo(topics, motion) => read_scans(bags, topics, *motion, &mut write),
        Reading::Fixed(scan, stamps) => read_fixed_scans(bags, scan, *stamps, &mut write),
    };
    // the temporary file, removed on any failure from here on
    let partial = file
        .as_ref()
        .and_then(|f| f.partial().map(Path::to_path_buf));
    let cleanup = |e: super::CmdError| {
        if let Some(p) = &partial {
            let _ = std::fs::remove_file(p);
        }
        e
    };
    let done = result.map_err(|e| cleanup(e.into()))?;
    if file.is_none() && first.is_some() {
        return Err(format!(
            "{}: topic {scan_topic}: no scan between --from and --to: the scans span 0 to {span:.3} s after the first",
            names.join(", ")
        )
        .into());
    }
    if file.is_none() && matches!(reading, Reading::Fixed(..)) {
        return Err(format!(
            "{}: topic {scan_topic}: no scan with a beam ({} empty)",
            names.join(", "),
            done.empty_scans
        )
        .into());
    }
    let Some(f) = file else {
        let skipped: Vec<String> = done
            .notes()
            .into_iter()
            .filter_map(|n| n.strip_prefix("warning: ").map(str::to_string))
            .collect();
        return Err(format!(
            "{}: topic {}: no scan lies within the servo messages ({} before the first, {} after the last, {} empty){}",
            names.join(", "),
            scan_topic,
            done.before_servo,
            done.after_servo,
            done.empty_scans,
            if skipped.is_empty() { String::new() } else { format!("; {}", skipped.join("; ")) }
        )
        .into());
    };
    let (path, version, beams, angle_min_deg) =
        (f.path.clone(), f.version(), f.beams, f.angle_min_deg);
    if let Some((tmp, target)) = f.finish().map_err(|e| cleanup(e.into()))? {
        std::fs::rename(&tmp, &target)
            .map_err(|e| cleanup(format!("{}: cannot write: {e}", target.display()).into()))?;
    }
    Ok(Written {
        path,
        scans,
        version,
        beams,
        angle_min_deg,
        done,
    })
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    let bags = open_bags(&args.bags)?;
    if args.list {
        return list(&bags);
    }
    let (Some(scan), Some(out)) = (&args.scan_topic, &args.out) else {
        return Err("--scan-topic and --out are needed (or --list)".into());
    };
    let servo = match (&args.servo_topic, args.fixed) {
        (Some(servo), _) => Some(servo),
        (None, true) => None,
        (None, false) => {
            return Err("--servo-topic is needed (or --fixed for a fixed LRF)".into());
        }
    };
    super::preflight::check_out_file("--out", out)?;
    check_not_an_input(out, &args.bags)?;
    let reading = match servo {
        Some(servo) => Reading::Servo(
            Topics {
                scan: scan.clone(),
                servo: servo.clone(),
                source: source(&args)?,
                stamps: args.stamps,
            },
            args.servo_motion,
        ),
        None => Reading::Fixed(scan.clone(), args.stamps),
    };
    if let (Some(a), Some(b)) = (args.from, args.to) {
        if b < a {
            return Err(format!("--to {b} is before --from {a}").into());
        }
    }
    let w = write_scans(&bags, &reading, [args.from, args.to], out)?;
    let done = &w.done;
    let from = match servo {
        Some(servo) => format!("servo from {servo}"),
        None => "a fixed LRF: servo 0".into(),
    };
    let skipped = match servo {
        Some(_) => format!(
            "{} skipped before the servo messages, {} after, ",
            done.before_servo, done.after_servo
        ),
        None => String::new(),
    };
    println!(
        "scans: {} scans of {} beams from {} bag(s), {from} → {} (pingcal-scan v{}); {skipped}{} empty, {} duplicate(s), {} ranges masked",
        w.scans,
        w.beams,
        bags.len(),
        w.path.display(),
        w.version,
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
    if w.version == 4 {
        println!(
            "scans: one file for every beam geometry (pingcal-scan v4: a `# geometry` line where it changes; the first scan's {} beams from {}°)",
            w.beams, w.angle_min_deg
        );
    }
    Ok(())
}
