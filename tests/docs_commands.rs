//! The field guide's commands run as written (issue 18, "a test that follows the README and
//! docs' commands as written, from `cargo install` to a calibration of a simulated field"):
//! the shell block of `docs/install.md`'s "Five commands" runs in bash from the repository
//! root, with `HOME` and cargo's install root in a temporary folder (cargo and rustup keep
//! their own homes, and the build reuses this workspace's target folder, so the install is a
//! copy of what the tests already built). Then its outputs are checked.
//!
//! The docs are checked against the binary and themselves too: `docs/commands.md` has a
//! section for every subcommand, naming exactly the options its `--help` lists; the README
//! opens with the two commands and stays under 150 lines; every relative link of the README
//! and of `docs/` leads to a file and a heading that exist.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The first ```sh block after the heading `heading` of a markdown text.
fn sh_block(md: &str, heading: &str) -> String {
    let at = md
        .find(heading)
        .unwrap_or_else(|| panic!("no heading {heading:?}"));
    let rest = &md[at..];
    let start = rest.find("```sh\n").expect("a sh block under the heading") + 6;
    let len = rest[start..].find("```").expect("the block ends");
    rest[start..start + len].to_string()
}

/// A home folder of the machine's (where cargo and rustup live unless told otherwise).
fn real_home(var: &str, default_sub: &str) -> Option<PathBuf> {
    std::env::var_os(var)
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(default_sub)))
}

