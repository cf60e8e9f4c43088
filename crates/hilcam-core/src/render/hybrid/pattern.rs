//! Where a pixel's coverage samples lie: 64 points, one in each cell of an 8 × 8 grid
//! (jittered), from a fixed table of patterns; each pixel of each frame takes one pattern
//! and a toroidal shift from its random key. A shifted jittered grid is still one point
//! per (shifted) cell, so the pixel-area estimate keeps its stratification, while its error
//! changes from seed to seed and pixel to pixel (noise, not a fixed pattern).

use crate::render::sampling::{Rng, mix64};
use std::sync::OnceLock;

/// Samples per pixel.
pub const SAMPLES: usize = 64;
const SIDE: usize = 8;
const PATTERNS: usize = 128;

/// The table: `PATTERNS` jittered grids, x then y.
fn table() -> &'static [[[f32; SAMPLES]; 2]; PATTERNS] {
    static T: OnceLock<Box<[[[f32; SAMPLES]; 2]; PATTERNS]>> = OnceLock::new();
    T.get_or_init(|| {
        let mut t = Box::new([[[0.0; SAMPLES]; 2]; PATTERNS]);
        let mut rng = Rng::from_state(0x6879_6272_6964_5041); // "hybridPA"
        for [xs, ys] in t.iter_mut() {
            for (k, (x, y)) in xs.iter_mut().zip(ys.iter_mut()).enumerate() {
                let (i, j) = (k % SIDE, k / SIDE);
                *x = (i as f32 + rng.next_f32()) / SIDE as f32;
                *y = (j as f32 + rng.next_f32()) / SIDE as f32;
            }
        }
        t
    })
}

/// The coverage samples of the pixel with random key `key` in frame (`seed`, `frame`):
/// offsets in [0, 1)² from the pixel's corner, into `x` and `y`.
#[inline(never)]
pub fn fill(seed: u64, frame: u64, key: u64, x: &mut [f32; SAMPLES], y: &mut [f32; SAMPLES]) {
    let Choice { pattern, dx, dy, swap, mirror } = choose(seed, frame, key);
    let p = &table()[pattern];
    let (px, py) = if swap { (&p[1], &p[0]) } else { (&p[0], &p[1]) };
    for k in 0..SAMPLES {
        let sx = if mirror { 1.0 - px[k] } else { px[k] };
        let a = sx + dx;
        let b = py[k] + dy;
        // frac, and never 1.0 (1 − tiny rounds to 1 in f32 only from the mirror at 0).
        x[k] = (if a >= 1.0 { a - 1.0 } else { a }).min(ONE_BELOW);
        y[k] = (if b >= 1.0 { b - 1.0 } else { b }).min(ONE_BELOW);
    }
}

/// A pixel's pattern, shift, transpose and mirror.
struct Choice {
    pattern: usize,
    dx: f32,
    dy: f32,
    swap: bool,
    mirror: bool,
}

#[inline]
fn choose(seed: u64, frame: u64, key: u64) -> Choice {
    let h = mix64(mix64(seed ^ mix64(frame ^ 0x636f_7665_7261_6765)) ^ key.wrapping_mul(0x9e37_79b9_7f4a_7c15)); // "coverage"
    Choice {
        pattern: (h as usize) % PATTERNS,
        dx: ((h >> 8) & 0xff_ffff) as f32 * (1.0 / 16_777_216.0),
        dy: ((h >> 32) & 0xff_ffff) as f32 * (1.0 / 16_777_216.0),
        // A transpose or a mirror as well, from two more bits (more patterns, same cells).
        swap: h >> 60 & 1 == 1,
        mirror: h >> 61 & 1 == 1,
    }
}

/// The largest f32 below 1.
const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_cell_of_the_shifted_grid_holds_one_sample() {
        for key in 0..200u64 {
            let (mut x, mut y) = ([0.0; SAMPLES], [0.0; SAMPLES]);
            fill(3, 7, key, &mut x, &mut y);
            assert!(x.iter().chain(&y).all(|v| (0.0..1.0).contains(v)));
            // Undo the shift: each cell of the 8 × 8 grid holds exactly one sample.
            let c = choose(3, 7, key);
            let mut cells = [0u32; SAMPLES];
            for k in 0..SAMPLES {
                let cell = |v: f32, d: f32| (((v - d).rem_euclid(1.0) * SIDE as f32) as usize).min(SIDE - 1);
                cells[cell(y[k], c.dy) * SIDE + cell(x[k], c.dx)] += 1;
            }
            // A sample within f32 rounding of a cell border may land in the next cell.
            let misplaced = cells.iter().filter(|&&n| n != 1).count();
            assert!(misplaced <= 2, "key {key}: {cells:?}");
        }
    }

    #[test]
    fn patterns_differ_between_pixels_and_seeds_and_repeat_for_the_same_key() {
        let get = |seed, key| {
            let (mut x, mut y) = ([0.0; SAMPLES], [0.0; SAMPLES]);
            fill(seed, 0, key, &mut x, &mut y);
            (x, y)
        };
        assert_eq!(get(1, 5), get(1, 5));
        assert_ne!(get(1, 5), get(1, 6));
        assert_ne!(get(1, 5), get(2, 5));
    }
}
