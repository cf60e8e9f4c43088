//! The library's shape, checked: hilcam-core's top-level modules form layers in data-flow
//! order (each imports only modules of earlier layers, so there is no import cycle), the
//! core depends on no command-line or lab crate, neither library names the binary, and no
//! two of the core's files import each other.
//! Reads the sources and manifests; builds nothing.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// hilcam-core's top-level modules, earliest layer first: a module may import (via
/// `crate::`) only modules listed before it. `lib.rs` documents the same order.
/// `shutdown` comes first: the links, the sinks (GigE's threads, the stream's clients),
/// replay and serve all hold the one stop signal, so it must sit below all of them.
const LAYERS: &[&str] = &[
    "shutdown", "heap", "metrics", "pose", "link", "render", "sensor", "scene", "pipeline", "frame", "session", "sink",
    "rig", "replay", "serve",
];

/// Crates the product core must not depend on: the command line and the lab's.
const NOT_IN_CORE: &[&str] = &["clap", "hilcam-lab", "hilcam", "plotters", "indicatif", "tracing-subscriber"];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        for e in std::fs::read_dir(path).unwrap() {
            rust_files(&e.unwrap().path(), out);
        }
    } else if path.is_file() && path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The files of top-level module `m`: `m.rs` and/or everything under `m/`.
fn module_files(src: &Path, m: &str) -> Vec<PathBuf> {
    let mut files = Vec::new();
    rust_files(&src.join(format!("{m}.rs")), &mut files);
    rust_files(&src.join(m), &mut files);
    assert!(!files.is_empty(), "no source for module `{m}` under {}", src.display());
    files
}

/// Code of a line without its `//` comment (doc links are not imports).
fn code(line: &str) -> &str {
    line.find("//").map_or(line, |i| &line[..i])
}

/// Every `crate::<name>` in `text`'s code, with its line number.
fn crate_refs(text: &str) -> Vec<(usize, String)> {
    let mut refs = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = code(line);
        let mut rest = line;
        while let Some(i) = rest.find("crate::") {
            let preceded_by_ident =
                rest[..i].chars().last().is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$');
            rest = &rest[i + "crate::".len()..];
            if preceded_by_ident {
                continue;
            }
            let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
            refs.push((n + 1, name));
        }
    }
    refs
}

#[test]
fn core_modules_are_the_declared_layers() {
    let lib = std::fs::read_to_string(root().join("crates/hilcam-core/src/lib.rs")).unwrap();
    let declared: BTreeSet<&str> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("pub mod ").or_else(|| l.strip_prefix("mod ")))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    let layered: BTreeSet<&str> = LAYERS.iter().copied().collect();
    assert_eq!(
        declared, layered,
        "hilcam-core's lib.rs modules and this test's LAYERS differ: place each module in a layer"
    );
}

#[test]
fn core_modules_import_only_earlier_layers() {
    let src = root().join("crates/hilcam-core/src");
    let mut back_edges = Vec::new();
    for (layer, m) in LAYERS.iter().enumerate() {
        for file in module_files(&src, m) {
            let text = std::fs::read_to_string(&file).unwrap();
            for (line, target) in crate_refs(&text) {
                let Some(t) = LAYERS.iter().position(|l| *l == target) else { continue };
                if t > layer {
                    back_edges.push(format!(
                        "{}:{line}: `{m}` imports `{target}`, a later layer (order: {})",
                        file.strip_prefix(root()).unwrap().display(),
                        LAYERS.join(" → ")
                    ));
                }
            }
        }
    }
    assert!(
        back_edges.is_empty(),
        "import back-edges (each closes a cycle or inverts the data flow):\n{}",
        back_edges.join("\n")
    );
}

#[test]
fn the_checker_sees_a_back_edge() {
    // The scanner itself: a `use crate::serve` line is found, a comment or a longer
    // identifier ending in `crate` is not.
    let refs =
        crate_refs("use crate::serve::Thing;\n// see crate::replay\nlet x = mycrate::pose;\n  crate::render::f()");
    assert_eq!(refs, vec![(1, "serve".to_string()), (4, "render".to_string())]);
}

