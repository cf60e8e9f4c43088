//! Lookups: bilinear within a level (texel centres at `(i + ½)/w`, coordinates wrapped:
//! glTF's default `REPEAT`, and what OBJ exporters mean by UVs outside [0, 1]), and
//! trilinear between the two levels whose texel size brackets a footprint.

use super::mip::{Level, MipMap};

/// `v` wrapped into `[0, n)`, as an index.
#[inline]
fn wrap(i: i64, n: u32) -> u32 {
    i.rem_euclid(i64::from(n)) as u32
}

/// Bilinear value of `level` at texture coordinate `(s, t)` (`t` = 0 at the image's top).
#[inline]
pub fn bilinear(level: &Level, s: f32, t: f32) -> f32 {
    let x = f64::from(s) * f64::from(level.w) - 0.5;
    let y = f64::from(t) * f64::from(level.h) - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let (xa, xb) = (wrap(x0, level.w), wrap(x0 + 1, level.w));
    let (ya, yb) = (wrap(y0, level.h), wrap(y0 + 1, level.h));
    let top = level.at(xa, ya) * (1.0 - fx) + level.at(xb, ya) * fx;
    let bottom = level.at(xa, yb) * (1.0 - fx) + level.at(xb, yb) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The value at `(s, t)` prefiltered over a footprint `width` wide in texture
/// coordinates (1 = the whole image): the level whose texels are `width` across, linearly
/// between the two nearest. A footprint below one level-0 texel is plain bilinear.
#[inline]
pub fn trilinear(mip: &MipMap, s: f32, t: f32, width: f32) -> f32 {
    let (w, h) = mip.size();
    let texels = width * w.max(h) as f32;
    let last = (mip.levels.len() - 1) as f32;
    let lod = if texels > 1.0 { texels.log2().min(last) } else { 0.0 };
    if lod <= 0.0 {
        return bilinear(&mip.levels[0], s, t);
    }
    let l0 = lod.floor();
    let f = lod - l0;
    let a = bilinear(&mip.levels[l0 as usize], s, t);
    if f == 0.0 {
        return a;
    }
    a * (1.0 - f) + bilinear(&mip.levels[l0 as usize + 1], s, t) * f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_hits_texel_centres_and_interpolates_between_them() {
        let m = MipMap::new(2, 2, vec![0.0, 1.0, 2.0, 3.0]);
        let l = &m.levels[0];
        assert_eq!(bilinear(l, 0.25, 0.25), 0.0);
        assert_eq!(bilinear(l, 0.75, 0.25), 1.0);
        assert_eq!(bilinear(l, 0.25, 0.75), 2.0);
        assert_eq!(bilinear(l, 0.5, 0.25), 0.5);
        // Wrapped: s = 0 is halfway between the last column and the first.
        assert_eq!(bilinear(l, 0.0, 0.25), 0.5);
        assert_eq!(bilinear(l, 1.25, -0.75), 0.0);
    }

    #[test]
    fn the_footprint_picks_the_level() {
        let data: Vec<f32> = (0..16 * 16).map(|i| ((i % 16 + i / 16) % 2) as f32).collect();
        let m = MipMap::new(16, 16, data);
        // A texel-wide footprint: level 0 (a check's own value at its centre).
        assert_eq!(trilinear(&m, 0.5 / 16.0, 0.5 / 16.0, 1.0 / 16.0), 0.0);
        // Two texels: level 1, the checkerboard's mean everywhere.
        assert_eq!(trilinear(&m, 0.5 / 16.0, 0.5 / 16.0, 2.0 / 16.0), 0.5);
        // Between: linear in log2 of the width.
        let v = trilinear(&m, 0.5 / 16.0, 0.5 / 16.0, 2f32.sqrt() / 16.0);
        assert!((v - 0.25).abs() < 1e-6, "{v}");
        // Wider than the image: the last level.
        assert_eq!(trilinear(&m, 0.3, 0.7, 10.0), 0.5);
    }
}
