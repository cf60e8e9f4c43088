//! Tests whose datagrams could leave the machine (a hostile stream destination, an
//! Aravis discovery broadcast on every interface) run inside a private network
//! namespace (`unshare -n`, as root): only its own loopback exists there, so nothing
//! can reach another host, and fixed ports cannot collide with other tests.

use std::process::Command;

const INSIDE: &str = "HILCAM_TEST_NETNS";

/// In the namespace: brings `lo` up and returns true (the test goes on). Outside: runs
/// this test binary's `test` (its full path, `module::name`) again inside one, prints
/// its output, asserts it passed and returns false (the caller returns).
pub(crate) fn enter(test: &str) -> bool {
    if std::env::var_os(INSIDE).is_some() {
        loopback_up().expect("bringing lo up in the test's network namespace");
        return true;
    }
    let exe = std::env::current_exe().unwrap();
    let out = Command::new("unshare")
        .args(["--net", "--"])
        .arg(exe)
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env(INSIDE, "1")
        .output()
        .expect("unshare (util-linux) runs the test in a private network namespace");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    println!("--- {test} in a private network namespace ---\n{text}");
    assert!(
        out.status.success() && text.contains("1 passed"),
        "{test} failed in its network namespace (unshare -n needs root: CAP_SYS_ADMIN):\n{text}"
    );
    false
}

/// `ip link set lo up` without iproute2: SIOCSIFFLAGS with IFF_UP on `lo`.
fn loopback_up() -> std::io::Result<()> {
    // SAFETY: a plain socket and two ioctls on a zeroed ifreq naming "lo"; the fd is closed.
    unsafe {
        let fd = libc::socket(libc::AF_INET, libc::SOCK_DGRAM, 0);
        if fd < 0 {
            return Err(std::io::Error::last_os_error());
        }
        let mut ifr: libc::ifreq = std::mem::zeroed();
        ifr.ifr_name[0] = b'l' as libc::c_char;
        ifr.ifr_name[1] = b'o' as libc::c_char;
        let mut r = libc::ioctl(fd, libc::SIOCGIFFLAGS, &mut ifr);
        if r == 0 {
            ifr.ifr_ifru.ifru_flags |= libc::IFF_UP as libc::c_short;
            r = libc::ioctl(fd, libc::SIOCSIFFLAGS, &ifr);
        }
        let err = std::io::Error::last_os_error();
        libc::close(fd);
        if r == 0 { Ok(()) } else { Err(err) }
    }
}
