//! The per-frame noise stream of one pixel: counter-based, so any pixel's draws cost a
//! hash each and need no per-pixel seeding.
//!
//! Each pixel has two streams, one for shot noise and one for read noise, so that how
//! many draws one takes (none for a zero mean, more on a rejection) never moves the
//! other. Draw `j` of part `q` (0 shot, 1 read) of pixel `p` in a frame keyed `k` is
//! SplitMix64's output number `p·2³² + q·2³¹ + j` from state `k` (Steele, Lea & Flood 2014: `mix64(k + n·γ)`, γ the golden
//! ratio constant): one frame's pixels read disjoint runs of one SplitMix64 sequence,
//! which passes BigCrush. Another frame's key is the same sequence shifted by an
//! unrelated n (γ is odd); two frames share a draw only if that shift is within a few
//! draws of a multiple of 2³² that maps one pixel onto another: about 2⁻³⁸ per pair of
//! 1-Mpixel frames.

use crate::render::sampling::mix64;

/// Domain separator, so the sensor's streams never coincide with the renderer's (which
/// key by (seed, frame, pixel, sample)) even when the same seed is passed.
const FRAME_NOISE_DOMAIN: u64 = 0x53_454e_534f_5232; // "SENSOR2"

/// SplitMix64's increment (2⁶⁴ / φ, odd).
const GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// The key of a frame's noise: every pixel's stream derives from it.
#[inline]
pub fn frame_key(frame_seed: u64) -> u64 {
    mix64(frame_seed ^ FRAME_NOISE_DOMAIN)
}

/// One pixel's draws of one kind in one frame.
#[derive(Clone, Copy, Debug)]
pub struct PixelStream {
    state: u64,
}

/// A pixel's two streams.
#[derive(Clone, Copy, Debug)]
pub struct PixelNoise {
    pub shot: PixelStream,
    pub read: PixelStream,
}

impl PixelNoise {
    /// The streams of `pixel` (its index on the full sensor) under frame key `key`.
    #[inline]
    pub fn new(key: u64, pixel: u64) -> PixelNoise {
        let shot = PixelStream::new(key, pixel, 0);
        // Part 1 is 2³¹ draws on: one add instead of a second multiply.
        PixelNoise { shot, read: PixelStream { state: shot.state.wrapping_add(GAMMA.wrapping_mul(1 << 31)) } }
    }
}

impl PixelStream {
    /// Part `part` (0 or 1) of the streams of `pixel` under frame key `key`.
    #[inline]
    pub fn new(key: u64, pixel: u64, part: u64) -> PixelStream {
        let n = (pixel << 32) | (part << 31);
        PixelStream { state: key.wrapping_add(n.wrapping_mul(GAMMA)) }
    }

    /// The first draw of part `part` of each of the pixels `first..first + out.len()`,
    /// in `out`: a loop without branches, which the compiler vectorises.
    #[inline(always)]
    pub fn first_draws(key: u64, first: u64, part: u64, out: &mut [u64]) {
        // Pixel p + 1's streams start 2³² draws after pixel p's.
        let step = GAMMA.wrapping_mul(1 << 32);
        let s0 = PixelStream::new(key, first, part).state.wrapping_add(GAMMA);
        for (i, o) in out.iter_mut().enumerate() {
            *o = mix64(s0.wrapping_add(step.wrapping_mul(i as u64)));
        }
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GAMMA);
        mix64(self.state)
    }

    /// Uniform in the open interval (0, 1) with 53 random bits: never 0 (so `ln` is
    /// finite) and never 1.
    #[inline]
    pub fn uniform_open(&mut self) -> f64 {
        // Through i64: a 53-bit value converts exactly, and baseline x86-64 converts signed
        // integers in one instruction (unsigned 64-bit ones in several).
        ((self.next_u64() >> 11) as i64 as f64 + 0.5) * (1.0 / 9_007_199_254_740_992.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_keyed_and_follow_splitmix64() {
        // SplitMix64 from state 0: the reference generator's first output.
        let mut s = PixelStream::new(0, 0, 0);
        assert_eq!(s.next_u64(), 0xe220_a839_7b1d_cdaf);
        let a = PixelNoise::new(frame_key(1), 5).shot.next_u64();
        assert_eq!(a, PixelNoise::new(frame_key(1), 5).shot.next_u64());
        let n = PixelNoise::new(frame_key(1), 5);
        assert_eq!(n.read.state, PixelStream::new(frame_key(1), 5, 1).state);
        assert_ne!(a, PixelNoise::new(frame_key(2), 5).shot.next_u64());
        assert_ne!(a, PixelNoise::new(frame_key(1), 6).shot.next_u64());
        assert_ne!(a, PixelNoise::new(frame_key(1), 5).read.next_u64());
        // The read stream starts where the shot stream's 2³¹ draws would end, and pixel
        // p's where pixel p − 1's read stream would.
        let skip = |mut s: PixelStream, n: u64| {
            s.state = s.state.wrapping_add(n.wrapping_mul(GAMMA));
            s
        };
        assert_eq!(PixelStream::new(7, 3, 1).next_u64(), skip(PixelStream::new(7, 3, 0), 1 << 31).next_u64());
        assert_eq!(PixelStream::new(7, 4, 0).next_u64(), skip(PixelStream::new(7, 3, 1), 1 << 31).next_u64());
    }

    #[test]
    fn first_draws_are_each_pixels_first() {
        let mut d = [0u64; 70];
        let first = u32::MAX as u64 - 3;
        PixelStream::first_draws(frame_key(4), first, 0, &mut d);
        for (i, d) in d.iter().enumerate() {
            assert_eq!(*d, PixelStream::new(frame_key(4), first + i as u64, 0).next_u64());
        }
        PixelStream::first_draws(frame_key(4), first, 1, &mut d);
        for (i, d) in d.iter().enumerate() {
            assert_eq!(*d, PixelNoise::new(frame_key(4), first + i as u64).read.next_u64());
        }
    }

    #[test]
    fn uniforms_are_open_and_centred() {
        let mut s = PixelStream::new(frame_key(3), 0, 0);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = s.uniform_open();
            assert!(u > 0.0 && u < 1.0);
            sum += u;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.003);
    }
}
