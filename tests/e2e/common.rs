//! Helpers of the end-to-end tests: the simulated project (made once per test binary), a
//! private copy of it per test, running the binary with a time limit, the checks every
//! failed run must pass, and a hand-written PNG encoder (the `image` crate is not a
//! dependency of this package).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Seed of the simulated project every test starts from.
pub const SEED: u64 = 3;

/// Longest a single run of the binary may take before the test fails (a hang is a bug).
const RUN_LIMIT: Duration = Duration::from_secs(180);

/// The binary under test.
pub fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_pingcal")
}

/// `$TMP/pingcal-e2e-<pid>`: everything this test binary writes.
pub fn root() -> &'static Path {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(|| {
        let tmp = std::env::temp_dir();
        remove_dead_roots(&tmp);
        let root = tmp.join(format!("pingcal-e2e-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        fs::create_dir_all(&root).expect("create the e2e temp dir");
        root
    })
}

/// Removes the folders left by earlier runs of this test binary whose process is gone
/// (Linux only: a live process has `/proc/<pid>`; elsewhere nothing is removed).
fn remove_dead_roots(tmp: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = fs::read_dir(tmp) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = name
            .strip_prefix("pingcal-e2e-")
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = fs::remove_dir_all(e.path());
        }
    }
}

/// The pristine simulated project (`pingcal simulate --seed 3`), made on first use.
pub fn pristine() -> &'static Path {
    static PRISTINE: OnceLock<PathBuf> = OnceLock::new();
    PRISTINE.get_or_init(|| simulate_once("pristine", None))
}

/// The quick simulated project: the small field ([`SMALL_FIELD`]) of the same seed on a rig
/// whose LRF mount is exactly as the project states (`[lrf] mount_errors = false`, as
/// [`LRF_AS_STATED`]), with `method = "spheres"`: its verdict is ok without the joint
/// adjustment, and it simulates and calibrates in about a third of the pristine project's
/// time. For the tests of what a run does with its files, folders, exit codes and batches,
/// where neither the method nor the field's size matters. Made on first use.
pub fn quick_pristine() -> &'static Path {
    static QUICK: OnceLock<PathBuf> = OnceLock::new();
    QUICK.get_or_init(|| {
        let dir = simulate_once(
            "quick",
            Some(&format!("{SMALL_FIELD}mount_errors = false\n")),
        );
        two_step_method(&dir);
        dir
    })
}

/// A small field, as a `simulation.toml` gives it: five convergent stations, half the
/// rendering's supersampling, a 0.35° servo step (a quarter of the beams). The planner's and
/// σ-honesty's field and the quick project's.
pub const SMALL_FIELD: &str = "\
[stations]
convergent = 5

[render]
supersampling = 2

[lrf]
servo_step_deg = 0.3515625
";

/// The simulator configuration's `[lrf]` line of a 0.35° servo step: a quarter of the default
/// sweep's beams (the small field's), for the cases whose subject is not the LRF's precision.
pub const QUARTER_BEAMS: &str = "servo_step_deg = 0.3515625\n";

/// The simulator configuration (to append to a test's own) of an LRF mounted exactly as the
/// project states: with [`two_step_method`] the verdict is ok without the joint adjustment,
/// at about a third of its time, for the tests of what does not depend on the LRF's mount.
pub const LRF_AS_STATED: &str = "[lrf]\nmount_errors = false\n";

/// Sets the project in `dir` to the two-step method (`method = "spheres"`, where the
/// simulator writes `"all"`).
pub fn two_step_method(dir: &Path) {
    replace_once(
        &dir.join("project.toml"),
        "method = \"all\"",
        "method = \"spheres\"",
    );
}

