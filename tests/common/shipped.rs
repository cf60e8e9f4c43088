//! Shipped files that a project script writes: running the script again gives the same
//! bytes (a stale file fails naming itself).

use std::path::Path;

/// Run `python3 script OUT` and compare each of `files` in OUT with `shipped_dir`'s.
pub fn assert_script_writes(script: &str, shipped_dir: &str, files: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new("python3")
        .arg(script)
        .arg(dir.path())
        .output()
        .unwrap_or_else(|e| panic!("python3 runs {script}: {e}"));
    assert!(out.status.success(), "{script}: {}", String::from_utf8_lossy(&out.stderr));
    for f in files {
        let shipped = std::fs::read(Path::new(shipped_dir).join(f)).unwrap();
        assert!(std::fs::read(dir.path().join(f)).unwrap() == shipped, "{shipped_dir}/{f} is stale (run {script})");
    }
}
