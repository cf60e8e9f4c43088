//! MTL files as written: every key of every material with its line, so that a material
//! without a `[materials.NAME]` table can be built from its own keys (`mtl_bsdf`) and
//! every key that is not used can be reported by file and line. tobj reads the same
//! files for the material names; it keeps no line numbers.

use std::path::{Path, PathBuf};

/// One key of a material: its words after the key, and the line it is on (1-based).
#[derive(Clone, Debug, PartialEq)]
pub struct MtlKey {
    pub key: String,
    pub args: Vec<String>,
    pub line: usize,
}

/// One `newmtl` block.
#[derive(Clone, Debug, PartialEq)]
pub struct MtlMaterial {
    pub name: String,
    /// The MTL file it is in.
    pub file: PathBuf,
    /// Line of its `newmtl`.
    pub line: usize,
    /// Its keys in file order.
    pub keys: Vec<MtlKey>,
}

impl MtlMaterial {
    /// The first occurrence of `key` (MTL keys are case-sensitive: `Kd`, `Pr`).
    pub fn get(&self, key: &str) -> Option<&MtlKey> {
        self.keys.iter().find(|k| k.key == key)
    }

    /// `file:line` for messages, the file by its name only (as the MTL's author knows it).
    pub fn at(&self, line: usize) -> String {
        let name =
            self.file.file_name().map_or_else(|| self.file.display().to_string(), |n| n.to_string_lossy().into());
        format!("{name}:{line}")
    }
}

/// The materials of an MTL file's text (`file` names it in the result).
pub fn parse_mtl(file: &Path, text: &str) -> Vec<MtlMaterial> {
    let mut out: Vec<MtlMaterial> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let args: Vec<String> = words.map(str::to_string).collect();
        if key == "newmtl" {
            out.push(MtlMaterial { name: args.join(" "), file: file.to_path_buf(), line: i + 1, keys: Vec::new() });
        } else if let Some(m) = out.last_mut() {
            m.keys.push(MtlKey { key: key.to_string(), args, line: i + 1 });
        }
    }
    out
}

/// The materials of every `mtllib` an OBJ's text names, relative to `dir`. A library that
/// cannot be read adds nothing here: the OBJ loader reports it where a face needs it.
pub fn libraries_of_obj(dir: &Path, obj_text: &str) -> Vec<MtlMaterial> {
    let mut out = Vec::new();
    for line in obj_text.lines() {
        let mut words = line.split_whitespace();
        if words.next() != Some("mtllib") {
            continue;
        }
        for name in words {
            let path = dir.join(name);
            if let Ok(text) = std::fs::read_to_string(&path) {
                out.extend(parse_mtl(&path, &text));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_keep_their_lines_and_comments_are_dropped() {
        let text = "# made by hand\nnewmtl panel\nKd 0.5 0.5 0.5 # grey\n\nPs 0.3\nnewmtl foil\nPm 1\n";
        let m = parse_mtl(Path::new("dir/panel.mtl"), text);
        assert_eq!(m.len(), 2);
        assert_eq!((m[0].name.as_str(), m[0].line), ("panel", 2));
        assert_eq!(m[0].get("Kd").unwrap().args, ["0.5", "0.5", "0.5"]);
        assert_eq!(m[0].at(m[0].get("Ps").unwrap().line), "panel.mtl:5");
        assert_eq!(m[1].get("Pm").unwrap().line, 7);
        assert!(m[1].get("Kd").is_none());
    }
}
