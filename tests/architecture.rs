//! The library's shape, checked: hilcam-core's top-level modules form layers in data-flow
//! order (each imports only modules of earlier layers, so there is no import cycle), the
//! core depends on no command-line or lab crate, and neither library names the binary.
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
