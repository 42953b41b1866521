//! One module per subcommand. Each exposes `Args` (clap) and `run(Args) -> CmdResult`.

pub mod ba;
pub mod calibrate;
pub mod cloud;
pub mod demo;
pub mod detect;
pub mod gen_bal;
pub mod plan;
pub mod preflight;
pub mod progress;
pub mod register;
pub mod scans;
pub mod simulate;
pub mod targets;

/// The error every command returns: printed by `main` as one line.
pub type CmdError = Box<dyn std::error::Error + Send + Sync>;
/// The result every command returns.
pub type CmdResult = Result<(), CmdError>;

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename),
/// so that an interrupted run never leaves a partial output file looking complete.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> CmdResult {
    let tmp = partial_path(path)?;
    // The error names the file the user asked for, not the temporary one.
    std::fs::write(&tmp, bytes).map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
    Ok(())
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
}
