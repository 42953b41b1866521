//! The shape of the code, checked from its sources (issue 12):
//!
//! - no module cycles in library code: in every crate, at every level, the modules that
//!   share a parent refer to each other (through `crate::…`, `super::…`, `self::…` paths)
//!   without a cycle — so each module can be read after the ones it uses;
//! - the crates depend on each other one way: the libraries never on the binary's crate,
//!   `geometry` and `camera` on no other pingcal crate, `ba` only on those two, the LRF, target and
//!   project crates never on the simulator (the project's reader builds the LRF's settings
//!   with the LRF crate's types), and the bag reader (`rosbag`) only on `lrf`
//!   (and what it builds on);
//! - the binary's crate holds no mathematics: no linear algebra of its own (no nalgebra or
//!   faer in its `[dependencies]`, no solve, decomposition or inverse called in its
//!   sources); fits, estimators and transforms live in the library they belong to;
//! - libraries never print: no `println!`/`eprintln!` outside the binary's `commands` and
//!   `main.rs` (tests, examples and doc comments aside).
//!
//! Test modules (`#[cfg(test)]` to the end of a file) are not library code and are skipped.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every `.rs` file under `dir`, with its module path (`["a", "b"]` for `a/b.rs` or
/// `a/b/mod.rs`; `[]` for `lib.rs`/`main.rs`).
fn modules(dir: &Path, prefix: &[String], out: &mut Vec<(Vec<String>, PathBuf)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().flatten().collect();
    entries.sort_by_key(|e| e.path());
    for e in entries {
        let p = e.path();
        let name = p.file_stem().unwrap().to_string_lossy().to_string();
        if p.is_dir() {
            let mut q = prefix.to_vec();
            q.push(name);
            modules(&p, &q, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            let mut q = prefix.to_vec();
            if !matches!(name.as_str(), "lib" | "main" | "mod") {
                q.push(name);
            }
            out.push((q, p));
        }
    }
}

/// Library code of a file: comments and the trailing test module removed.
fn code(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let line = match line.find("//") {
            Some(i) if !line[..i].contains('"') => &line[..i],
            _ => line,
        };
        out.push_str(line);
        out.push('\n');
    }
    out
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The paths (as segment lists) that start at `text[start..]`, after a `crate::`-like
/// prefix: `a::b`, or each member of a `{a::b, c}` group.
fn paths_at(text: &str, start: usize) -> Vec<Vec<String>> {
    let rest = &text[start..];
    if let Some(inner) = rest.strip_prefix('{') {
        let mut depth = 0;
        let mut end = inner.len();
        for (i, c) in inner.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    end = i;
                    break;
                }
                '}' => depth -= 1,
                _ => {}
            }
        }
        let body = &inner[..end];
        let mut items = Vec::new();
        let (mut depth, mut from) = (0, 0);
        for (i, c) in body.char_indices() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    items.push(&body[from..i]);
                    from = i + 1;
                }
                _ => {}
            }
        }
        items.push(&body[from..]);
        return items
            .iter()
            .flat_map(|it| paths_at(it.trim_start(), 0))
            .collect();
    }
    let mut segs = Vec::new();
    let mut s = rest;
    loop {
        let n = s.find(|c: char| !is_ident(c)).unwrap_or(s.len());
        if n == 0 {
            break;
        }
        segs.push(s[..n].to_string());
        s = &s[n..];
        match s.strip_prefix("::") {
            Some(t) if t.starts_with('{') => {
                let base = segs.clone();
                return paths_at(t, 0)
                    .into_iter()
                    .map(|p| base.iter().cloned().chain(p).collect())
                    .collect();
            }
            Some(t) => s = t,
            None => break,
        }
    }
    vec![segs]
}

