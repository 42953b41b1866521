//! A calibration's output folder holds one run's results, never a mix of two.
//!
//! **The swap.** The whole set is written into a fresh hidden folder beside the output
//! folder (`.NAME.pingcal-new-PID`), and only when every file is written is it switched in
//! with one `renameat2(RENAME_EXCHANGE)` (Linux): the two folders trade names in one step
//! that a kill cannot split, so the output folder is at every instant either the complete
//! earlier set or the complete new one. The earlier set, now under the hidden name, is then
//! removed. A full disk, an error or a kill before the switch leaves the earlier set as it
//! was (the hidden folder is removed, or, after a kill, by the next run).
//!
//! **When the folder holds more.** A user's own files, folders and symlinks in the output
//! folder (anything pingcal does not write there) are carried into the new folder before
//! the switch: files as hard links (the same files, not copies), folders made again,
//! symlinks as the same links; one the user adds while the set is written is moved over
//! after the switch. Only where that cannot be done — one of pingcal's outputs is a symlink
//! (the file behind it is replaced, the link kept), an entry is neither file, folder nor
//! link, a hard link fails (another file system mounted inside) — or where the exchange is
//! not supported (another OS, a file system without it), is the set written file by file:
//! each file beside its final name, all renamed into place once all are written,
//! `results.json` last (its presence means the run finished). A kill during those renames
//! can leave some files of each run; the swap cannot.
//!
//! **One writer.** A lock file beside the folder (`.NAME.pingcal-lock`, holding the
//! writer's process id) is created exclusively for the whole run; a second run into the
//! same folder is refused, named, while the first is alive. A lock whose process is gone
//! (a killed run) is taken over, and that run's hidden folders and `.partial` files are
//! removed.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The folders below an output folder that pingcal writes (each holding files only).
pub const FOLDERS: [&str; 4] = ["ros", "opencv", "kalibr", "overlays"];

/// The files directly in an output folder that pingcal writes.
pub const FILES: [&str; 3] = ["results.json", "report.html", "cloud.ply"];

/// `dir`'s sibling named `.NAME.<what>`.
fn sibling(dir: &Path, what: &str) -> PathBuf {
    let name = dir.file_name().unwrap_or_default().to_string_lossy();
    dir.with_file_name(format!(".{name}.{what}"))
}

/// Whether process `pid` is alive (Linux: `/proc/PID` exists; elsewhere assumed alive).
fn alive(pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        Path::new(&format!("/proc/{pid}")).exists()
    } else {
        true
    }
}

/// The output folder as the file system names it: through a symlink, the folder behind it
/// (the swap must move the folder, not the link).
pub fn real_dir(dir: &Path) -> PathBuf {
    fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf())
}

/// Why outputs could not be written: one line naming the file or folder.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A file or folder that cannot be created, written, locked or resolved.
    #[error("{}: cannot {action}: {error}", path.display())]
    Io {
        /// The file or folder the user asked for (never a temporary one).
        path: PathBuf,
        /// `create`, `write`, `lock` or `resolve`.
        action: &'static str,
        /// What the system said.
        error: std::io::Error,
    },
    /// Another pingcal process is writing into the folder.
    #[error("{}: another pingcal (process {pid}) is writing into this folder (lock {}): wait for it, or choose another --out", dir.display(), lock.display())]
    Busy {
        /// The output folder.
        dir: PathBuf,
        /// The other process.
        pid: u32,
        /// Its lock file.
        lock: PathBuf,
    },
    /// Another run took the folder's lock at the same instant.
    #[error("{}: cannot take the lock {}: another run takes it at the same time", dir.display(), lock.display())]
    Contended {
        /// The output folder.
        dir: PathBuf,
        /// The lock file.
        lock: PathBuf,
    },
    /// A chain of more than 40 symbolic links.
    #[error("{}: too many levels of symbolic links", path.display())]
    SymlinkLoop {
        /// The path given.
        path: PathBuf,
    },
    /// A path that names no file (`/`, `..`).
    #[error("{}: not a file name", path.display())]
    NotAFileName {
        /// The path given.
        path: PathBuf,
    },
    /// results.json could not be serialised.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

impl OutputError {
    /// The [`OutputError::Io`] of `action` on `path`.
    fn io(path: &Path, action: &'static str, error: std::io::Error) -> OutputError {
        OutputError::Io {
            path: path.to_path_buf(),
            action,
            error,
        }
    }
}

/// The lock of an output folder, held for a whole run; released when dropped. Writing a
/// result set takes one ([`write_set`]), so a set is never
/// written into a folder another run holds.
#[derive(Debug)]
pub struct FolderLock {
    path: PathBuf,
    dir: PathBuf,
}

