//! Low-discrepancy samples: a shuffled, Owen-scrambled Sobol (0,2)-sequence per pair of
//! dimensions (Burley 2020, "Practical Hash-based Owen Scrambling").
//!
//! Each pixel gets its own scramble, keyed like [`Rng`](super::Rng) by
//! (seed, frame, pixel), so images stay independent of thread scheduling. Each 2-D
//! dimension pair (pixel position, each bounce's direction, …) gets an independent index
//! shuffle and scramble, which decorrelates the pairs while keeping every pair's first
//! 2^m samples a (0, m, 2)-net: one sample in every elementary interval.

use super::{Rng, mix64};
use glam::Vec2;

/// Laine–Karras style hash that only lets lower bits affect higher ones: applied to
/// bit-reversed values, it is a nested uniform (Owen) scramble.
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen scramble of a 32-bit binary fraction (most significant bit first).
#[inline]
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// Second Sobol dimension by bit loop (reference for the table version).
pub fn sobol_dim1_reference(mut i: u32) -> u32 {
    let mut r = 0u32;
    let mut v = 1u32 << 31;
    while i != 0 {
        if i & 1 != 0 {
            r ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    r
}

/// The generator matrix is linear over GF(2), so the result is the XOR of the four index
/// bytes' contributions: four lookups instead of a loop over 32 bits (shuffled indices
/// have random high bits). Bit reversal is linear too, so [`SOBOL1_REVERSED_TABLES`]
/// holds the same entries reversed.
const SOBOL1_TABLES: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    // Direction numbers v_k for index bit k.
    let mut v = [0u32; 32];
    let mut k = 0;
    let mut d = 1u32 << 31;
    while k < 32 {
        v[k] = d;
        d ^= d >> 1;
        k += 1;
    }
    let mut byte = 0;
    while byte < 4 {
        let mut b = 0;
        while b < 256 {
            let mut r = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if b & (1 << bit) != 0 {
                    r ^= v[byte * 8 + bit];
                }
                bit += 1;
            }
            t[byte][b] = r;
            b += 1;
        }
        byte += 1;
    }
    t
};

/// [`SOBOL1_TABLES`] with every entry bit-reversed: `sobol_dim1(i).reverse_bits()` without
/// the reversal, which x86 has no instruction for.
const SOBOL1_REVERSED_TABLES: [[u32; 256]; 4] = {
    let mut t = SOBOL1_TABLES;
    let mut byte = 0;
    while byte < 4 {
        let mut b = 0;
        while b < 256 {
            t[byte][b] = t[byte][b].reverse_bits();
            b += 1;
        }
        byte += 1;
    }
    t
};

#[inline]
fn by_bytes(t: &[[u32; 256]; 4], i: u32) -> u32 {
    t[0][(i & 0xff) as usize]
        ^ t[1][((i >> 8) & 0xff) as usize]
        ^ t[2][((i >> 16) & 0xff) as usize]
        ^ t[3][(i >> 24) as usize]
}

/// Second Sobol dimension (the first is the van der Corput radical inverse, `i.reverse_bits()`).
#[inline]
pub fn sobol_dim1(i: u32) -> u32 {
    by_bytes(&SOBOL1_TABLES, i)
}

/// `sobol_dim1(i).reverse_bits()`.
#[inline]
fn sobol_dim1_reversed(i: u32) -> u32 {
    by_bytes(&SOBOL1_REVERSED_TABLES, i)
}

#[inline]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

const PAIR_SALT: u64 = 0x632b_e59b_d9b4_e019;

/// `mix64(pair + PAIR_SALT)` for every pair the sequence serves: a pair's scramble key
/// `mix64(pixel_key ^ mix64(pair + PAIR_SALT))` is then one mix instead of two.
const PAIR_KEYS: [u64; MAX_PAIRS as usize] = {
    let mut t = [0u64; MAX_PAIRS as usize];
    let mut pair = 0;
    while pair < t.len() {
        t[pair] = mix64((pair as u64).wrapping_add(PAIR_SALT));
        pair += 1;
    }
    t
};

