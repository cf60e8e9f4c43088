//! A run of dark pixels read from the empty-well table, a chunk at a time.
//!
//! A dark pixel's first shot draw decides it: its low 32 bits at or below a threshold
//! mean an empty well (no dark electron), whose code the high 32 bits pick from the
//! [`EmptyWell`] table. The draws of a chunk are hashed first, in a loop of their own
//! that the compiler vectorises (the hash has no branch and each pixel's is
//! independent), then read in pixel order; only the rare pixel with a dark electron or
//! more takes the caller's own path.

use super::empty_well::{EmptyWell, TALLY_RUN, Tally};
use super::stream::PixelStream;

/// Pixels hashed ahead of the reading loop (512 bytes of draws, in L1).
const CHUNK: usize = 64;
const _: () = assert!(CHUNK <= TALLY_RUN);

/// The largest 32-bit value `x` with `(x + ½)·2⁻³² ≤ empty`: the integer form of the
/// test on a first draw's low bits that an empty well passes (None when none does).
pub fn empty_threshold(empty: f64) -> Option<u32> {
    let passes = |x: u32| (x as f64 + 0.5) * (1.0 / 4_294_967_296.0) <= empty;
    if !passes(0) {
        return None;
    }
    // Start near the answer, then step to it with the test itself (exact whatever the
    // rounding of the estimate).
    let mut x = (empty * 4_294_967_296.0 - 0.5).clamp(0.0, u32::MAX as f64) as u32;
    while !passes(x) {
        x -= 1;
    }
    while x < u32::MAX && passes(x + 1) {
        x += 1;
    }
    Some(x)
}

/// Codes of the pixels `first..first + out.len()` under frame key `key`: an empty well
/// read from `well` when the low bits of the pixel's first shot draw are at most
/// `threshold`, else `rare(i, out_i)`. Returns what the table's codes add to the row's sums.
#[inline(always)]
pub fn run(
    key: u64,
    first: u64,
    out: &mut [u16],
    well: &EmptyWell,
    threshold: Option<u32>,
    mut rare: impl FnMut(usize, &mut u16),
) -> Tally {
    let mut tally = Tally::default();
    let Some(t) = threshold else {
        for (i, o) in out.iter_mut().enumerate() {
            rare(i, o);
        }
        return tally;
    };
    let mut h = [0u64; CHUNK];
    for (k, chunk) in out.chunks_mut(CHUNK).enumerate() {
        let p0 = first + (k * CHUNK) as u64;
        let h = &mut h[..chunk.len()];
        PixelStream::first_draws(key, p0, 0, h);
        let mut packed = 0u64;
        for (i, (o, &h)) in chunk.iter_mut().zip(h.iter()).enumerate() {
            if h as u32 <= t {
                let v = well.tally((h >> 32) as u32);
                packed += v;
                *o = v as u16;
            } else {
                rare(k * CHUNK + i, o);
            }
        }
        tally.add(packed);
    }
    tally
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_is_the_float_test() {
        let passes = |x: u32, e: f64| (x as f64 + 0.5) * (1.0 / 4_294_967_296.0) <= e;
        for e in [1.0, 1.0 - 1e-3, 0.5, 1e-9, 2.0f64.powi(-33), 0.75 + 2.0f64.powi(-33), 1.0 - 2.0f64.powi(-40)] {
            let t = empty_threshold(e).unwrap();
            assert!(passes(t, e), "{e}");
            assert!(t == u32::MAX || !passes(t + 1, e), "{e}");
        }
        assert_eq!(empty_threshold(-1.0), None);
        assert_eq!(empty_threshold(2.0f64.powi(-34)), None);
    }
}