impl FolderLock {
    /// Takes the lock of output folder `dir`, or says which process holds it. A stale lock
    /// (its process gone) is taken over and the killed run's leftovers removed.
    pub fn take(given: &Path) -> Result<FolderLock, OutputError> {
        if let Some(parent) = given.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent).map_err(|e| OutputError::io(parent, "create", e))?;
        }
        let dir = real_dir(given);
        let path = sibling(&dir, "pingcal-lock");
        for _ in 0..2 {
            match create_with_pid(&path) {
                Ok(()) => {
                    remove_leftovers(&dir);
                    return Ok(FolderLock {
                        path,
                        dir: given.to_path_buf(),
                    });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let pid = fs::read_to_string(&path)
                        .ok()
                        .and_then(|s| s.trim().parse::<u32>().ok());
                    match pid {
                        Some(pid) if alive(pid) => {
                            return Err(OutputError::Busy {
                                dir,
                                pid,
                                lock: path,
                            })
                        }
                        // a lock without a process number, seconds old: one being taken
                        // this instant where hard links are not supported
                        None if just_made(&path) => break,
                        // a killed run's lock: the second attempt takes it
                        _ => {
                            let _ = fs::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(OutputError::io(&path, "lock", e)),
            }
        }
        Err(OutputError::Contended { dir, lock: path })
    }
}

/// Creates the lock file `path` holding this process's number, or fails with
/// `AlreadyExists`. The number is written to a private file first and linked in (a hard link
/// is made whole or not at all), so a second run never reads a lock still empty and takes
/// it for a killed run's; where the file system has no hard links, the lock is created and
/// then written.
fn create_with_pid(path: &Path) -> std::io::Result<()> {
    static TAKEN: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let pid = std::process::id();
    let n = TAKEN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let private = path.with_file_name(format!(
        "{}-{pid}-{n}",
        path.file_name().unwrap_or_default().to_string_lossy()
    ));
    fs::write(&private, pid.to_string())?;
    let linked = fs::hard_link(&private, path);
    let _ = fs::remove_file(&private);
    match linked {
        Err(e) if e.kind() != std::io::ErrorKind::AlreadyExists => {
            let mut f = fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(path)?;
            write!(f, "{pid}")
        }
        other => other,
    }
}

/// Whether file `path` was modified in the last five seconds.
fn just_made(path: &Path) -> bool {
    fs::metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|age| age.as_secs_f64() < 5.0)
}

impl FolderLock {
    /// The output folder it locks, as the user named it.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let _ = fs::remove_file(&self.path);
    }
}

/// Removes what a killed run left beside and in `dir`: its hidden new and old folders
/// (`.NAME.pingcal-new-PID`, `.NAME.pingcal-old-PID` of processes that are gone) and the
/// `.X.partial` files of the file-by-file way.
fn remove_leftovers(dir: &Path) {
    let name = dir
        .file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned();
    if let Some(Ok(entries)) = dir.parent().map(fs::read_dir) {
        for e in entries.flatten() {
            let f = e.file_name().to_string_lossy().into_owned();
            for kind in ["pingcal-new-", "pingcal-old-", "pingcal-lock-"] {
                let prefix = format!(".{name}.{kind}");
                let pid = f
                    .strip_prefix(&prefix)
                    .and_then(|p| p.split('-').next().and_then(|p| p.parse::<u32>().ok()));
                if pid.is_some_and(|p| !alive(p)) {
                    let _ = fs::remove_dir_all(e.path());
                    let _ = fs::remove_file(e.path());
                }
            }
        }
    }
    let sub = FOLDERS.iter().map(|f| dir.join(f));
    for d in std::iter::once(dir.to_path_buf()).chain(sub) {
        let Ok(entries) = fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let f = e.file_name().to_string_lossy().into_owned();
            if f.starts_with('.') && f.ends_with(".partial") {
                let _ = fs::remove_file(e.path());
            }
        }
    }
}

/// Whether `name`, a file in pingcal's folder `folder` (one of [`FOLDERS`]), is of a kind
/// pingcal writes there: an image's overlay (`overlays/*.png`), or an export's name
/// (`ros/`, `opencv/`, `kalibr/`, [`pingcal_pipeline::exports`]). Anything else there is a
/// user's file.
fn written_by_pingcal(folder: &str, name: &str) -> bool {
    match folder {
        "overlays" => name.ends_with(".png"),
        "ros" => {
            name.starts_with("camera_info_") && name.ends_with(".yaml")
                || name.ends_with(".urdf")
                || name.ends_with(".launch")
                || name.ends_with(".launch.py")
                || name.ends_with("_static_transform_publisher.sh")
        }
        "opencv" => name.ends_with(".yaml"),
        "kalibr" => name == "camchain.yaml",
        _ => false,
    }
}