/// `pingcal simulate --seed SEED [--config …] --out root()/NAME`, which must succeed.
fn simulate_once(name: &str, config: Option<&str>) -> PathBuf {
    let dir = root().join(name);
    let log = root().join(format!("simulate-{name}"));
    let t0 = Instant::now();
    fs::create_dir_all(&log).expect("create the simulate log dir");
    simulate_into(&dir, config, &log);
    eprintln!("simulate {name}: {:.1} s", t0.elapsed().as_secs_f64());
    for f in ["project.toml", "truth.json", "scans/S00.csv"] {
        assert!(dir.join(f).is_file(), "pingcal simulate wrote no {f}");
    }
    dir
}

/// `pingcal simulate --seed SEED [--config <log>/<name>.toml] --out OUT` (NAME: the last part
/// of OUT) with the simulator configuration `config` (TOML) and the run's output in `log`;
/// it must succeed.
fn simulate_into(out: &Path, config: Option<&str>, log: &Path) {
    let name = out.file_name().expect("a named folder").to_string_lossy();
    let cfg = log.join(format!("{name}.toml"));
    let seed = SEED.to_string();
    let mut args = vec![
        "simulate",
        "--out",
        out.to_str().expect("UTF-8 path"),
        "--seed",
        &seed,
    ];
    if let Some(config) = config {
        fs::write(&cfg, config).expect("write the simulator configuration");
        args.extend(["--config", cfg.to_str().expect("UTF-8 path")]);
    }
    let run = run(&args, log);
    assert!(
        run.success(),
        "pingcal simulate {name} failed ({:?}):\nstdout: {}\nstderr: {}",
        run.code,
        run.stdout,
        run.stderr
    );
}

/// The pristine project's calibration, run once per test binary (`pingcal calibrate
/// project.toml --out out --json` in `root()/calibrated`): for the tests that only read what
/// a calibration of the simulated field writes. Its folders must not be written to.
pub struct Calibration {
    /// The project's folder (a copy of the pristine one).
    pub project: PathBuf,
    /// The output folder.
    pub out: PathBuf,
    /// The run.
    pub run: Run,
}

/// The shared [`Calibration`], made on first use; it must have succeeded.
pub fn calibration() -> &'static Calibration {
    static CALIBRATION: OnceLock<Calibration> = OnceLock::new();
    CALIBRATION.get_or_init(|| {
        let dir = root().join("calibrated");
        let project = dir.join("project");
        copy_dir(pristine(), &project);
        let out = dir.join("out");
        let toml = project.join("project.toml");
        let args = [
            "calibrate",
            toml.to_str().expect("UTF-8 path"),
            "--out",
            out.to_str().expect("UTF-8 path"),
            "--json",
        ];
        let run = run(&args, &dir);
        assert!(
            run.success(),
            "the shared calibration failed ({:?}):\nstdout: {}\nstderr: {}",
            run.code,
            run.stdout,
            run.stderr
        );
        Calibration { project, out, run }
    })
}

/// Copies the folder `src` into `dst` (created), recursively.
pub fn copy_dir(src: &Path, dst: &Path) {
    fs::create_dir_all(dst).unwrap_or_else(|e| panic!("create {}: {e}", dst.display()));
    for e in fs::read_dir(src).unwrap_or_else(|e| panic!("read {}: {e}", src.display())) {
        let e = e.expect("directory entry");
        let to = dst.join(e.file_name());
        if e.file_type().expect("file type").is_dir() {
            copy_dir(&e.path(), &to);
        } else {
            fs::copy(e.path(), &to).unwrap_or_else(|err| {
                panic!("copy {} → {}: {err}", e.path().display(), to.display())
            });
        }
    }
}

/// One test's folder: its own copy of the simulated project and an output folder. Removed
/// when the test passes, kept (for a look) when it fails.
pub struct Work {
    /// `root()/<name>`.
    pub dir: PathBuf,
    /// When the test started (its time is printed when it ends).
    start: Instant,
}

impl Work {
    /// A fresh folder `root()/<name>` (names must differ between tests).
    pub fn new(name: &str) -> Self {
        let dir = root().join(name);
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("create the test dir");
        Work {
            dir,
            start: Instant::now(),
        }
    }

