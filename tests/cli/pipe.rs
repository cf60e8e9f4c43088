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
