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
//! **When the folder holds more.** If the output folder holds anything pingcal does not
//! write there (a user's file, a symlink among the outputs), it is not swapped: each file
//! is written beside its final name and renamed into place, `results.json` last (its
//! presence means the run finished), which keeps the user's files and links. The same
//! happens where the exchange is not supported (another OS, a file system without it).
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

/// The lock of an output folder, held for a whole run; released when dropped. Writing a
/// result set takes one ([`crate::commands::calibrate::write_outputs`]), so a set is never
/// written into a folder another run holds.
#[derive(Debug)]
pub struct FolderLock {
    path: PathBuf,
    dir: PathBuf,
}

impl FolderLock {
    /// Takes the lock of output folder `dir`, or says which process holds it. A stale lock
    /// (its process gone) is taken over and the killed run's leftovers removed.
    pub fn take(given: &Path) -> Result<FolderLock, String> {
        if let Some(parent) = given.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent)
                .map_err(|e| format!("{}: cannot create: {e}", parent.display()))?;
        }
        let dir = real_dir(given);
        let path = sibling(&dir, "pingcal-lock");
        for _ in 0..2 {
            match fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    let _ = write!(f, "{}", std::process::id());
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
                            return Err(format!(
                                "{}: another pingcal (process {pid}) is writing into this folder (lock {}): wait for it, or choose another --out",
                                dir.display(),
                                path.display()
                            ))
                        }
                        // a killed run's lock (or one being written this instant: the
                        // second attempt decides)
                        _ => {
                            let _ = fs::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(format!("{}: cannot lock: {e}", path.display())),
            }
        }
        Err(format!(
            "{}: cannot take the lock {}: another run takes it at the same time",
            dir.display(),
            path.display()
        ))
    }
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
            for kind in ["pingcal-new-", "pingcal-old-"] {
                let prefix = format!(".{name}.{kind}");
                let pid = f.strip_prefix(&prefix).and_then(|p| p.parse::<u32>().ok());
                if pid.is_some_and(|p| !alive(p)) {
                    let _ = fs::remove_dir_all(e.path());
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
pub fn swap_in(dir: &Path, files: &[SetFile]) -> Result<bool, String> {
    let dir = real_dir(dir);
    if dir.exists() && !only_ours(&dir) {
        return Ok(false);
    }
    let new = sibling(&dir, &format!("pingcal-new-{}", std::process::id()));
    let _ = fs::remove_dir_all(&new);
    let cleanup = |e: String| {
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
            .map_err(|e| cleanup(format!("{}: cannot write: {e}", dir.join(rel).display())))?;
    }
    if !dir.exists() {
        return fs::rename(&new, &dir)
            .map(|()| true)
            .map_err(|e| cleanup(format!("{}: cannot write: {e}", dir.display())));
    }
    match exchange(&new, &dir) {
        Ok(()) => {
            // `new` now holds the earlier set
            let _ = fs::remove_dir_all(&new);
            Ok(true)
        }
        Err(_) => {
            let _ = fs::remove_dir_all(&new);
            Ok(false)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
