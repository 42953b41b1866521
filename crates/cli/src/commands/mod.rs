//! One module per subcommand. Each exposes `Args` (clap) and `run(Args) -> CmdResult`.

pub mod ba;
pub mod calibrate;
pub mod cloud;
pub mod demo;
pub mod detect;
pub mod frames;
pub mod gen_bal;
pub mod lrf_mount;
pub mod plan;
pub mod preflight;
pub mod progress;
pub mod register;
pub mod result_set;
pub mod scans;
pub mod simulate;
pub mod sphere_calib;
pub mod targets;

/// The error every command returns: printed by `main` as one line.
pub type CmdError = Box<dyn std::error::Error + Send + Sync>;
/// The result every command returns.
pub type CmdResult = Result<(), CmdError>;

/// A command's end with an exit code of its own (not the 1 of every other error): `main`
/// prints `pingcal: MESSAGE` (nothing when the message is empty) and exits with `code`.
/// `pingcal calibrate` ends so when its verdict is doubtful (3) or failed (4).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exit {
    /// The process's exit code.
    pub code: i32,
    /// One line for stderr (empty: none).
    pub message: String,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} (exit {})", self.message, self.code)
    }
}

impl std::error::Error for Exit {}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename),
/// so that an interrupted run never leaves a partial output file looking complete.
///
/// Through symlinks: the file behind the links is replaced (the temporary file beside it)
/// and the link stays a link; a device or FIFO behind `path` (`/dev/stdout`) is written
/// straight, with no temporary file ([`write_target`]).
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> CmdResult {
    let cannot = |e: std::io::Error| format!("{}: cannot write: {e}", path.display());
    let target = match write_target(path)? {
        WriteTarget::Direct(p) => {
            use std::io::Write;
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .open(&p)
                .map_err(cannot)?;
            return f.write_all(bytes).map_err(|e| cannot(e).into());
        }
        WriteTarget::Replace(p) => p,
    };
    let tmp = partial_path(&target)?;
    // The error names the file the user asked for, not the temporary one.
    std::fs::write(&tmp, bytes).map_err(cannot)?;
    if let Err(e) = std::fs::rename(&tmp, &target) {
        let _ = std::fs::remove_file(&tmp);
        return Err(cannot(e).into());
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
pub fn write_target(path: &std::path::Path) -> Result<WriteTarget, CmdError> {
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => {
            let t = std::fs::canonicalize(path)
                .map_err(|e| format!("{}: cannot resolve: {e}", path.display()))?;
            return Ok(WriteTarget::Replace(t));
        }
        Ok(m) if !m.is_dir() => return Ok(WriteTarget::Direct(path.to_path_buf())),
        _ => {}
    }
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let t = std::fs::read_link(&p)
                    .map_err(|e| format!("{}: cannot resolve: {e}", path.display()))?;
                p = match p.parent() {
                    Some(d) if t.is_relative() => d.join(t),
                    _ => t,
                };
            }
            _ => return Ok(WriteTarget::Replace(p)),
        }
    }
    Err(format!("{}: too many levels of symbolic links", path.display()).into())
}

/// The temporary file [`write_atomic`] (and a streaming writer) writes `path` through:
/// `.NAME.partial` in the same folder, renamed onto `path` once complete.
pub fn partial_path(path: &std::path::Path) -> Result<std::path::PathBuf, CmdError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| format!("{}: not a file name", path.display()))?;
    Ok(dir.join(format!(".{}.partial", name.to_string_lossy())))
}

#[cfg(test)]
mod tests {
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