/// Whether `dir` holds only what pingcal writes there: [`FILES`] as regular files and
/// [`FOLDERS`] holding regular files of the kinds pingcal writes there
/// ([`written_by_pingcal`]), no symlinks.
fn only_ours(dir: &Path) -> bool {
    let Ok(entries) = fs::read_dir(dir) else {
        return false;
    };
    entries.flatten().all(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        let Ok(t) = e.file_type() else {
            return false;
        };
        if FILES.contains(&name.as_str()) {
            return t.is_file();
        }
        FOLDERS.contains(&name.as_str())
            && t.is_dir()
            && fs::read_dir(e.path()).is_ok_and(|inner| {
                inner.flatten().all(|f| {
                    f.file_type().is_ok_and(|t| t.is_file())
                        && written_by_pingcal(&name, &f.file_name().to_string_lossy())
                })
            })
    })
}

/// Whether the entry `name` of output folder `dir` (`folder`: the pingcal folder it is in,
/// if any) is one of pingcal's outputs.
fn is_output(folder: Option<&str>, name: &str) -> bool {
    match folder {
        None => FILES.contains(&name) || FOLDERS.contains(&name),
        Some(f) => written_by_pingcal(f, name),
    }
}

/// Carries the user's entries of output folder `dir` into the new folder `new` (see the
/// module doc); `Ok(false)` where that cannot be done.
fn carry_users(dir: &Path, new: &Path) -> std::io::Result<bool> {
    for e in fs::read_dir(dir)? {
        let e = e?;
        let name = e.file_name().to_string_lossy().into_owned();
        let t = e.file_type()?;
        if FILES.contains(&name.as_str()) {
            if !t.is_file() {
                return Ok(false);
            }
        } else if FOLDERS.contains(&name.as_str()) {
            if !t.is_dir() {
                return Ok(false);
            }
            for f in fs::read_dir(e.path())? {
                let f = f?;
                let ft = f.file_type()?;
                if is_output(Some(&name), &f.file_name().to_string_lossy()) {
                    if !ft.is_file() {
                        return Ok(false);
                    }
                } else if !mirror(&f.path(), &new.join(&name).join(f.file_name()), ft)? {
                    return Ok(false);
                }
            }
        } else if !mirror(&e.path(), &new.join(&name), t)? {
            return Ok(false);
        }
    }
    Ok(true)
}

/// `from` made again at `to`: a file as a hard link, a folder with its permissions and
/// contents, a symlink as the same link; `Ok(false)` for anything else, or a file that
/// cannot be linked.
fn mirror(from: &Path, to: &Path, t: fs::FileType) -> std::io::Result<bool> {
    if let Some(p) = to.parent() {
        fs::create_dir_all(p)?;
    }
    if t.is_symlink() {
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(fs::read_link(from)?, to)?;
            return Ok(true);
        }
        #[cfg(not(unix))]
        return Ok(false);
    }
    if t.is_file() {
        return Ok(fs::hard_link(from, to).is_ok());
    }
    if t.is_dir() {
        fs::create_dir_all(to)?;
        fs::set_permissions(to, fs::metadata(from)?.permissions())?;
        for e in fs::read_dir(from)? {
            let e = e?;
            if !mirror(&e.path(), &to.join(e.file_name()), e.file_type()?)? {
                return Ok(false);
            }
        }
        return Ok(true);
    }
    Ok(false)
}

/// Moves the user's entries of the earlier folder `old` that are not in the output folder
/// `dir` after the switch (added while the new set was written) into it.
fn rescue_users(old: &Path, dir: &Path) {
    let top = std::iter::once((None, old.to_path_buf(), dir.to_path_buf()));
    let sub = FOLDERS.iter().map(|f| (Some(*f), old.join(f), dir.join(f)));
    for (folder, from, to) in top.chain(sub) {
        let Ok(entries) = fs::read_dir(&from) else {
            continue;
        };
        for e in entries.flatten() {
            let name = e.file_name();
            let target = to.join(&name);
            if !is_output(folder, &name.to_string_lossy()) && fs::symlink_metadata(&target).is_err()
            {
                let _ = fs::create_dir_all(&to);
                let _ = fs::rename(e.path(), &target);
            }
        }
    }
}

