//! The C heap's tuning for a process that renders frame after frame.
//!
//! Every frame allocates and frees buffers of megabytes (the truth planes, encoded
//! frames, recorded images). glibc's malloc serves blocks that large with `mmap` and
//! unmaps them on free, or trims the heap's top back to the kernel, so the next frame's
//! buffers start as fresh pages: a page fault and a zeroed page per 4 KiB, a third of the
//! truth pass's time at 1024² (docs/performance.md, "Fixed costs"). Raising the mmap
//! threshold to glibc's maximum (32 MiB) and the trim threshold above any frame's working
//! set keeps those pages in the process: its resident size stays at its peak instead.

/// Blocks up to this size come from the heap, not from a mapping of their own.
const MMAP_THRESHOLD: i32 = 32 << 20;
/// Free memory at the heap's top kept rather than returned to the kernel.
const TRIM_THRESHOLD: i32 = 1 << 30;

/// Keep freed frame buffers' pages for the next frame (glibc only; elsewhere a no-op that
/// returns false). Returns whether both settings took. Call once, early in `main`.
pub fn keep_frame_pages() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only sets malloc's parameters; it is safe to call at any time.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

/// Grow `v`'s capacity to at least `cap` (never shrinks): a frame's scratch buffers take
/// the largest size any earlier frame needed, so a steady stream allocates nothing.
pub fn reserve_to<T>(v: &mut Vec<T>, cap: usize) {
    if v.capacity() < cap {
        v.reserve_exact(cap - v.len());
    }
}

#[cfg(test)]
mod tests {
    #[test]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn glibc_takes_both_settings() {
        assert!(super::keep_frame_pages());
    }
}