#[test]
fn core_depends_on_no_cli_or_lab_crate() {
    let manifest: toml::Table =
        std::fs::read_to_string(root().join("crates/hilcam-core/Cargo.toml")).unwrap().parse().unwrap();
    let deps = manifest["dependencies"].as_table().unwrap();
    let bad: Vec<&str> = NOT_IN_CORE.iter().copied().filter(|c| deps.contains_key(*c)).collect();
    assert!(
        bad.is_empty(),
        "crates/hilcam-core/Cargo.toml depends on {bad:?}: the core must build without the CLI and the lab"
    );
}

#[test]
fn libraries_never_name_the_binary() {
    for lib in ["crates/hilcam-core/src", "crates/hilcam-lab/src"] {
        let mut files = Vec::new();
        rust_files(&root().join(lib), &mut files);
        assert!(files.len() > 10, "{lib}: too few sources found");
        for f in files {
            let text = std::fs::read_to_string(&f).unwrap();
            for (n, line) in text.lines().enumerate() {
                let c = code(line);
                let names_binary = c.contains("hilcam::");
                let core_names_lab = lib.contains("core") && c.contains("hilcam_lab");
                assert!(
                    !names_binary && !core_names_lab,
                    "{}:{}: a library imports the binary or the core imports the lab: {line}",
                    f.display(),
                    n + 1
                );
            }
        }
    }
}

// --- Files: no two import each other --------------------------------------------------

/// A source file's module path under `src` (`render/cull/visibility.rs` → render, cull,
/// visibility; a `mod.rs` or `lib.rs` is its folder's module).
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib")) {
        parts.pop();
    }
    parts
}

/// A file's code as the import scan reads it: without comments, string contents, its
/// unit tests (`#[cfg(test)] mod tests` to the end) and `pub(in path)` visibilities.
fn import_code(text: &str) -> String {
    let text = text.find("#[cfg(test)]\nmod tests").map_or(text, |i| &text[..i]);
    let mut out = String::new();
    for line in text.lines() {
        let line = code(line);
        let mut in_str = false;
        let mut prev = ' ';
        for ch in line.chars() {
            if ch == '"' && prev != '\\' {
                in_str = !in_str;
            } else if !in_str {
                out.push(ch);
            }
            prev = if prev == '\\' && ch == '\\' { ' ' } else { ch };
        }
        out.push('\n');
    }
    while let Some(i) = out.find("pub(in ") {
        let end = out[i..].find(')').map_or(out.len(), |j| i + j + 1);
        out.replace_range(i..end, "pub");
    }
    out
}