#[test]
fn the_install_page_runs_as_written_from_cargo_install_to_a_calibration() {
    let root = workspace().canonicalize().unwrap();
    let md = std::fs::read_to_string(root.join("docs/install.md")).unwrap();
    let block = sh_block(&md, "## Five commands");
    assert!(block.contains("cargo install") && block.contains("pingcal calibrate"));
    let tmp = std::env::temp_dir().join(format!("pingcal-docs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let (home, install) = (tmp.join("home"), tmp.join("cargo-root"));
    std::fs::create_dir_all(&home).unwrap();
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    let path = format!(
        "{}:{}",
        install.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut cmd = Command::new("bash");
    cmd.args(["-euo", "pipefail", "-c", &block])
        .current_dir(&root)
        .env("HOME", &home)
        .env("CARGO_INSTALL_ROOT", &install)
        .env("CARGO_TARGET_DIR", &target)
        .env("PATH", path);
    for (var, sub) in [("CARGO_HOME", ".cargo"), ("RUSTUP_HOME", ".rustup")] {
        if let Some(h) = real_home(var, sub) {
            cmd.env(var, h);
        }
    }
    let out = cmd.output().expect("bash runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "docs/install.md's commands failed:\n{block}\n{err}"
    );
    assert!(
        install.join("bin/pingcal").is_file(),
        "cargo install installed no pingcal"
    );
    let try_dir = home.join("pingcal-try");
    let results = std::fs::read_to_string(try_dir.join("field/results/results.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&results).unwrap();
    assert!(
        v["mean_check_error_mm"].as_f64().is_some_and(|m| m < 10.0),
        "the calibration of the simulated field: {}",
        v["mean_check_error_mm"]
    );
    assert!(try_dir.join("field/results/report.html").is_file());
    let pdf = std::fs::read(try_dir.join("targets.pdf")).unwrap();
    assert!(pdf.starts_with(b"%PDF-"), "targets.pdf is a PDF");
    let _ = std::fs::remove_dir_all(&tmp);
}

/// The text of `pingcal ARGS`, which must succeed.
fn pingcal_out(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_pingcal"))
        .args(args)
        .output()
        .expect("pingcal runs");
    assert!(out.status.success(), "pingcal {args:?} failed");
    String::from_utf8(out.stdout).unwrap()
}

/// The subcommands `pingcal --help` lists (clap's own `help` left out).
fn subcommands() -> Vec<String> {
    let help = pingcal_out(&["--help"]);
    let list = help
        .split("Commands:\n")
        .nth(1)
        .expect("pingcal --help lists its commands");
    list.lines()
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}

/// The long options `pingcal COMMAND --help` lists (`--help` itself left out): an option's
/// line starts with at most six spaces, its description's lines with more.
fn help_options(command: &str) -> BTreeSet<String> {
    let help = pingcal_out(&[command, "--help"]);
    help.lines()
        .filter_map(|l| {
            let t = l.trim_start();
            let indent = l.len() - t.len();
            let t = t.strip_prefix("-h, ").unwrap_or(t);
            (indent <= 6 && t.starts_with("--")).then(|| option_at(t))
        })
        .filter(|o| o != "--help")
        .collect()
}

/// The option name (`--name`) at the start of `text`.
fn option_at(text: &str) -> String {
    let n = text[2..]
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
        .map_or(text.len(), |i| i + 2);
    text[..n].to_string()
}

/// Every `--option` in `text`.
fn options_in(text: &str) -> BTreeSet<String> {
    text.match_indices("--")
        .filter(|(i, _)| {
            let next = text[i + 2..].chars().next();
            next.is_some_and(|c| c.is_ascii_lowercase())
                && !text[..*i].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '-')
        })
        .map(|(i, _)| option_at(&text[i..]))
        .collect()
}

/// The sections of docs/commands.md, by command: the text from its heading
/// "## `pingcal COMMAND`" to the next heading of that level.
fn command_sections(md: &str) -> BTreeMap<String, String> {
    let mut sections = BTreeMap::new();
    for part in md.split("\n## ").skip(1) {
        let (head, body) = part.split_once('\n').unwrap_or((part, ""));
        if let Some(cmd) = head
            .strip_prefix("`pingcal ")
            .and_then(|h| h.strip_suffix('`'))
        {
            sections.insert(cmd.to_string(), body.to_string());
        }
    }
    sections
}

/// What a section documents: the options at the head of its bullets ("- `--out DIR`: …",
/// "- `--tilt-x-deg a`, `--tilt-z-deg b`: …"), and those of its synopsis (the ```text block).
fn documented_options(section: &str) -> (BTreeSet<String>, BTreeSet<String>) {
    let bullets = section
        .lines()
        .filter_map(|l| l.strip_prefix("- `--").map(|_| &l[2..]))
        .flat_map(|l| options_in(l.split("`: ").next().unwrap_or(l)))
        .collect();
    let synopsis = section
        .split("```text\n")
        .nth(1)
        .and_then(|s| s.split("```").next())
        .map(options_in)
        .unwrap_or_default();
    (bullets, synopsis)
}

/// docs/commands.md is the command reference: a section for every subcommand of the binary
/// and none for a command it does not have; each section's bullets name exactly the options
/// the command's `--help` lists, and its synopsis no option the command does not have.
#[test]
fn the_command_reference_documents_every_command_and_exactly_its_options() {
    let md = std::fs::read_to_string(workspace().join("docs/commands.md")).unwrap();
    let sections = command_sections(&md);
    let commands = subcommands();
    assert!(commands.len() >= 14, "pingcal --help lists {commands:?}");
    let documented: BTreeSet<&String> = sections.keys().collect();
    let existing: BTreeSet<&String> = commands.iter().collect();
    assert_eq!(
        documented, existing,
        "docs/commands.md's sections (left) against pingcal's subcommands (right)"
    );
    let mut wrong = Vec::new();
    for command in &commands {
        let help = help_options(command);
        let (bullets, synopsis) = documented_options(&sections[command]);
        for o in help.difference(&bullets) {
            wrong.push(format!("{command}: {o} is not documented"));
        }
        for o in bullets.difference(&help).chain(synopsis.difference(&help)) {
            wrong.push(format!("{command}: {o} is documented but not an option"));
        }
    }
    assert!(wrong.is_empty(), "docs/commands.md:\n{}", wrong.join("\n"));
}

/// The two commands a newcomer runs open the README, and it stays a two-minute read.
#[test]
fn the_readme_opens_with_the_two_commands_and_stays_short() {
    let readme = std::fs::read_to_string(workspace().join("README.md")).unwrap();
    let block = sh_block(&readme, "# pingcal");
    let lines: Vec<&str> = block.lines().collect();
    assert!(
        lines.len() == 2
            && lines[0].starts_with("cargo run --release -p pingcal -- demo ")
            && lines[1].starts_with("cargo test --workspace --release "),
        "the README's first block is not the two commands:\n{block}"
    );
    assert!(
        readme.starts_with("# pingcal\n\n```sh\n"),
        "the README opens with the two commands"
    );
    let n = readme.lines().count();
    assert!(n < 150, "README.md has {n} lines: move details into docs/");
}

/// A heading's anchor as GitHub makes it: lower case, letters, digits, `-` and `_` kept,
/// spaces turned into `-`, everything else dropped.
fn slug(heading: &str) -> String {
    heading
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

#[test]
fn anchors_are_githubs() {
    assert_eq!(slug("1. The verdict"), "1-the-verdict");
    assert_eq!(
        slug("The output of `pingcal detect --out FILE.json`"),
        "the-output-of-pingcal-detect---out-filejson"
    );
    assert_eq!(
        slug("In each ecosystem's files"),
        "in-each-ecosystems-files"
    );
    assert_eq!(slug("`pingcal lrf-mount`"), "pingcal-lrf-mount");
}

/// The lines of a markdown text outside its fenced code blocks.
fn prose(md: &str) -> String {
    let mut fenced = false;
    let mut out = String::new();
    for line in md.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// The anchors of a markdown file's headings (GitHub's: a repeated one gets `-1`, `-2`, …).
fn anchors(md: &str) -> BTreeSet<String> {
    let mut seen = BTreeMap::<String, usize>::new();
    let mut out = BTreeSet::new();
    for line in prose(md).lines() {
        let text = line.trim_start_matches('#');
        if text.len() < line.len() && text.starts_with(' ') {
            let s = slug(text.trim());
            let n = seen.entry(s.clone()).or_insert(0);
            out.insert(if *n == 0 {
                s.clone()
            } else {
                format!("{s}-{n}")
            });
            *n += 1;
        }
    }
    out
}

/// The targets of the markdown links and images `[text](target)` of a text outside its
/// code (fenced blocks and inline code spans).
fn link_targets(md: &str) -> Vec<String> {
    let text: String = prose(md)
        .lines()
        .map(|l| l.split('`').step_by(2).collect::<Vec<_>>().join(" "))
        .collect::<Vec<_>>()
        .join("\n");
    text.match_indices("](")
        .filter_map(|(i, _)| {
            let rest = &text[i + 2..];
            rest.find(')').map(|end| rest[..end].to_string())
        })
        .collect()
}

/// Every relative link of the README and of docs/ leads to a file that exists and, with an
/// anchor into a markdown file, to one of its headings.
#[test]
fn every_relative_link_of_the_readme_and_docs_resolves() {
    let root = workspace();
    let mut files = vec![root.join("README.md")];
    for e in std::fs::read_dir(root.join("docs")).unwrap().flatten() {
        if e.path().extension().is_some_and(|x| x == "md") {
            files.push(e.path());
        }
    }
    let mut broken = Vec::new();
    let mut checked = 0;
    for file in &files {
        let md = std::fs::read_to_string(file).unwrap();
        for target in link_targets(&md) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (path, anchor) = target.split_once('#').unwrap_or((&target, ""));
            let dest = if path.is_empty() {
                file.clone()
            } else {
                file.parent().unwrap().join(path)
            };
            checked += 1;
            let name = file.strip_prefix(&root).unwrap().display();
            if !dest.exists() {
                broken.push(format!("{name}: {target}: no such file"));
            } else if !anchor.is_empty() && dest.extension().is_some_and(|x| x == "md") {
                let text = std::fs::read_to_string(&dest).unwrap();
                if !anchors(&text).contains(anchor) {
                    broken.push(format!("{name}: {target}: no such heading"));
                }
            }
        }
    }
    assert!(
        checked > 50,
        "only {checked} links found: the link reader is broken"
    );
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}