/// The samples of one camera sample (pixel, index): 2-D points for successive dimension
/// pairs. After `MAX_PAIRS` pairs it continues with independent random numbers, seeded
/// only then (most paths never get there, and seeding costs as much as a pair).
#[derive(Clone, Debug)]
pub struct SobolStream {
    pixel_key: u64,
    index: u32,
    /// `index.reverse_bits()`, the first step of every pair's index shuffle.
    index_reversed: u32,
    pair: u32,
    rng: Option<Rng>,
}

/// Dimension pairs served by the sequence before falling back to independent numbers
/// (pixel position + 2 pairs per bounce for 4 bounces with room to spare).
const MAX_PAIRS: u32 = 16;

impl SobolStream {
    pub fn new(seed: u64, frame: u64, pixel: u64, index: u32) -> Self {
        let pixel_key = mix64(seed ^ mix64(frame.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ mix64(pixel)));
        SobolStream { pixel_key, index, index_reversed: index.reverse_bits(), pair: 0, rng: None }
    }

    /// The pair's point: the pair's shuffled index `i`, then both Sobol coordinates of `i`
    /// Owen-scrambled, each with its own seed (the definition: `next_2d_reference` in the
    /// tests). The reversals that cancel are left out (`owen_scramble(x, s)` is
    /// `laine_karras(x.reverse_bits(), s).reverse_bits()`): three bit reversals instead of
    /// seven, and one mix per pair.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        if self.pair >= MAX_PAIRS {
            return self.past_the_last_pair();
        }
        let k = (mix64(self.pixel_key ^ PAIR_KEYS[self.pair as usize]) >> 32) as u32;
        self.pair += 1;
        let i = laine_karras(self.index_reversed, k).reverse_bits();
        let x = laine_karras(i, k ^ 0xa511_e9b3).reverse_bits();
        let y = laine_karras(sobol_dim1_reversed(i), k ^ 0x63d8_3595).reverse_bits();
        Vec2::new(to_unit(x), to_unit(y))
    }

    #[cold]
    fn past_the_last_pair(&mut self) -> Vec2 {
        let (key, index) = (self.pixel_key, self.index);
        let rng = self.rng.get_or_insert_with(|| Rng::from_state(mix64(key ^ mix64(u64::from(index) + 1))));
        rng.next_2d()
    }

    /// One number (uses a whole dimension pair; simple and keeps pairs aligned).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        self.next_2d().x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_2_to_the_m_samples_form_a_0m2_net() {
        for m in [2u32, 4, 6] {
            let n = 1u32 << m;
            for pixel in 0..20u64 {
                for pair in 0..3 {
                    let pts: Vec<Vec2> = (0..n)
                        .map(|i| {
                            let mut s = SobolStream::new(7, 1, pixel, i);
                            for _ in 0..pair {
                                s.next_2d();
                            }
                            s.next_2d()
                        })
                        .collect();
                    // Every elementary interval of shape 2^-a × 2^-(m-a) holds one point.
                    for a in 0..=m {
                        let (nx, ny) = (1u32 << a, 1u32 << (m - a));
                        let mut seen = vec![0u32; n as usize];
                        for p in &pts {
                            let (cx, cy) = ((p.x * nx as f32) as u32, (p.y * ny as f32) as u32);
                            seen[(cy * nx + cx) as usize] += 1;
                        }
                        assert!(seen.iter().all(|&c| c == 1), "m={m} a={a} pixel={pixel} pair={pair}: {seen:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn scrambles_differ_between_pixels_and_pairs_and_are_uniform() {
        let a = SobolStream::new(1, 0, 10, 0).next_2d();
        let b = SobolStream::new(1, 0, 11, 0).next_2d();
        assert_ne!(a, b);
        let mut s = SobolStream::new(1, 0, 10, 0);
        let (p0, p1) = (s.next_2d(), s.next_2d());
        assert_ne!(p0, p1);
        // Mean over many pixels' first sample is 1/2 (unbiased scramble).
        let n = 100_000;
        let mean: f64 = (0..n).map(|px| SobolStream::new(3, 0, px, 0).next_2d().y as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.004, "{mean}");
    }

    #[test]
    fn past_the_last_pair_numbers_stay_uniform_and_distinct_per_sample() {
        let n = 50_000u32;
        let mut mean = 0.0f64;
        let mut firsts = std::collections::HashSet::new();
        for i in 0..n {
            let mut s = SobolStream::new(9, 2, u64::from(i % 97), i);
            for _ in 0..MAX_PAIRS {
                s.next_2d();
            }
            let (a, b) = (s.next_2d(), s.next_2d());
            assert_ne!(a, b);
            firsts.insert(a.x.to_bits());
            mean += f64::from(a.x + a.y + b.x + b.y) / 4.0;
        }
        assert!((mean / f64::from(n) - 0.5).abs() < 0.005, "{}", mean / f64::from(n));
        assert!(firsts.len() as f64 > 0.99 * f64::from(n), "{} distinct of {n}", firsts.len());
    }

    /// The definition [`SobolStream::next_2d`] computes, written as it reads.
    fn next_2d_reference(s: &mut SobolStream) -> Vec2 {
        if s.pair >= MAX_PAIRS {
            return s.past_the_last_pair();
        }
        let k = (mix64(s.pixel_key ^ mix64(u64::from(s.pair).wrapping_add(PAIR_SALT))) >> 32) as u32;
        s.pair += 1;
        let i = owen_scramble(s.index, k);
        let x = owen_scramble(i.reverse_bits(), k ^ 0xa511_e9b3);
        let y = owen_scramble(sobol_dim1(i), k ^ 0x63d8_3595);
        Vec2::new(to_unit(x), to_unit(y))
    }

    #[test]
    fn next_2d_is_the_reference_bit_for_bit() {
        let mut r = Rng::from_state(11);
        for n in 0..20_000u32 {
            let (pixel, index) = (u64::from(r.next_u32()), if n < 4096 { n } else { r.next_u32() });
            let (mut fast, mut reference) =
                (SobolStream::new(5, 3, pixel, index), SobolStream::new(5, 3, pixel, index));
            for pair in 0..MAX_PAIRS + 2 {
                let (a, b) = (fast.next_2d(), next_2d_reference(&mut reference));
                assert_eq!(
                    (a.x.to_bits(), a.y.to_bits()),
                    (b.x.to_bits(), b.y.to_bits()),
                    "pixel {pixel} index {index} pair {pair}"
                );
            }
        }
    }

    #[test]
    fn reversed_table_is_the_reversed_sobol_dimension() {
        let mut r = Rng::from_state(6);
        for i in (0..4096u32).chain((0..10_000).map(|_| r.next_u32())).chain([u32::MAX]) {
            assert_eq!(sobol_dim1_reversed(i), sobol_dim1(i).reverse_bits(), "index {i}");
        }
    }

    #[test]
    fn table_sobol_matches_the_bit_loop() {
        let mut r = Rng::from_state(5);
        for i in (0..4096u32).chain((0..10_000).map(|_| r.next_u32())).chain([u32::MAX]) {
            assert_eq!(sobol_dim1(i), sobol_dim1_reference(i), "index {i}");
        }
    }

    #[test]
    fn owen_scramble_is_a_bijection_on_the_top_bits() {
        let mut seen = [false; 256];
        for i in 0..256u32 {
            let x = owen_scramble(i << 24, 0x1234_5678) >> 24;
            assert!(!seen[x as usize]);
            seen[x as usize] = true;
        }
    }
}
