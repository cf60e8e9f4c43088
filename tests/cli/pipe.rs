//! `hilcam render … | head -1`: a subcommand whose stdout is a pipe that closes ends
//! quietly (killed by SIGPIPE, as Unix tools are), instead of panicking with "failed
//! printing to stdout: Broken pipe".

#![cfg(unix)]

use std::os::fd::{FromRawFd, OwnedFd};
use std::os::unix::process::ExitStatusExt;
use std::process::{Command, Stdio};

/// A pipe whose read end is already closed: every write to the returned end fails.
fn closed_pipe() -> OwnedFd {
    let mut fds = [0; 2];
    // SAFETY: `fds` has room for the two descriptors `pipe` writes.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0, "pipe");
    // SAFETY: both descriptors were just created and are owned here.
    unsafe {
        libc::close(fds[0]);
        OwnedFd::from_raw_fd(fds[1])
    }
}

#[test]
fn render_into_a_closed_pipe_ends_without_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plate.pfm");
    let o = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["render", "scenes/plate.toml", "--width", "32", "--out"])
        .arg(&out)
        .stdout(Stdio::from(closed_pipe()))
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("panicked") && !stderr.contains("Broken pipe"), "{stderr}");
    assert_eq!(o.status.signal(), Some(libc::SIGPIPE), "{:?}: {stderr}", o.status);
    // The image was written before the summary line hit the closed pipe.
    assert!(out.exists());
}

#[test]
fn version_into_a_closed_pipe_ends_without_a_panic() {
    let o = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .arg("version")
        .stdout(Stdio::from(closed_pipe()))
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert_eq!(o.status.signal(), Some(libc::SIGPIPE), "{:?}: {}", o.status, String::from_utf8_lossy(&o.stderr));
}

/// `hilcam --log info render …` of a scene whose load logs at info (its model's own
/// materials), with stderr on `stderr`, `NO_COLOR` set or not.
fn render_log(stderr: Stdio, no_color: Option<&str>) -> std::process::Output {
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hilcam"));
    cmd.args(["--log", "info", "render", "scenes/gltf_satellite.toml", "--width", "16", "--out"])
        .arg(dir.path().join("sat.pfm"))
        .env_remove("NO_COLOR")
        .stdout(Stdio::null())
        .stderr(stderr);
    if let Some(v) = no_color {
        cmd.env("NO_COLOR", v);
    }
    cmd.output().unwrap()
}

/// A pseudo-terminal: (controller, the terminal end a child writes to).
fn pty() -> (std::fs::File, OwnedFd) {
    let (mut main, mut sub) = (0, 0);
    // SAFETY: openpty writes two descriptors into the two ints; the name and settings are
    // left to the defaults (null pointers are allowed).
    let rc = unsafe { libc::openpty(&mut main, &mut sub, std::ptr::null_mut(), std::ptr::null(), std::ptr::null()) };
    assert_eq!(rc, 0, "openpty");
    // SAFETY: both were just opened and are owned here.
    unsafe { (std::fs::File::from_raw_fd(main), OwnedFd::from_raw_fd(sub)) }
}

/// Everything the child wrote to the terminal (read until the child's end closes: EIO).
fn drain(mut main: std::fs::File) -> String {
    use std::io::Read;
    let mut all = Vec::new();
    let mut buf = [0u8; 4096];
    while let Ok(n) = main.read(&mut buf) {
        if n == 0 {
            break;
        }
        all.extend_from_slice(&buf[..n]);
    }
    String::from_utf8_lossy(&all).into_owned()
}

#[test]
fn log_lines_are_coloured_only_on_a_terminal_and_never_with_no_color() {
    const ESC: &str = "\x1b[";
    // A pipe (a log file, `2>&1 | tee`): plain text.
    let o = render_log(Stdio::piped(), None);
    let piped = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && piped.contains("INFO"), "{piped}");
    assert!(!piped.contains(ESC), "colour escapes in a piped log: {piped:?}");
    // A terminal: coloured, unless NO_COLOR is set to anything non-empty.
    for (no_color, coloured) in [(None, true), (Some("1"), false), (Some(""), true)] {
        let (main, sub) = pty();
        let o = render_log(Stdio::from(sub), no_color);
        assert!(o.status.success());
        let text = drain(main);
        assert!(text.contains("INFO"), "NO_COLOR={no_color:?}: {text:?}");
        assert_eq!(text.contains(ESC), coloured, "NO_COLOR={no_color:?}: {text:?}");
    }
}
