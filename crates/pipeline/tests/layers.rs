//! The pipeline's modules form a sequence: each may use only the modules before it.
//!
//! The shared modules (ids, progress, context, scene, adjust) come first, then the steps in
//! the order they run, then what gathers and writes their results. This test reads
//! `src/*.rs` and the files of a module's folder (`src/matching/`, `src/sphere_calib/`) as
//! that module's, collects every `super::X` and `crate::X` path outside comments, and fails
//! when a module uses a later one, when the modules' uses form a cycle, when a module is
//! missing from [`ORDER`], when a module's library code uses an item of the crate root
//! (lib.rs only runs the steps and re-exports for the crate's callers: a step that
//! imported its `Options` from there would import from the module that imports it), or
//! when the library prints or draws (`println!`, `eprintln!`, indicatif): that is the
//! binary's side.

use std::collections::BTreeMap;
use std::path::Path;

/// The modules of the pipeline crate, lowest first (`lib.rs`, the root that runs them, is
/// apart; `test_support.rs` serves the unit tests).
const ORDER: [&str; 31] = [
    "ids",
    "progress",
    "context",
    "scene",
    "adjust",
    "detect",
    "network",
    "matching",
    "bundle",
    "head",
    "board_camera",
    "lrf",
    "extrinsic",
    "joint",
    "joint_starts",
    "fixed_lrf",
    "final_lrf",
    "stages",
    "verdict",
    "conventions",
    "results",
    "report",
    "overlays",
    "rectify",
    "exports",
    "outcome",
    "range_sensors",
    "sphere_calib",
    "board_lrf",
    "out_folders",
    "result_set",
];

/// The text of `src` without its `//` comments (doc comments included).
fn strip_comments(src: &str) -> String {
    src.lines()
        .map(|l| l.find("//").map_or(l, |k| &l[..k]))
        .collect::<Vec<_>>()
        .join("\n")
}

fn ident(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The first segments named after `super::` or `crate::` in `src` (braced groups
/// `use super::{a, b::c}` give `a` and `b`).
fn used_modules(src: &str) -> Vec<String> {
    let code = strip_comments(src);
    let mut out = Vec::new();
    for prefix in ["super::", "crate::"] {
        let mut rest = code.as_str();
        while let Some(k) = rest.find(prefix) {
            rest = &rest[k + prefix.len()..];
            let t = rest.trim_start();
            if let Some(group) = t.strip_prefix('{') {
                let mut depth = 0;
                let mut start = true;
                for (i, c) in group.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => start = true,
                        c if start && (c.is_ascii_alphanumeric() || c == '_') => {
                            out.push(ident(&group[i..]).to_string());
                            start = false;
                        }
                        c if !c.is_whitespace() => start = false,
                        _ => {}
                    }
                }
            } else {
                out.push(ident(t).to_string());
            }
        }
    }
    out
}

/// Module → the sibling modules it uses.
fn graph(files: &BTreeMap<String, String>) -> BTreeMap<String, Vec<String>> {
    files
        .iter()
        .map(|(m, src)| {
            let mut uses: Vec<String> = used_modules(src)
                .into_iter()
                .filter(|u| u != m && files.contains_key(u))
                .collect();
            uses.sort();
            uses.dedup();
            (m.clone(), uses)
        })
        .collect()
}

