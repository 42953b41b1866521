//! Checks every command makes before any work, so that a run that cannot finish says so at
//! once instead of after minutes of computing: the output folder can be created and
//! written, the thread count is sane, a list of ids names each id once.
//!
//! Each check returns one line naming the option or path and what was expected.

use std::path::Path;

/// The most worker threads any command accepts (`--threads`); 0 means all cores.
pub const MAX_THREADS: usize = 1024;

/// `--threads N`: 0 (all cores) to [`MAX_THREADS`].
pub fn check_threads(n: usize) -> Result<(), String> {
    if n > MAX_THREADS {
        return Err(format!(
            "--threads {n}: expected 0 (all cores) to {MAX_THREADS}"
        ));
    }
    Ok(())
}

/// Creates `dir` (and its parents) and writes and removes a probe file in it, so that an
/// output folder that cannot be written is refused before the work that would fill it.
pub fn check_out_dir(dir: &Path) -> Result<(), String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!(
            "{}: cannot write the results there: it is a file, not a folder",
            dir.display()
        ));
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{}: cannot create the output folder: {e}", dir.display()))?;
    let probe = dir.join(format!(".pingcal-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| {
        format!(
            "{}: cannot write into the output folder: {e}",
            dir.display()
        )
    })?;
    std::fs::remove_file(&probe).map_err(|e| {
        format!(
            "{}: cannot remove a file from the output folder: {e}",
            dir.display()
        )
    })
}

/// An output file `path`: not a folder, and its folder writable (see [`check_out_dir`]).
pub fn check_out_file(option: &str, path: &Path) -> Result<(), String> {
    if path.is_dir() {
        return Err(format!(
            "{option} {}: is a folder, expected a file name",
            path.display()
        ));
    }
    // Through symlinks the temporary file goes beside the file behind them; a device or
    // FIFO (`/dev/stdout`) is written straight, with nothing to check.
    let target = match super::write_target(path).map_err(|e| format!("{option} {e}"))? {
        super::WriteTarget::Direct(_) => return Ok(()),
        super::WriteTarget::Replace(t) => t,
    };
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    check_out_dir(dir).map_err(|e| format!("{option} {}: {e}", path.display()))
}

/// Refuses an id given twice in the list of `option`, naming it.
pub fn check_unique<T: PartialEq + std::fmt::Display>(
    option: &str,
    ids: &[T],
) -> Result<(), String> {
    for (k, id) in ids.iter().enumerate() {
        if ids[..k].contains(id) {
            return Err(format!("{option}: '{id}' is given twice"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An output "folder" that is a file, or under /proc, is refused naming the path.
    #[test]
    fn unwritable_output_folders_are_refused_naming_them() {
        let tmp = std::env::temp_dir().join(format!("pingcal-preflight-{}", std::process::id()));
        std::fs::create_dir_all(&tmp).unwrap();
        let file = tmp.join("a_file");
        std::fs::write(&file, b"x").unwrap();
        let e = check_out_dir(&file).unwrap_err();
        assert!(e.contains("a_file") && e.contains("not a folder"), "{e}");
        let e = check_out_dir(&file.join("sub")).unwrap_err();
        assert!(
            e.contains("a_file/sub") && e.contains("cannot create"),
            "{e}"
        );
        if Path::new("/proc/self").exists() {
            let e = check_out_dir(Path::new("/proc/x")).unwrap_err();
            assert!(e.starts_with("/proc/x: cannot create"), "{e}");
        }
        let ok = tmp.join("new/deeper");
        check_out_dir(&ok).unwrap();
        assert_eq!(
            std::fs::read_dir(&ok).unwrap().count(),
            0,
            "the probe is removed"
        );
        let e = check_out_file("--out", &tmp).unwrap_err();
        assert!(e.contains("--out") && e.contains("is a folder"), "{e}");
        std::fs::remove_dir_all(&tmp).unwrap();
    }

    #[test]
    fn threads_and_duplicates() {
        assert!(check_threads(0).is_ok() && check_threads(MAX_THREADS).is_ok());
        let e = check_threads(100_000).unwrap_err();
        assert_eq!(e, "--threads 100000: expected 0 (all cores) to 1024");
        let e = check_unique("--check", &["B1", "B4", "B1"]).unwrap_err();
        assert_eq!(e, "--check: 'B1' is given twice");
        assert!(check_unique("--check", &["B1", "B4"]).is_ok());
    }
}