/// The set of `files` written into the locked output folder: swapped in as one
/// ([`swap_in`]), or where the swap does not apply, file by file (see the module doc); an
/// error leaves the earlier set as it was.
pub fn write_set(lock: &FolderLock, files: &[SetFile]) -> Result<(), OutputError> {
    let dir = lock.dir();
    fs::create_dir_all(dir).map_err(|e| OutputError::io(dir, "create", e))?;
    if swap_in(dir, files)? {
        return Ok(());
    }
    let mut paths: Vec<(PathBuf, &[u8])> =
        files.iter().map(|(rel, b)| (dir.join(rel), *b)).collect();
    // Through symlinks, the file behind them is replaced and the link stays a link.
    for (path, _) in &mut paths {
        if let WriteTarget::Replace(t) = write_target(path)? {
            *path = t;
        }
    }
    let partial = |p: &Path| {
        let name = p.file_name().unwrap_or_default().to_string_lossy();
        p.with_file_name(format!(".{name}.partial"))
    };
    for (k, (path, bytes)) in paths.iter().enumerate() {
        if let Err(e) = write_file(&partial(path), bytes) {
            for (p, _) in &paths[..=k] {
                let _ = fs::remove_file(partial(p));
            }
            return Err(OutputError::io(path, "write", e));
        }
    }
    for (path, _) in &paths {
        fs::rename(partial(path), path).map_err(|e| OutputError::io(path, "write", e))?;
    }
    remove_stale_overlays(dir, files);
    Ok(())
}

/// Removes the PNGs of `dir/overlays/` that the set `files` does not have: those of images
/// an earlier run had and this one has not, which would otherwise pass for this run's.
fn remove_stale_overlays(dir: &Path, files: &[SetFile]) {
    let ours: std::collections::BTreeSet<PathBuf> =
        files.iter().map(|(rel, _)| dir.join(rel)).collect();
    let Ok(entries) = fs::read_dir(dir.join("overlays")) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        let is_png = path.extension().is_some_and(|x| x == "png");
        if is_png && e.file_type().is_ok_and(|t| t.is_file()) && !ours.contains(&path) {
            let _ = fs::remove_file(&path);
        }
    }
}

/// Exchanges the names of `a` and `b` in one step (Linux `renameat2` with
/// `RENAME_EXCHANGE`). `Err` where it is not supported.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| {
        CString::new(p.as_os_str().as_bytes())
            .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))
    };
    let (ca, cb) = (c(a)?, c(b)?);
    // SAFETY: two valid NUL-terminated paths, relative to the working directory.
    let r = unsafe {
        libc::syscall(
            libc::SYS_renameat2,
            libc::AT_FDCWD,
            ca.as_ptr(),
            libc::AT_FDCWD,
            cb.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}

/// One file of a result set: its path below the output folder and its bytes.
pub type SetFile<'a> = (PathBuf, &'a [u8]);

/// Writes `bytes` to `path` (its folder created), executable when it is a script.
fn write_file(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent)?;
    }
    fs::write(path, bytes)?;
    #[cfg(unix)]
    if path.extension().is_some_and(|x| x == "sh") {
        use std::os::unix::fs::PermissionsExt;
        fs::set_permissions(path, fs::Permissions::from_mode(0o755))?;
    }
    Ok(())
}

/// Writes the result set `files` as output folder `dir` by the swap (see the module doc).
/// `Ok(false)`: the swap does not apply here (the folder holds more, or the system cannot
/// exchange), nothing was changed; the caller writes file by file.
pub fn swap_in(dir: &Path, files: &[SetFile]) -> Result<bool, OutputError> {
    let dir = real_dir(dir);
    let carry = dir.exists() && !only_ours(&dir);
    let new = sibling(&dir, &format!("pingcal-new-{}", std::process::id()));
    let _ = fs::remove_dir_all(&new);
    let cleanup = |e: OutputError| {
        let _ = fs::remove_dir_all(&new);
        e
    };
    if fs::create_dir_all(&new).is_err() {
        // the folder's parent is not writable: the file-by-file way needs only the folder
        let _ = fs::remove_dir_all(&new);
        return Ok(false);
    }
    if let Ok(m) = fs::metadata(&dir) {
        let _ = fs::set_permissions(&new, m.permissions());
    }
    for (rel, bytes) in files {
        write_file(&new.join(rel), bytes)
            .map_err(|e| cleanup(OutputError::io(&dir.join(rel), "write", e)))?;
    }
    if carry && !carry_users(&dir, &new).unwrap_or(false) {
        let _ = fs::remove_dir_all(&new);
        return Ok(false);
    }
    if !dir.exists() {
        return fs::rename(&new, &dir)
            .map(|()| true)
            .map_err(|e| cleanup(OutputError::io(&dir, "write", e)));
    }
    match exchange(&new, &dir) {
        Ok(()) => {
            // `new` now holds the earlier set, and the user's entries as they were before
            // the switch: one added meanwhile is moved over
            if carry {
                rescue_users(&new, &dir);
            }
            let _ = fs::remove_dir_all(&new);
            Ok(true)
        }
        Err(_) => {
            let _ = fs::remove_dir_all(&new);
            Ok(false)
        }
    }
}