    /// A copy of the pristine project in `<dir>/<sub>`; returns that folder.
    pub fn project(&self, sub: &str) -> PathBuf {
        let p = self.dir.join(sub);
        copy_dir(pristine(), &p);
        p
    }

    /// A copy of the quick project ([`quick_pristine`]) in `<dir>/<sub>`; returns that
    /// folder.
    pub fn quick_project(&self, sub: &str) -> PathBuf {
        let p = self.dir.join(sub);
        copy_dir(quick_pristine(), &p);
        p
    }

    /// `pingcal calibrate PROJECT/project.toml --out DIR/out --quiet EXTRA…`: the run and
    /// the output folder.
    pub fn calibrate(&self, project: &Path, extra: &[&str]) -> (Run, PathBuf) {
        let out = self.dir.join("out");
        let toml = project.join("project.toml");
        let mut args = vec![
            "calibrate",
            toml.to_str().expect("UTF-8 path"),
            "--out",
            out.to_str().expect("UTF-8 path"),
            "--quiet",
        ];
        args.extend_from_slice(extra);
        (self.run(&args), out)
    }

    /// Runs `pingcal calibrate PROJECT/project.toml --out DIR/out --quiet --json`, which must
    /// fail cleanly naming every needle (see [`assert_clean_failure`]), with a JSON line whose
    /// `error` is the error line's message and whose `error_kind` is `kind` (`input`, `data`
    /// or `adjustment`); returns the error line.
    pub fn calibrate_fails(&self, project: &Path, kind: &str, needles: &[&str]) -> String {
        let (run, out) = self.calibrate(project, &["--json"]);
        let err = assert_clean_failure(&run, &out, needles);
        let lines = run.json_lines();
        assert_eq!(lines.len(), 1, "one JSON line: {}", run.stdout);
        let l = &lines[0];
        assert_eq!(l["verdict"], "error", "{l}");
        assert_eq!(l["error_kind"], kind, "{l}\n{err}");
        let message = l["error"].as_str().expect("error");
        assert!(err.ends_with(message), "{l}\n{err}");
        err
    }

    /// `pingcal simulate --seed SEED --config <config> --out <dir>/<name>` with the simulator
    /// configuration `config` (TOML), which must succeed; returns the project's folder.
    pub fn simulate(&self, name: &str, config: &str) -> PathBuf {
        let out = self.dir.join(name);
        simulate_into(&out, Some(config), &self.dir);
        out
    }

    /// `pingcal ARGS` with stdout and stderr captured in files of this folder.
    pub fn run(&self, args: &[&str]) -> Run {
        run(args, &self.dir)
    }
}

impl Drop for Work {
    fn drop(&mut self) {
        eprintln!(
            "{}: {:.1} s",
            self.dir.display(),
            self.start.elapsed().as_secs_f64()
        );
        if !std::thread::panicking() {
            let _ = fs::remove_dir_all(&self.dir);
        }
    }
}

/// What a run of the binary did.
#[derive(Debug)]
pub struct Run {
    /// Exit code (None: killed by a signal).
    pub code: Option<i32>,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
    /// Wall time.
    pub secs: f64,
}

impl Run {
    /// Exit code 0.
    pub fn success(&self) -> bool {
        self.code == Some(0)
    }

    /// The JSON lines of a `--json` run's stdout.
    pub fn json_lines(&self) -> Vec<serde_json::Value> {
        (self.stdout.lines())
            .filter(|l| !l.trim().is_empty())
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
            .collect()
    }

    /// A calibration that wrote its results, whatever its verdict: the exit code is the
    /// verdict's (0 ok, 3 doubtful, 4 failed; docs/batch.md). Checked against `results`'
    /// `verdict.status`.
    pub fn calibrated(&self, results: &Path) -> bool {
        let Some(expected) = (match self.code {
            Some(0) => Some("ok"),
            Some(3) => Some("doubtful"),
            Some(4) => Some("failed"),
            _ => None,
        }) else {
            return false;
        };
        let status = read_json(results)["verdict"]["status"].clone();
        assert_eq!(
            status,
            expected,
            "exit code {:?} against the verdict in {}",
            self.code,
            results.display()
        );
        true
    }
}

