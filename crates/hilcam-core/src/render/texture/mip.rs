//! A mip-map pyramid of one band: level 0 is the image, each next level the 2×2 box
//! average of the one before (an odd last row or column folds into its neighbour), down
//! to one texel. Box averages keep every level's mean equal to the image's.

/// One level: `w × h` texels, row-major, row 0 at the image's top.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    pub w: u32,
    pub h: u32,
    pub data: Vec<f32>,
}

impl Level {
    #[inline]
    pub fn at(&self, x: u32, y: u32) -> f32 {
        self.data[(y * self.w + x) as usize]
    }
}

/// The pyramid; `levels[0]` is the full-resolution image.
#[derive(Clone, Debug, PartialEq)]
pub struct MipMap {
    pub levels: Vec<Level>,
}

/// Source texels of destination index `i` along an axis of `n` texels: `2i, 2i + 1`, and
/// also `2i + 2` for the last one when `n` is odd.
fn sources(i: u32, n: u32) -> std::ops::Range<u32> {
    let last = i + 1 == (n / 2).max(1);
    let end = if last { n } else { 2 * i + 2 };
    (2 * i).min(n - 1)..end.max(2 * i + 1).min(n.max(1))
}

impl MipMap {
    /// The pyramid of a `w × h` image (`data.len() == w·h`, both ≥ 1).
    pub fn new(w: u32, h: u32, data: Vec<f32>) -> MipMap {
        assert!(w >= 1 && h >= 1 && data.len() == (w * h) as usize, "texture of {w}×{h} with {} texels", data.len());
        let mut levels = vec![Level { w, h, data }];
        while let Some(prev) = levels.last().filter(|l| l.w > 1 || l.h > 1) {
            let (nw, nh) = ((prev.w / 2).max(1), (prev.h / 2).max(1));
            let mut data = Vec::with_capacity((nw * nh) as usize);
            for y in 0..nh {
                let ys = sources(y, prev.h);
                for x in 0..nw {
                    let xs = sources(x, prev.w);
                    let mut sum = 0.0f64;
                    for sy in ys.clone() {
                        for sx in xs.clone() {
                            sum += f64::from(prev.at(sx, sy));
                        }
                    }
                    data.push((sum / (ys.len() * xs.len()) as f64) as f32);
                }
            }
            levels.push(Level { w: nw, h: nh, data });
        }
        MipMap { levels }
    }

    /// Bytes held by all levels (the load report's figure).
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.data.len() * std::mem::size_of::<f32>()).sum()
    }

    /// Level 0's size.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].w, self.levels[0].h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_level_keeps_the_mean_and_halves_down_to_one_texel() {
        let data: Vec<f32> = (0..8 * 4).map(|i| (i * 7 % 5) as f32).collect();
        let mean = data.iter().sum::<f32>() / 32.0;
        let m = MipMap::new(8, 4, data);
        let sizes: Vec<(u32, u32)> = m.levels.iter().map(|l| (l.w, l.h)).collect();
        assert_eq!(sizes, [(8, 4), (4, 2), (2, 1), (1, 1)]);
        for l in &m.levels {
            let lm = l.data.iter().sum::<f32>() / l.data.len() as f32;
            assert!((lm - mean).abs() < 1e-5, "{lm} vs {mean}");
        }
        assert_eq!(m.bytes(), (32 + 8 + 2 + 1) * 4);
    }

    #[test]
    fn odd_sizes_fold_the_last_row_and_column_in() {
        // 3×1: one texel, the mean of all three.
        let m = MipMap::new(3, 1, vec![1.0, 2.0, 6.0]);
        assert_eq!(m.levels[1].data, [3.0]);
        let m = MipMap::new(5, 3, (0..15).map(|i| i as f32).collect());
        assert_eq!((m.levels[1].w, m.levels[1].h), (2, 1));
        // Texel (1, 0) averages columns 2..5 of rows 0..3.
        let want = [2, 3, 4, 7, 8, 9, 12, 13, 14].iter().sum::<i32>() as f32 / 9.0;
        assert!((m.levels[1].at(1, 0) - want).abs() < 1e-6);
    }
}