/// Writes the outputs of a calibration into `dir`, all or none: `ros/`, `opencv/` and
/// `kalibr/` ([`crate::exports`]), `overlays/`, `cloud.ply`, `report.html` and
/// `results.json`, as one set ([`write_set`]): written beside the folder and
/// swapped in with one exchange of names, so that the folder is always either the earlier
/// set or the new one, under the folder's lock (a second writer is refused). A run that
/// fails before or while writing leaves the outputs of an earlier run as they were. `lock`:
/// the folder's, taken before the run began (a second run into it is refused before any
/// work).
pub fn write_outcome(
    lock: &FolderLock,
    outcome: &crate::outcome::Outcome,
) -> Result<(), OutputError> {
    let mut owned: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut shared: Vec<(PathBuf, &[u8])> = Vec::new();
    outcome_files(outcome, Path::new(""), &mut owned, &mut shared)?;
    for other in &outcome.range_sensors {
        if let Ok(o) = &other.outcome {
            let below = PathBuf::from("lrfs").join(&other.id);
            outcome_files(o, &below, &mut owned, &mut shared)?;
        }
    }
    let mut set: Vec<SetFile> = shared;
    set.extend(owned.iter().map(|(p, b)| (p.clone(), b.as_slice())));
    write_set(lock, &set)
}

/// The files of `outcome` below `below`: the exports, overlays and `cloud.ply` borrowed
/// into `shared`, `report.html` and `results.json` made into `owned`.
fn outcome_files<'a>(
    outcome: &'a crate::outcome::Outcome,
    below: &Path,
    owned: &mut Vec<(PathBuf, Vec<u8>)>,
    shared: &mut Vec<(PathBuf, &'a [u8])>,
) -> Result<(), OutputError> {
    let json = serde_json::to_string_pretty(&outcome.results)? + "\n";
    let html = pingcal_report::render_html(&outcome.report);
    push_files(below, (&outcome.exports, &outcome.overlays), shared);
    shared.push((below.join("cloud.ply"), &outcome.cloud_ply));
    owned.push((below.join("report.html"), html.into_bytes()));
    owned.push((below.join("results.json"), json.into_bytes()));
    Ok(())
}

/// The exports (`ros/`, `opencv/`, `kalibr/`) and the overlays of a run below `below`.
fn push_files<'a>(
    below: &Path,
    (exports, overlays): (&'a [crate::exports::OutputFile], &'a [(String, Vec<u8>)]),
    set: &mut Vec<SetFile<'a>>,
) {
    for (rel, text) in exports {
        set.push((below.join(rel), text.as_bytes()));
    }
    for (rel, bytes) in overlays {
        set.push((below.join(rel), bytes.as_slice()));
    }
}

/// Writes the outputs of a one-camera, one-range-sensor run (`pingcal sphere-calib`, a
/// board project) into `lock`'s folder, all or none ([`write_set`]): its exports, overlays,
/// `report.html` and `results.json` (the text `json`).
pub fn write_outputs(
    lock: &FolderLock,
    out: &crate::sphere_calib::outputs::Outputs,
    json: &str,
) -> Result<(), OutputError> {
    let mut set: Vec<SetFile> = Vec::new();
    push_files(Path::new(""), (&out.exports, &out.overlays), &mut set);
    set.push(("report.html".into(), out.report_html.as_bytes()));
    set.push(("results.json".into(), json.as_bytes()));
    write_set(lock, &set)
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename),
/// so that an interrupted run never leaves a partial output file looking complete.
///
/// Through symlinks: the file behind the links is replaced (the temporary file beside it)
/// and the link stays a link; a device or FIFO behind `path` (`/dev/stdout`) is written
/// straight, with no temporary file ([`write_target`]).
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> Result<(), OutputError> {
    let cannot = |e| OutputError::io(path, "write", e);
    let target = match write_target(path)? {
        WriteTarget::Direct(p) => {
            use std::io::Write;
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .open(&p)
                .map_err(cannot)?;
            return f.write_all(bytes).map_err(cannot);
        }
        WriteTarget::Replace(p) => p,
    };
    let tmp = partial_path(&target)?;
    // The error names the file the user asked for, not the temporary one.
    std::fs::write(&tmp, bytes).map_err(cannot)?;
    if let Err(e) = std::fs::rename(&tmp, &target) {
        let _ = std::fs::remove_file(&tmp);
        return Err(cannot(e));
    }
    Ok(())
}

/// Where a write to a path lands.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WriteTarget {
    /// A regular file, or none yet: replace this path (the end of any symlink chain) by a
    /// temporary file renamed onto it.
    Replace(std::path::PathBuf),
    /// Not a regular file (a device such as `/dev/stdout`, a FIFO): write straight into it.
    Direct(std::path::PathBuf),
}