/// Absolute module paths a file refers to.
fn references(module: &[String], text: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    for (prefix, base) in [("crate::", 0usize), ("super::", 1), ("self::", 2)] {
        let mut from = 0;
        while let Some(i) = text[from..].find(prefix) {
            let at = from + i;
            from = at + prefix.len();
            if at > 0 && text[..at].ends_with(|c: char| is_ident(c) || c == ':') {
                continue;
            }
            // Resolve the prefix against the file's module path.
            let mut root: Vec<String> = module.to_vec();
            match base {
                0 => root.clear(),
                // `super` of module a::b (`a/b.rs` or `a/b/mod.rs`) is `a`.
                1 => {
                    root.pop();
                }
                _ => {}
            }
            let mut rest = &text[from..];
            // super::super::
            if base == 1 {
                while let Some(r) = rest.strip_prefix("super::") {
                    root.pop();
                    rest = r;
                }
            }
            let start = text.len() - rest.len();
            for p in paths_at(text, start) {
                out.push(root.iter().cloned().chain(p).collect());
            }
        }
    }
    out
}

/// The cycles among sibling modules of one crate (each as a list of module paths).
fn cycles(src: &Path) -> Vec<String> {
    let mut files = Vec::new();
    modules(src, &[], &mut files);
    let known: BTreeSet<Vec<String>> = files.iter().map(|(m, _)| m.clone()).collect();
    // edges[parent][child] = set of siblings it refers to
    let mut edges: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (m, path) in &files {
        if m.is_empty() || path.components().any(|c| c.as_os_str() == "bin") {
            continue;
        }
        for r in references(m, &code(path)) {
            // The longest common prefix of m and r is the parent; the next segments are the
            // two siblings.
            let common = m.iter().zip(&r).take_while(|(a, b)| a == b).count();
            if common >= m.len() || common >= r.len() {
                continue;
            }
            let parent = m[..common].to_vec();
            let target: Vec<String> = r[..=common].to_vec();
            if !known.contains(&target) {
                continue; // an item (fn, type) of the parent, not a module
            }
            edges
                .entry(parent)
                .or_default()
                .entry(m[common].clone())
                .or_default()
                .insert(r[common].clone());
        }
    }
    let mut found = Vec::new();
    for (parent, g) in &edges {
        // Depth-first search for a back edge.
        fn visit(
            n: &str,
            g: &BTreeMap<String, BTreeSet<String>>,
            stack: &mut Vec<String>,
            done: &mut BTreeSet<String>,
            found: &mut Vec<Vec<String>>,
        ) {
            if let Some(i) = stack.iter().position(|s| s == n) {
                let mut c = stack[i..].to_vec();
                c.push(n.to_string());
                found.push(c);
                return;
            }
            if done.contains(n) {
                return;
            }
            stack.push(n.to_string());
            for m in g.get(n).into_iter().flatten() {
                visit(m, g, stack, done, found);
            }
            stack.pop();
            done.insert(n.to_string());
        }
        let mut done = BTreeSet::new();
        let mut cs = Vec::new();
        for n in g.keys() {
            visit(n, g, &mut Vec::new(), &mut done, &mut cs);
        }
        for c in cs {
            let p = if parent.is_empty() {
                "crate".to_string()
            } else {
                parent.join("::")
            };
            found.push(format!("{p}: {}", c.join(" → ")));
        }
    }
    found
}

fn crates() -> Vec<(String, PathBuf)> {
    let mut v: Vec<_> = std::fs::read_dir(workspace().join("crates"))
        .unwrap()
        .flatten()
        .map(|e| (e.file_name().to_string_lossy().to_string(), e.path()))
        .filter(|(_, p)| p.join("Cargo.toml").exists())
        .collect();
    v.sort();
    v
}

#[test]
fn no_module_cycles_in_library_code() {
    let mut all = Vec::new();
    for (name, dir) in crates() {
        for c in cycles(&dir.join("src")) {
            all.push(format!("{name}: {c}"));
        }
    }
    assert!(all.is_empty(), "module cycles:\n{}", all.join("\n"));
}