/// Runs `pingcal ARGS`; stdout and stderr go to files in `dir` (no pipe to fill up), and a
/// run longer than [`RUN_LIMIT`] is killed and fails the test.
pub fn run(args: &[&str], dir: &Path) -> Run {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let (out_path, err_path) = (
        dir.join(format!("run{n}.stdout")),
        dir.join(format!("run{n}.stderr")),
    );
    let t0 = Instant::now();
    let mut child = Command::new(bin())
        .args(args)
        .stdin(Stdio::null())
        .stdout(fs::File::create(&out_path).expect("stdout file"))
        .stderr(fs::File::create(&err_path).expect("stderr file"))
        .spawn()
        .expect("start pingcal");
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait for pingcal") {
            break s;
        }
        if t0.elapsed() > RUN_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            panic!("pingcal {args:?} still running after {RUN_LIMIT:?}: killed");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let secs = t0.elapsed().as_secs_f64();
    let read = |p: &Path| String::from_utf8_lossy(&fs::read(p).unwrap_or_default()).into_owned();
    Run {
        code: status.code(),
        stdout: read(&out_path),
        stderr: read(&err_path),
        secs,
    }
}

/// The outputs of a calibration of the simulated (stereo) project, `results.json` first.
pub const OUTPUTS: [&str; 18] = [
    "results.json",
    "report.html",
    "cloud.ply",
    "ros/ros1_static_transform_publisher.sh",
    "ros/ros2_static_transform_publisher.sh",
    "ros/static_transform_ros1.launch",
    "ros/static_transform_ros2.launch.py",
    "ros/laser_joint.urdf",
    "ros/camera_info_left.yaml",
    "ros/camera_info_right.yaml",
    "ros/lrf_model.urdf",
    "ros/lrf_model_ros1.launch",
    "ros/lrf_model_ros2.launch.py",
    "opencv/camera_left.yaml",
    "opencv/camera_right.yaml",
    "opencv/stereo.yaml",
    "kalibr/camchain.yaml",
    "overlays/S00_left.png",
];

/// Checks a run that must fail cleanly: non-zero exit, exactly one stderr line starting
/// `pingcal: error: ` that contains every one of `needles`, no panic, and none of the
/// outputs in `out`. Returns the error line.
pub fn assert_clean_failure(run: &Run, out: &Path, needles: &[&str]) -> String {
    let ctx = format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        run.code, run.stdout, run.stderr
    );
    assert!(
        !run.success() && run.code.is_some(),
        "expected a non-zero exit code: {ctx}"
    );
    assert!(
        !run.stderr.contains("panicked") && !run.stdout.contains("panicked"),
        "pingcal panicked: {ctx}"
    );
    // warnings about earlier steps may come first; the error is one line, the last
    let lines: Vec<&str> = (run.stderr.trim().lines())
        .filter(|l| !(l.starts_with("pingcal: ") && l.contains(": warning: ")))
        .collect();
    assert_eq!(lines.len(), 1, "expected one error line on stderr: {ctx}");
    let err = lines[0];
    assert!(
        run.stderr.trim().ends_with(err),
        "the error line must be the last: {ctx}"
    );
    assert!(
        err.starts_with("pingcal: error: "),
        "the error line must start with `pingcal: error: `: {ctx}"
    );
    for n in needles {
        assert!(err.contains(n), "the error does not name {n:?}: {ctx}");
    }
    for f in OUTPUTS {
        assert!(
            !out.join(f).exists(),
            "a failed run left {} behind: {ctx}",
            out.join(f).display()
        );
    }
    err.to_string()
}