/// The file a write to `path` must replace, following symlinks (also dangling ones, whose
/// target is created), or [`WriteTarget::Direct`] when `path` leads to something that is not
/// a regular file nor a folder.
pub fn write_target(path: &std::path::Path) -> Result<WriteTarget, OutputError> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => {
            let t = std::fs::canonicalize(path).map_err(|e| OutputError::io(path, "resolve", e))?;
            return Ok(WriteTarget::Replace(t));
        }
        Ok(m) if !m.is_dir() => return Ok(WriteTarget::Direct(path.to_path_buf())),
        _ => {}
    }
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let t = std::fs::read_link(&p).map_err(|e| OutputError::io(path, "resolve", e))?;
                p = match p.parent() {
                    Some(d) if t.is_relative() => d.join(t),
                    _ => t,
                };
            }
            _ => return Ok(WriteTarget::Replace(p)),
        }
    }
    Err(OutputError::SymlinkLoop {
        path: path.to_path_buf(),
    })
}

/// The temporary file [`write_atomic`] (and a streaming writer) writes `path` through:
/// `.NAME.partial` in the same folder, renamed onto `path` once complete.
pub fn partial_path(path: &std::path::Path) -> Result<std::path::PathBuf, OutputError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let name = path.file_name().ok_or_else(|| OutputError::NotAFileName {
        path: path.to_path_buf(),
    })?;
    Ok(dir.join(format!(".{}.partial", name.to_string_lossy())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// The result set named `which` (`A` the earlier run's, `B` the new one's): the same
    /// outputs with other bytes, and overlays of other images.
    fn set(which: &str) -> Vec<(PathBuf, Vec<u8>)> {
        let overlays: &[&str] = if which == "A" {
            &["S00_left", "S01_left"]
        } else {
            &["S00_left", "S02_left"]
        };
        let mut v: Vec<(PathBuf, Vec<u8>)> = [
            "ros/camera_info_left.yaml",
            "ros/lrf_static_transform_publisher.sh",
            "opencv/left.yaml",
            "kalibr/camchain.yaml",
            "cloud.ply",
            "report.html",
            "results.json",
        ]
        .iter()
        .map(|f| (PathBuf::from(f), format!("{which}: {f}").into_bytes()))
        .collect();
        for o in overlays {
            let f = format!("overlays/{o}.png");
            v.insert(0, (PathBuf::from(&f), format!("{which}: {f}").into_bytes()));
        }
        v
    }

    fn write(dir: &Path, which: &str) {
        let files = set(which);
        let refs: Vec<SetFile> = files.iter().map(|(p, b)| (p.clone(), &b[..])).collect();
        let lock = FolderLock::take(dir).unwrap();
        write_set(&lock, &refs).unwrap();
    }

    /// pingcal's outputs in `dir`, path → bytes (the user's entries left out).
    fn outputs(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
        let mut m = BTreeMap::new();
        for e in fs::read_dir(dir).unwrap().flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if FILES.contains(&name.as_str()) {
                m.insert(PathBuf::from(&name), fs::read(e.path()).unwrap());
            } else if FOLDERS.contains(&name.as_str()) {
                for f in fs::read_dir(e.path()).unwrap().flatten() {
                    let fname = f.file_name().to_string_lossy().into_owned();
                    if written_by_pingcal(&name, &fname) {
                        m.insert(Path::new(&name).join(&fname), fs::read(f.path()).unwrap());
                    }
                }
            }
        }
        m
    }

    fn as_map(which: &str) -> BTreeMap<PathBuf, Vec<u8>> {
        set(which).into_iter().collect()
    }

    /// The user's entries of the test: a file, a file in `ros/`, a folder with a file and a
    /// symlink; their state, to compare before and after.
    fn users(dir: &Path, make: bool) -> Vec<(String, String)> {
        let entries = [
            ("notes.txt", "my notes"),
            ("ros/my_robot.xacro", "<robot/>"),
            ("mine/deep/data.csv", "1,2,3"),
        ];
        if make {
            for (rel, text) in entries {
                write_file(&dir.join(rel), text.as_bytes()).unwrap();
            }
            #[cfg(unix)]
            std::os::unix::fs::symlink("notes.txt", dir.join("latest")).unwrap();
        }
        let mut state: Vec<(String, String)> = entries
            .iter()
            .map(|(rel, _)| {
                let text =
                    fs::read_to_string(dir.join(rel)).unwrap_or_else(|e| format!("missing: {e}"));
                (rel.to_string(), text)
            })
            .collect();
        state.push((
            "latest".into(),
            fs::read_link(dir.join("latest")).map_or("missing".into(), |l| l.display().to_string()),
        ));
        state
    }

    /// Not a test of its own: the write that `a_kill_at_any_step_of_the_write_leaves_one_whole_set`
    /// runs in a child process under strace (set `B` into `PINGCAL_KILL_TEST_DIR`).
    #[test]
    #[ignore = "run by a_kill_at_any_step_of_the_write_leaves_one_whole_set"]
    fn one_write_for_the_kill_test() {
        if let Ok(dir) = std::env::var("PINGCAL_KILL_TEST_DIR") {
            write(Path::new(&dir), "B");
        }
    }

    /// Issue 39, "a result folder is one run's": the new set's write is killed (SIGKILL,
    /// injected by strace) at each of its renames, links and unlinks in turn, into a folder
    /// holding the earlier set, with and without a user's own entries. After every kill
    /// the folder holds, file by file, the whole earlier set or the whole new one, and the
    /// user's entries as they were; the next run clears the killed run's leftovers and
    /// writes the whole new set.
    #[test]
    fn a_kill_at_any_step_of_the_write_leaves_one_whole_set() {
        let usable = std::process::Command::new("strace")
            .args(["-qq", "-o", "/dev/null", "true"])
            .status()
            .is_ok_and(|s| s.success());
        if !usable {
            println!("skipped: strace is not installed or cannot trace here (ptrace refused)");
            return;
        }
        let exe = std::env::current_exe().unwrap();
        let root = std::env::temp_dir().join(format!("pingcal-kill-{}", std::process::id()));
        let (a, b) = (as_map("A"), as_map("B"));
        let mut kills = BTreeMap::new();
        for with_users in [false, true] {
            for group in [
                "rename,renameat,renameat2",
                "link,linkat",
                "unlink,unlinkat,rmdir",
            ] {
                for k in 1.. {
                    let _ = fs::remove_dir_all(&root);
                    let dir = root.join("out");
                    write(&dir, "A");
                    let before = users(&dir, with_users);
                    let inject = format!("inject={group}:signal=KILL:when={k}");
                    let status = std::process::Command::new("strace")
                        .args(["-f", "-qq", "-o", "/dev/null", "-e"])
                        .arg(format!("trace={group}"))
                        .args(["-e", &inject])
                        .arg(&exe)
                        .args([
                            "--exact",
                            "result_set::tests::one_write_for_the_kill_test",
                            "--ignored",
                            "--test-threads=1",
                        ])
                        .env("PINGCAL_KILL_TEST_DIR", &dir)
                        .stdout(std::process::Stdio::null())
                        .stderr(std::process::Stdio::null())
                        .status()
                        .unwrap();
                    let now = outputs(&dir);
                    assert!(
                        now == a || now == b,
                        "killed at {group} #{k} (users: {with_users}): a mix of two sets: {:?}",
                        now.iter()
                            .map(|(p, v)| (p, String::from_utf8_lossy(v)))
                            .collect::<Vec<_>>()
                    );
                    if with_users {
                        assert_eq!(
                            users(&dir, false),
                            before,
                            "killed at {group} #{k}: the user's entries changed"
                        );
                    }
                    write(&dir, "B");
                    assert_eq!(outputs(&dir), b, "the run after a kill at {group} #{k}");
                    let left: Vec<String> = fs::read_dir(&root)
                        .unwrap()
                        .flatten()
                        .map(|e| e.file_name().to_string_lossy().into_owned())
                        .filter(|n| n != "out")
                        .collect();
                    assert!(
                        left.is_empty(),
                        "left after a kill at {group} #{k}: {left:?}"
                    );
                    if with_users {
                        assert_eq!(users(&dir, false), before);
                    }
                    if status.success() {
                        // the write passed every call of the group: all were tried
                        kills.insert((with_users, group), k - 1);
                        break;
                    }
                    assert!(k < 200, "{group}: the write never finished under strace");
                }
            }
        }
        let _ = fs::remove_dir_all(&root);
        println!("kill points tried (with the user's entries, syscalls): {kills:?}");
        assert!(kills.values().sum::<usize>() >= 4, "{kills:?}");
    }

    /// Sixteen takers of one folder's lock at once: exactly one holds it, every other is
    /// refused naming the holder's process; none reads a lock still being written as a
    /// killed run's (the race the end-to-end test of two runs at once met on CI).
    #[test]
    fn of_takers_at_once_exactly_one_holds_the_lock() {
        let base = std::env::temp_dir().join(format!("pingcal-lock-race-{}", std::process::id()));
        let _ = fs::remove_dir_all(&base);
        fs::create_dir_all(&base).unwrap();
        for round in 0..20 {
            let dir = base.join(format!("out{round}"));
            let barrier = std::sync::Barrier::new(16);
            let results: Vec<Result<FolderLock, OutputError>> = std::thread::scope(|s| {
                let takers: Vec<_> = (0..16)
                    .map(|_| {
                        s.spawn(|| {
                            barrier.wait();
                            FolderLock::take(&dir)
                        })
                    })
                    .collect();
                takers.into_iter().map(|t| t.join().unwrap()).collect()
            });
            let held = results.iter().filter(|r| r.is_ok()).count();
            assert_eq!(held, 1, "round {round}: {held} takers hold the lock");
            for e in results.iter().filter_map(|r| r.as_ref().err()) {
                assert!(
                    matches!(e, OutputError::Busy { pid, .. } if *pid == std::process::id()),
                    "round {round}: {e}"
                );
            }
        }
        let left: Vec<_> = fs::read_dir(&base)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|f| f.contains("pingcal-lock"))
            .collect();
        assert!(left.is_empty(), "lock files left: {left:?}");
        fs::remove_dir_all(&base).unwrap();
    }

    /// A killed run's lock (a process that is gone) is taken over; a lock file without a
    /// process number made this instant is one being taken, and is refused.
    #[test]
    fn a_killed_runs_lock_is_taken_over_and_one_being_made_is_not() {
        let base = std::env::temp_dir().join(format!("pingcal-lock-stale-{}", std::process::id()));
        let _ = fs::remove_dir_all(&base);
        fs::create_dir_all(&base).unwrap();
        let dir = base.join("out");
        let lock = base.join(".out.pingcal-lock");
        // no Linux process has a number this high (pid_max is at most 2^22)
        fs::write(&lock, "4294967295").unwrap();
        fs::write(base.join(".out.pingcal-lock-4294967295-0"), "4294967295").unwrap();
        let taken = FolderLock::take(&dir).unwrap();
        assert_eq!(
            fs::read_to_string(&lock).unwrap(),
            std::process::id().to_string()
        );
        assert!(!base.join(".out.pingcal-lock-4294967295-0").exists());
        drop(taken);
        assert!(!lock.exists());
        fs::write(&lock, "").unwrap();
        let e = FolderLock::take(&dir).unwrap_err();
        assert!(matches!(e, OutputError::Contended { .. }), "{e}");
        assert!(e
            .to_string()
            .contains("another run takes it at the same time"));
        fs::remove_dir_all(&base).unwrap();
    }

    #[test]
    fn a_users_file_among_the_outputs_stops_the_swap() {
        let root = std::env::temp_dir().join(format!("pingcal-result-set-{}", std::process::id()));
        let dir = root.join("out");
        let _ = fs::remove_dir_all(&root);
        for (rel, mine) in [
            ("results.json", false),
            ("overlays/S00_left.png", false),
            ("ros/camera_info_left.yaml", false),
            ("ros/lrf_model_ros2.launch.py", false),
            ("kalibr/camchain.yaml", false),
            ("overlays/notes.txt", true),
            ("ros/my_robot.xacro", true),
            ("kalibr/imu.yaml", true),
        ] {
            write_file(&dir.join(rel), b"x").unwrap();
            assert_eq!(only_ours(&dir), !mine, "{rel}");
            if mine {
                fs::remove_file(dir.join(rel)).unwrap();
            }
        }
        let _ = fs::remove_dir_all(&root);
    }

    /// A failed write names the file asked for, never the temporary `.partial` one.
    #[test]
    fn a_failed_write_names_the_target_not_the_temporary_file() {
        let path = std::path::Path::new("/nonexistent-pingcal-dir/results.json");
        let e = super::write_atomic(path, b"{}").unwrap_err().to_string();
        assert!(
            e.starts_with("/nonexistent-pingcal-dir/results.json: cannot write")
                && !e.contains("partial"),
            "{e}"
        );
    }

    /// A symlink to a file in another folder stays a link; the file behind it gets the
    /// bytes; a dangling link gets its target created.
    #[cfg(unix)]
    #[test]
    fn a_write_through_a_symlink_keeps_the_link() {
        let d = std::env::temp_dir().join(format!("pingcal-symlink-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(d.join("a")).unwrap();
        std::fs::create_dir_all(d.join("b")).unwrap();
        std::fs::write(d.join("b/real.txt"), b"old").unwrap();
        std::os::unix::fs::symlink("../b/real.txt", d.join("a/link.txt")).unwrap();
        super::write_atomic(&d.join("a/link.txt"), b"new").unwrap();
        let m = std::fs::symlink_metadata(d.join("a/link.txt")).unwrap();
        assert!(m.file_type().is_symlink());
        assert_eq!(std::fs::read(d.join("b/real.txt")).unwrap(), b"new");
        std::os::unix::fs::symlink(d.join("b/new.txt"), d.join("a/dangling.txt")).unwrap();
        super::write_atomic(&d.join("a/dangling.txt"), b"x").unwrap();
        assert!(std::fs::symlink_metadata(d.join("a/dangling.txt"))
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(d.join("b/new.txt")).unwrap(), b"x");
        let mut left: Vec<_> = std::fs::read_dir(d.join("b"))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        assert_eq!(left, ["new.txt", "real.txt"]);
        let _ = std::fs::remove_dir_all(&d);
    }
}