/// A cycle of the graph, if there is one.
fn find_cycle(g: &BTreeMap<String, Vec<String>>) -> Option<Vec<String>> {
    fn visit(
        m: &str,
        g: &BTreeMap<String, Vec<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(m) {
            Some(2) => return None,
            Some(1) => {
                let k = path.iter().position(|p| p == m).expect("on the path");
                let mut cycle = path[k..].to_vec();
                cycle.push(m.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(m.to_string(), 1);
        path.push(m.to_string());
        for u in g.get(m).into_iter().flatten() {
            if let Some(c) = visit(u, g, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(m.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    g.keys()
        .find_map(|m| visit(m, g, &mut state, &mut Vec::new()))
}

/// The library code and the test code of the `.rs` files under `dir`, a module's folder
/// (`mod.rs` and submodules). In a submodule `super::` is the module, not the crate: it is
/// read as `self::`, which names no sibling of the module.
fn folder_parts(dir: &Path, lib: &mut String, tests: &mut String) {
    let mut paths: Vec<_> = (std::fs::read_dir(dir).expect("a module's folder"))
        .map(|e| e.expect("entry").path())
        .collect();
    paths.sort();
    for path in paths {
        if path.is_dir() {
            folder_parts(&path, lib, tests);
        } else if path.extension().is_some_and(|x| x == "rs") {
            let mut src = std::fs::read_to_string(&path).expect("readable source");
            if !path.ends_with("mod.rs") {
                src = src.replace("super::", "self::");
            }
            let (l, t) = src.split_once("\n#[cfg(test)]").unwrap_or((&src, ""));
            lib.push_str(l);
            lib.push('\n');
            tests.push_str(t);
            tests.push('\n');
        }
    }
}

/// Module → its source: `src/X.rs`, or `src/X/mod.rs`, with the files of its folder
/// `src/X/`, so that a module split into files is checked as one: the library code of all
/// its files, then their tests after one `#[cfg(test)]`.
fn pipeline_files() -> BTreeMap<String, String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = BTreeMap::new();
    let mut folders = BTreeMap::new();
    for e in std::fs::read_dir(&dir).expect("src") {
        let path = e.expect("entry").path();
        if path.is_dir() {
            let name = path
                .file_name()
                .expect("name")
                .to_string_lossy()
                .into_owned();
            let (mut lib, mut tests) = (String::new(), String::new());
            folder_parts(&path, &mut lib, &mut tests);
            folders.insert(name, (lib, tests));
        } else if path.extension().is_some_and(|x| x == "rs") {
            let name = path
                .file_stem()
                .expect("name")
                .to_string_lossy()
                .into_owned();
            if name == "test_support" {
                continue;
            }
            let src = std::fs::read_to_string(&path).expect("readable source");
            files.insert(name, src);
        }
    }
    for (name, (lib, tests)) in folders {
        let root = files.remove(&name).unwrap_or_default();
        let (root_lib, root_tests) = root.split_once("\n#[cfg(test)]").unwrap_or((&root, ""));
        let text = format!("{root_lib}\n{lib}\n#[cfg(test)]{root_tests}\n{tests}");
        files.insert(name, text);
    }
    files
}

#[test]
fn pipeline_modules_only_use_earlier_ones() {
    let mut files = pipeline_files();
    let root = files.remove("lib").expect("src/lib.rs");
    for m in files.keys() {
        assert!(
            ORDER.contains(&m.as_str()),
            "src/{m}.rs is not in ORDER of this test: put it where it belongs"
        );
    }
    for m in ORDER {
        assert!(
            root.contains(&format!("pub mod {m};")),
            "{m} of ORDER is not a module of src/lib.rs"
        );
    }
    let g = graph(&files);
    if let Some(c) = find_cycle(&g) {
        panic!("module cycle in the pipeline: {}", c.join(" → "));
    }
    let pos = |m: &str| ORDER.iter().position(|o| *o == m).expect("in ORDER");
    let mut wrong = Vec::new();
    for (m, uses) in &g {
        for u in uses {
            if pos(u) > pos(m) {
                wrong.push(format!("src/{m}.rs uses {u}, which comes after it"));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn no_module_uses_the_crate_roots_items() {
    let files = pipeline_files();
    let mut wrong = Vec::new();
    for (m, src) in &files {
        if m == "lib" {
            continue;
        }
        // library code: in a test module `super::` is the module itself
        let library = src.split("\n#[cfg(test)]").next().unwrap_or_default();
        for u in used_modules(library) {
            let module =
                files.contains_key(&u) || ["sphere_calib", "test_support"].contains(&u.as_str());
            if !u.is_empty() && !module {
                wrong.push(format!("src/{m}.rs uses the crate root's {u}"));
            }
        }
    }
    wrong.sort();
    wrong.dedup();
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn the_pipeline_neither_prints_nor_draws() {
    for (m, src) in pipeline_files() {
        // library code: the test module at the end of a file may print (a skip's reason)
        let library = src.split("\n#[cfg(test)]").next().unwrap_or_default();
        let code = strip_comments(library);
        for word in ["indicatif", "println!", "print!", "eprint!", "dbg!"] {
            assert!(
                !code.contains(word),
                "src/{m}.rs uses {word}: the library reports through pipeline::Progress"
            );
        }
    }
}

#[test]
fn the_parser_sees_uses_and_cycles() {
    let src = "use super::{a, b::{X, Y}, Options};\n// use super::c;\nfn f() { super::d::g(); crate::e::h(); }";
    assert_eq!(used_modules(src), vec!["a", "b", "Options", "d", "e"]);
    let files: BTreeMap<String, String> = [
        ("a", "use super::b::X;"),
        ("b", "use super::{c, Result};"),
        ("c", "fn f() { super::a::g() }"),
    ]
    .iter()
    .map(|(m, s)| (m.to_string(), s.to_string()))
    .collect();
    assert_eq!(
        find_cycle(&graph(&files)),
        Some(vec!["a".into(), "b".into(), "c".into(), "a".into()])
    );
}