#[test]
fn the_checker_sees_a_cycle() {
    let dir = std::env::temp_dir().join(format!("pingcal-arch-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("src/outer")).unwrap();
    std::fs::write(
        dir.join("src/lib.rs"),
        "pub mod a; pub mod b; pub mod outer;",
    )
    .unwrap();
    std::fs::write(dir.join("src/a.rs"), "use crate::b::thing;\n").unwrap();
    std::fs::write(
        dir.join("src/b.rs"),
        "use crate::{outer::x, a::{self, y}};\n",
    )
    .unwrap();
    std::fs::write(dir.join("src/outer/mod.rs"), "pub mod x; pub mod y;").unwrap();
    std::fs::write(dir.join("src/outer/x.rs"), "use super::y::f;").unwrap();
    std::fs::write(
        dir.join("src/outer/y.rs"),
        "fn g() { super::x::h() }\n#[cfg(test)]\nmod tests { use crate::a; }",
    )
    .unwrap();
    let c = cycles(&dir.join("src"));
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(c.len(), 2, "{c:?}");
    assert!(c.iter().any(|s| s.starts_with("crate: a → b → a")), "{c:?}");
    assert!(c.iter().any(|s| s.starts_with("outer: x → y → x")), "{c:?}");
}

/// The pingcal crates a crate's Cargo.toml names under `[dependencies]`.
fn pingcal_deps(dir: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    let mut in_deps = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        let l = line.trim();
        if l.starts_with('[') {
            in_deps = l == "[dependencies]";
            continue;
        }
        if in_deps {
            if let Some(name) = l.strip_prefix("pingcal-") {
                let n = name.split(['.', ' ', '=']).next().unwrap();
                out.insert(n.to_string());
            } else if l
                .strip_prefix("pingcal")
                .is_some_and(|r| r.starts_with(['.', ' ', '=']))
            {
                // the binary's crate is the package `pingcal`, in crates/cli
                out.insert("cli".to_string());
            }
        }
    }
    out
}

#[test]
fn crates_depend_one_way() {
    let deps: BTreeMap<String, BTreeSet<String>> = crates()
        .into_iter()
        .map(|(n, d)| (n, pingcal_deps(&d)))
        .collect();
    let allowed: &[(&str, &[&str])] = &[
        ("geometry", &[]),
        ("camera", &[]),
        // The tests' shared harnesses: a dev-dependency only. No crate lists it below, so
        // no crate may depend on it outside `[dev-dependencies]`.
        ("testkit", &[]),
        ("ba", &["geometry", "camera"]),
        ("targets", &["geometry", "camera", "ba"]),
        ("lrf", &["geometry", "camera", "ba"]),
        // a project's `[board]` resolves to the detectors' board (`Board::planar`)
        ("project", &["geometry", "camera", "ba", "targets", "lrf"]),
        ("report", &["geometry", "camera", "ba"]),
        (
            "sim",
            &["geometry", "camera", "ba", "targets", "lrf", "project"],
        ),
        ("rosbag", &["geometry", "camera", "ba", "lrf"]),
        (
            "pipeline",
            &[
                "geometry", "camera", "ba", "targets", "lrf", "project", "report", "rosbag",
            ],
        ),
        (
            "plan",
            &[
                "geometry", "camera", "ba", "targets", "lrf", "project", "report", "rosbag", "sim",
                "pipeline",
            ],
        ),
    ];
    for (krate, ok) in allowed {
        let Some(d) = deps.get(*krate) else { continue };
        for dep in d {
            assert!(
                ok.contains(&dep.as_str()),
                "crates/{krate} depends on pingcal-{dep}; allowed: {ok:?}"
            );
        }
    }
    for (krate, d) in &deps {
        assert!(
            !d.contains("cli"),
            "crates/{krate} depends on the binary's crate"
        );
        assert!(
            krate == "cli" || allowed.iter().any(|(k, _)| k == krate),
            "crates/{krate} is not in this test's list of allowed dependencies: put it in its layer"
        );
    }
}

/// Every text file under `dir` (sources, docs, manifests), skipping build output.
fn text_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            if p.file_name().is_some_and(|n| n != "target") {
                text_files(&p, out);
            }
        } else if p
            .extension()
            .is_some_and(|x| ["rs", "md", "toml", "py", "sh"].contains(&&*x.to_string_lossy()))
        {
            out.push(p);
        }
    }
}