/// Every path a `use` tree names (`a::{b, c::d as e}` → a::b, a::c::d).
fn use_paths(tree: &str) -> Vec<Vec<String>> {
    fn walk(prefix: &[String], items: &str, out: &mut Vec<Vec<String>>) {
        let (mut depth, mut start) = (0, 0);
        let mut parts = Vec::new();
        for (i, ch) in items.char_indices() {
            match ch {
                '{' => depth += 1,
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    parts.push(&items[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        parts.push(&items[start..]);
        for item in parts.into_iter().map(str::trim).filter(|s| !s.is_empty()) {
            let mut path = prefix.to_vec();
            match item.find('{') {
                Some(open) => {
                    let Some(close) = item.rfind('}').filter(|c| *c > open) else { continue };
                    path.extend(item[..open].split("::").filter(|s| !s.is_empty()).map(String::from));
                    walk(&path, &item[open + 1..close], out);
                }
                None => {
                    let item = item.split(" as ").next().unwrap();
                    path.extend(item.split("::").map(|s| s.trim().to_string()));
                    out.push(path);
                }
            }
        }
    }
    let mut out = Vec::new();
    walk(&[], &tree.split_whitespace().collect::<Vec<_>>().join(" "), &mut out);
    out
}

/// The paths a file's code names from its own crate: `use` trees and inline
/// `crate::`/`super::`/`self::` paths. A bare path (`use child::Item`) can only name a
/// module's own child: a folder's `mod.rs` re-exporting its files is that folder's face,
/// not a circle, and is not counted.
fn named_paths(code: &str) -> Vec<Vec<String>> {
    let mut paths = Vec::new();
    // `use` items: a line starting with `use` (after any visibility), to the `;`.
    let mut offset = 0;
    for line in code.split_inclusive('\n') {
        let t = line.trim_start();
        let t = t.strip_prefix("pub").map_or(t, |r| r.trim_start_matches(|c| c != ' ').trim_start());
        if let Some(tree) = t.strip_prefix("use ") {
            let start = offset + (line.len() - tree.len());
            if let Some(end) = code[start..].find(';') {
                paths.extend(use_paths(&code[start..start + end]));
            }
        }
        offset += line.len();
    }
    let bytes = code.as_bytes();
    for root in ["crate::", "super::", "self::"] {
        for (i, _) in code.match_indices(root) {
            if i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_' || bytes[i - 1] == b':') {
                continue;
            }
            let path: String =
                code[i..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':').collect();
            paths.push(path.split("::").filter(|s| !s.is_empty()).map(String::from).collect());
        }
    }
    paths
}

/// The file (module path) a path from module `here` lands in: the longest prefix that is
/// one of `modules`; `None` for paths outside the crate.
fn resolve(here: &[String], path: &[String], modules: &BTreeSet<Vec<String>>) -> Option<Vec<String>> {
    let mut full: Vec<String> = match path.first().map(String::as_str) {
        Some("crate") => Vec::new(),
        Some("self") => here.to_vec(),
        Some("super") => here.to_vec(),
        _ => return None,
    };
    let mut rest = &path[1..];
    if path[0] == "super" {
        full.pop();
        while rest.first().is_some_and(|s| s == "super") {
            full.pop();
            rest = &rest[1..];
        }
    }
    full.extend(rest.iter().cloned());
    (0..=full.len()).rev().map(|n| full[..n].to_vec()).find(|m| modules.contains(m))
}

/// Pairs of files of `files` (module path, code) that import each other.
fn mutual_imports(files: &[(Vec<String>, String)]) -> Vec<(String, String)> {
    let modules: BTreeSet<Vec<String>> = files.iter().map(|(m, _)| m.clone()).collect();
    let imports: Vec<BTreeSet<Vec<String>>> = files
        .iter()
        .map(|(m, code)| named_paths(code).iter().filter_map(|p| resolve(m, p, &modules)).filter(|t| t != m).collect())
        .collect();
    let mut pairs = Vec::new();
    for (i, (a, _)) in files.iter().enumerate() {
        for (j, (b, _)) in files.iter().enumerate() {
            if i < j && imports[i].contains(b) && imports[j].contains(a) {
                pairs.push((a.join("/"), b.join("/")));
            }
        }
    }
    pairs
}

#[test]
fn no_two_core_files_import_each_other() {
    let src = root().join("crates/hilcam-core/src");
    let mut paths = Vec::new();
    rust_files(&src, &mut paths);
    let files: Vec<(Vec<String>, String)> =
        paths.iter().map(|p| (module_path(&src, p), import_code(&std::fs::read_to_string(p).unwrap()))).collect();
    assert!(files.len() > 100, "too few core sources found: {}", files.len());
    let pairs = mutual_imports(&files);
    assert!(
        pairs.is_empty(),
        "files that import each other (move what both need into a file of its own):\n{}",
        pairs.iter().map(|(a, b)| format!("  {a} <-> {b}")).collect::<Vec<_>>().join("\n")
    );
}

#[test]
fn the_file_checker_sees_mutual_imports() {
    let m = |s: &str| s.split('/').map(String::from).collect::<Vec<_>>();
    let files = vec![
        (m("render/buffers"), import_code("use super::cull::{visibility::PrimaryRaster, coverage as c};\n")),
        (m("render/cull/visibility"), import_code("fn f() { crate::render::buffers::reserve_to(); }\n")),
        (m("render/cull/coverage"), import_code("// use super::visibility;\nlet s = \"super::visibility\";\n")),
        (m("render/cull"), import_code("pub(in crate::render) mod visibility;\n")),
    ];
    assert_eq!(mutual_imports(&files), vec![("render/buffers".to_string(), "render/cull/visibility".to_string())]);
    assert_eq!(
        use_paths("a::{b, c::{d as e, f}}, g"),
        [vec!["a", "b"], vec!["a", "c", "d"], vec!["a", "c", "f"], vec!["g"]]
    );
}