/// Replaces the one occurrence of `from` in `file` by `to` (fails if there is not exactly
/// one).
pub fn replace_once(file: &Path, from: &str, to: &str) {
    let text = fs::read_to_string(file).expect("read the file to edit");
    assert_eq!(
        text.matches(from).count(),
        1,
        "{from:?} must occur once in {}",
        file.display()
    );
    fs::write(file, text.replacen(from, to, 1)).expect("write the edited file");
}

/// A parsed JSON file.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = fs::read_to_string(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: not JSON: {e}", path.display()))
}

/// A valid 8-bit grayscale PNG of `width`×`height` (a horizontal ramp), written by hand:
/// signature, IHDR, one IDAT holding a zlib stream of stored (uncompressed) deflate
/// blocks, IEND.
pub fn gray_png(width: u32, height: u32) -> Vec<u8> {
    // the raw image: each row is filter byte 0 (none) followed by the pixels
    let mut raw = Vec::with_capacity((height * (width + 1)) as usize);
    for _ in 0..height {
        raw.push(0);
        raw.extend((0..width).map(|x| (x % 256) as u8));
    }
    // zlib: CMF/FLG (deflate, 32 K window, no dictionary, FCHECK so that it is a
    // multiple of 31), stored blocks of at most 65535 bytes, Adler-32 of the raw data
    let mut z = vec![0x78, 0x01];
    let chunks: Vec<&[u8]> = raw.chunks(65535).collect();
    for (k, c) in chunks.iter().enumerate() {
        z.push((k + 1 == chunks.len()) as u8); // BFINAL, BTYPE = 00
        let len = c.len() as u16;
        z.extend(len.to_le_bytes());
        z.extend((!len).to_le_bytes());
        z.extend_from_slice(c);
    }
    z.extend(adler32(&raw).to_be_bytes());

    let mut ihdr = Vec::new();
    ihdr.extend(width.to_be_bytes());
    ihdr.extend(height.to_be_bytes());
    ihdr.extend([8, 0, 0, 0, 0]); // bit depth 8, grayscale, deflate, filter 0, no interlace

    let mut png = vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];
    for (kind, data) in [(b"IHDR", &ihdr[..]), (b"IDAT", &z[..]), (b"IEND", &[][..])] {
        png.extend((data.len() as u32).to_be_bytes());
        let start = png.len();
        png.extend_from_slice(kind);
        png.extend_from_slice(data);
        let crc = crc32(&png[start..]); // over the chunk type and data
        png.extend(crc.to_be_bytes());
    }
    png
}

/// CRC-32 (IEEE 802.3, reflected, as PNG uses it), bit by bit: fast enough for a test.
pub fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in data {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// An uncompressed little-endian grey `w` × `h` TIFF: its nine tags, then its one strip at
/// byte `strip` (the strip's bytes `k mod modulo`; a `strip` other than the tags' end points
/// past or into them).
pub fn grey_tiff(w: u32, h: u32, strip: u32, modulo: u32) -> Vec<u8> {
    let entries: [(u16, u16, u32); 9] = [
        (256, 3, w),
        (257, 3, h),
        (258, 3, 8),
        (259, 3, 1),
        (262, 3, 1),
        (273, 4, strip),
        (277, 3, 1),
        (278, 3, h),
        (279, 4, w * h),
    ];
    let mut t = b"II*\0".to_vec();
    t.extend_from_slice(&8u32.to_le_bytes());
    t.extend_from_slice(&9u16.to_le_bytes());
    for (tag, ty, v) in entries {
        t.extend_from_slice(&tag.to_le_bytes());
        t.extend_from_slice(&ty.to_le_bytes());
        t.extend_from_slice(&1u32.to_le_bytes());
        t.extend_from_slice(&v.to_le_bytes());
    }
    t.extend_from_slice(&0u32.to_le_bytes());
    t.extend((0..w * h).map(|k| (k % modulo) as u8));
    t
}

/// Adler-32 (RFC 1950).
pub fn adler32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (1u32, 0u32);
    for &x in data {
        a = (a + x as u32) % 65521;
        b = (b + a) % 65521;
    }
    (b << 16) | a
}