/// The repository stands alone: no source, test or doc sends a reader to the design notes
/// that are not in it (the method, frames, units and formats are in docs/).
#[test]
fn no_file_points_outside_the_repository() {
    let mut files = Vec::new();
    for d in ["crates", "docs", "tests", "bench"] {
        text_files(&workspace().join(d), &mut files);
    }
    files.push(workspace().join("README.md"));
    let this = Path::new(file!()).file_name().unwrap().to_owned();
    let notes = ["SPEC", "NOTES"].map(|n| format!("{n}.md"));
    let mut found = Vec::new();
    for f in files {
        if f.file_name() == Some(&this) {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap_or_default();
        for (k, line) in text.lines().enumerate() {
            if notes.iter().any(|n| line.contains(n.as_str())) {
                found.push(format!("{}:{}", f.display(), k + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "references to notes outside the repository (put what users need into docs/): {found:?}"
    );
}

#[test]
fn libraries_never_print() {
    let mut found = Vec::new();
    for (name, dir) in crates() {
        let mut files = Vec::new();
        modules(&dir.join("src"), &[], &mut files);
        for (m, path) in files {
            let rel = path
                .strip_prefix(&dir)
                .unwrap()
                .to_string_lossy()
                .to_string();
            if name == "cli" && (rel == "src/main.rs" || m.first().is_some_and(|s| s == "commands"))
            {
                continue;
            }
            for (i, line) in code(&path).lines().enumerate() {
                if line.contains("println!(") || line.contains("print!(") {
                    found.push(format!("crates/{name}/{rel}:{}: {}", i + 1, line.trim()));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "library code prints:\n{}",
        found.join("\n")
    );
}

/// Calls that solve, decompose or invert: numeric routines, which belong in a library.
const NUMERIC_CALLS: [&str; 12] = [
    ".cholesky(",
    ".svd(",
    ".lu(",
    ".qr(",
    ".symmetric_eigen(",
    ".try_inverse(",
    ".pseudo_inverse(",
    ".solve(",
    ".solve_mut(",
    ".full_piv_lu(",
    "faer::",
    "nalgebra::",
];

#[test]
fn the_binary_holds_no_numeric_routines() {
    let cli = workspace().join("crates/cli");
    let deps = std::fs::read_to_string(cli.join("Cargo.toml")).unwrap();
    let deps = deps.split("[dependencies]").nth(1).unwrap_or("");
    let deps = deps.split("\n[").next().unwrap_or("");
    for krate in ["nalgebra", "faer"] {
        assert!(
            !deps.lines().any(|l| l.trim_start().starts_with(krate)),
            "crates/cli depends on {krate}: its mathematics belongs in a library crate"
        );
    }
    let mut files = Vec::new();
    modules(&cli.join("src"), &[], &mut files);
    let mut found = Vec::new();
    for (_, path) in files {
        for (i, line) in code(&path).lines().enumerate() {
            if let Some(call) = NUMERIC_CALLS.iter().find(|c| line.contains(*c)) {
                found.push(format!("{}:{}: {call}", path.display(), i + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "numeric routines in the binary's crate (move them to the library they belong to):\n{}",
        found.join("\n")
    );
}

/// The longest a function of library or binary code may be: a reader holds it in their head.
const MAX_FUNCTION_LINES: usize = 120;

/// The name of the function whose signature starts on `line`, if one does.
fn fn_name(line: &str) -> Option<&str> {
    let mut rest = line.trim_start();
    for prefix in [
        "pub(crate) ",
        "pub(super) ",
        "pub ",
        "const ",
        "async ",
        "unsafe ",
    ] {
        rest = rest.strip_prefix(prefix).unwrap_or(rest);
    }
    let rest = rest.strip_prefix("fn ")?;
    let end = rest.find(|c: char| !is_ident(c))?;
    (end > 0).then(|| &rest[..end])
}

/// The change of brace depth along `line`, outside string and character literals; `in_str`
/// carries an open string literal to the next line.
fn brace_change(line: &str, in_str: &mut bool) -> (i64, bool) {
    let (mut depth, mut opened) = (0, false);
    let c: Vec<char> = line.chars().collect();
    let mut i = 0;
    while i < c.len() {
        if *in_str {
            match c[i] {
                '\\' => i += 1,
                '"' => *in_str = false,
                _ => {}
            }
        } else {
            match c[i] {
                '"' => *in_str = true,
                // a character literal ('{', '\'', '\n'); a lifetime has no closing quote
                '\'' if c.get(i + 2) == Some(&'\'') => i += 2,
                '\'' if c.get(i + 1) == Some(&'\\') && c.get(i + 3) == Some(&'\'') => i += 3,
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => depth -= 1,
                _ => {}
            }
        }
        i += 1;
    }
    (depth, opened)
}

/// The functions in `text` (code as [`code`] gives it) longer than `max` lines: name, first
/// line (1-based) and length.
fn long_functions(text: &str, max: usize) -> Vec<(String, usize, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let Some(name) = fn_name(line) else { continue };
        let (mut depth, mut started, mut in_str) = (0i64, false, false);
        for (j, l) in lines.iter().enumerate().skip(i) {
            let (d, opened) = brace_change(l, &mut in_str);
            depth += d;
            started |= opened;
            if !started && l.trim_end().ends_with(';') {
                break; // a declaration without a body
            }
            if started && depth <= 0 {
                if j + 1 - i > max {
                    out.push((name.to_string(), i + 1, j + 1 - i));
                }
                break;
            }
        }
    }
    out
}

#[test]
fn the_length_check_counts_a_function_to_its_closing_brace() {
    let text = "pub fn a() {\n    let s = \"}\";\n    let c = '{';\n}\nfn b();\nfn c<'a>(x: &'a str) {\n    if x.is_empty() {\n    }\n}\n";
    assert!(long_functions(text, 4).is_empty());
    assert_eq!(
        long_functions(text, 3),
        vec![("a".to_string(), 1, 4), ("c".to_string(), 6, 4)]
    );
}

/// No function of library or binary code (tests aside) is longer than
/// [`MAX_FUNCTION_LINES`]: a long body is split into steps with names.
#[test]
fn no_function_outside_tests_is_too_long() {
    let mut found = Vec::new();
    for (name, dir) in crates() {
        let mut files = Vec::new();
        for sub in ["src", "examples", "benches"] {
            if dir.join(sub).is_dir() {
                modules(&dir.join(sub), &[], &mut files);
            }
        }
        for (_, path) in files {
            let rel = path.strip_prefix(&dir).unwrap().display().to_string();
            for (f, line, n) in long_functions(&code(&path), MAX_FUNCTION_LINES) {
                found.push(format!("crates/{name}/{rel}:{line}: {f} has {n} lines"));
            }
        }
    }
    assert!(
        found.is_empty(),
        "functions over {MAX_FUNCTION_LINES} lines (split them into named steps):\n{}",
        found.join("\n")
    );
}

/// The longest a file of the pipeline may be, in lines of non-test code (issue 49: rooms of
/// one job each).
const PIPELINE_MAX_FILE_LINES: usize = 800;

/// The longest a function of the pipeline may be (issue 49): a step a reader holds in their
/// head.
const PIPELINE_MAX_FUNCTION_LINES: usize = 80;

/// No file of `crates/pipeline` has more than [`PIPELINE_MAX_FILE_LINES`] lines of
/// non-test code, and no function there more than [`PIPELINE_MAX_FUNCTION_LINES`] lines.
#[test]
fn the_pipelines_files_and_functions_are_short() {
    let dir = workspace().join("crates/pipeline");
    let mut files = Vec::new();
    modules(&dir.join("src"), &[], &mut files);
    let mut found = Vec::new();
    for (_, path) in files {
        let rel = path.strip_prefix(&dir).unwrap().display().to_string();
        let text = code(&path);
        let n = text.lines().count();
        if n > PIPELINE_MAX_FILE_LINES {
            found.push(format!("crates/pipeline/{rel}: {n} lines of non-test code"));
        }
        for (f, line, n) in long_functions(&text, PIPELINE_MAX_FUNCTION_LINES) {
            found.push(format!("crates/pipeline/{rel}:{line}: {f} has {n} lines"));
        }
    }
    assert!(
        found.is_empty(),
        "the pipeline's files over {PIPELINE_MAX_FILE_LINES} lines or functions over {PIPELINE_MAX_FUNCTION_LINES} (split them by job):\n{}",
        found.join("\n")
    );
}
