//! Small geometry on the ideal (undistorted) image plane, shared by the coverage marks and
//! the primary raster: the cells a pixel rectangle's samples can fall in, a triangle's
//! extent within a row slab, and a fast floor.

use crate::render::camera::{PixelRect, View};

/// `⌊v⌋` for |v| < 2³¹ (a truncating conversion: `f64::floor` is a libm call on the
/// x86-64 baseline).
#[inline(always)]
pub(super) fn floor_i32(v: f64) -> i32 {
    let t = v as i32;
    if f64::from(t) > v { t - 1 } else { t }
}

/// The x-extent of the part of triangle `p` with `slab.0 ≤ y ≤ slab.1`, if any: over
/// its vertices inside the slab and its edges' crossings of the slab's two lines.
pub(super) fn slab_x_extent(p: [(f64, f64); 3], slab: (f64, f64)) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |x: f64| {
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        if a.1 >= slab.0 && a.1 <= slab.1 {
            take(a.0);
        }
        for line in [slab.0, slab.1] {
            if (a.1 - line) * (b.1 - line) < 0.0 {
                take(a.0 + (line - a.1) / (b.1 - a.1) * (b.0 - a.0));
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// The ideal-image cells (inclusive) that samples of pixels in `rect` can fall in: `rect`
/// itself for a pinhole; through a lens, the bounding box of the rectangle's outline
/// mapped to the ideal plane, with a margin.
pub(super) fn ideal_region(view: &View, rect: PixelRect) -> Option<(i32, i32, i32, i32)> {
    let (c0, c1, r0, r1) = (f64::from(rect.col0), f64::from(rect.col1), f64::from(rect.row0), f64::from(rect.row1));
    let mut lo = (c0, r0);
    let mut hi = (c1, r1);
    if view.has_distortion() {
        let steps = 256;
        for i in 0..=steps {
            let a = f64::from(i) / f64::from(steps);
            for (x, y) in
                [(c0 + a * (c1 - c0), r0), (c0 + a * (c1 - c0), r1), (c0, r0 + a * (r1 - r0)), (c1, r0 + a * (r1 - r0))]
            {
                let [ix, iy] = view.ideal_of_pixel(x, y);
                if !ix.is_finite() || !iy.is_finite() {
                    return None;
                }
                lo = (lo.0.min(ix), lo.1.min(iy));
                hi = (hi.0.max(ix), hi.1.max(iy));
            }
        }
        let pad = 0.02 * (hi.0 - lo.0).max(hi.1 - lo.1) + 2.0;
        lo = (lo.0 - pad, lo.1 - pad);
        hi = (hi.0 + pad, hi.1 + pad);
        if (hi.0 - lo.0).max(hi.1 - lo.1) > 1e6 {
            return None;
        }
    }
    Some((lo.0.floor() as i32, hi.0.floor() as i32, lo.1.floor() as i32, hi.1.floor() as i32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_i32_matches_floor() {
        for v in [-3.5, -3.0, -0.5, -1e-12, 0.0, 1e-12, 0.5, 2.0, 2.999_999, 1e6 + 0.25, -1e6 - 0.25] {
            assert_eq!(floor_i32(v), v.floor() as i32, "{v}");
        }
    }

    #[test]
    fn slab_x_extent_of_a_triangle() {
        let t = [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)];
        // Row band 4..5: the triangle spans x from 0 to 10 − 4 = 6 there.
        assert_eq!(slab_x_extent(t, (4.0, 5.0)), Some((0.0, 6.0)));
        // A band the triangle crosses entirely: its full width at the lower line.
        assert_eq!(slab_x_extent(t, (-1.0, 11.0)), Some((0.0, 10.0)));
        assert_eq!(slab_x_extent(t, (10.5, 12.0)), None);
        // A thin sliver from (0, 0) to (100, 1): in band 0.4..0.6 only x 40..60.
        let sliver = [(0.0, 0.0), (100.0, 1.0), (100.0, 1.0 + 1e-9)];
        let (a, b) = slab_x_extent(sliver, (0.4, 0.6)).unwrap();
        assert!((a - 40.0).abs() < 1e-6 && (b - 60.0).abs() < 1e-3, "{a} {b}");
    }
}
