//! The exact area of a triangle inside a pixel: the triangle (ideal image plane) taken to
//! the pixel's own coordinates by the inverse of the pixel's affine map, clipped to the
//! unit square (Sutherland–Hodgman), its area and centroid by the shoelace formula.
//!
//! Where every triangle a pixel's samples see is seen whole there (no other triangle in
//! front of any part of it inside the pixel), the pixel's coverage is these areas exactly:
//! no sampling noise at silhouettes against space, creases and material borders.

/// Most vertices of a triangle clipped by four half-planes.
const MAX_VERTS: usize = 7;

/// Area (fraction of the pixel) and centroid (offset in the pixel) of the triangle with
/// ideal-plane vertices `v` inside the pixel whose affine map is `m` (corner, then the
/// ideal offsets of unit steps in x and in y). None for a degenerate map.
pub fn clipped(v: &[[f64; 2]; 3], m: &[f64; 6]) -> Option<(f64, [f64; 2])> {
    let det = m[2] * m[5] - m[4] * m[3];
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // Pixel-local coordinates: q = J⁻¹ (p − corner), J = [[m2, m4], [m3, m5]].
    let local = |p: [f64; 2]| {
        let (dx, dy) = (p[0] - m[0], p[1] - m[1]);
        [(m[5] * dx - m[4] * dy) / det, (-m[3] * dx + m[2] * dy) / det]
    };
    let mut poly = [[0.0; 2]; MAX_VERTS + 1];
    let mut n = 3;
    for (k, p) in v.iter().enumerate() {
        poly[k] = local(*p);
    }
    // Most pixels lie wholly inside one triangle, and a small one wholly inside a pixel:
    // no clipping needed for either.
    if covers_unit_square(&poly[..3]) {
        return Some((1.0, [0.5, 0.5]));
    }
    if poly[..3].iter().all(|p| (0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1])) {
        let [a, b, c] = [poly[0], poly[1], poly[2]];
        let a2 = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        return Some(((a2 * 0.5).abs(), [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]));
    }
    let mut tmp = [[0.0; 2]; MAX_VERTS + 1];
    // Keep the side where `axis` coordinate is ≥ `bound` (`keep_above`) or ≤ it.
    for (axis, bound, keep_above) in [(0, 0.0, true), (0, 1.0, false), (1, 0.0, true), (1, 1.0, false)] {
        let inside = |p: &[f64; 2]| if keep_above { p[axis] >= bound } else { p[axis] <= bound };
        let mut out = 0;
        for i in 0..n {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            let (ia, ib) = (inside(&a), inside(&b));
            if ia {
                tmp[out] = a;
                out += 1;
            }
            if ia != ib {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                let mut c = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                c[axis] = bound;
                tmp[out] = c;
                out += 1;
            }
        }
        n = out.min(MAX_VERTS);
        poly[..n].copy_from_slice(&tmp[..n]);
        if n < 3 {
            return Some((0.0, [0.5, 0.5]));
        }
    }
    let (mut a2, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (p, q) = (poly[i], poly[(i + 1) % n]);
        let c = p[0] * q[1] - q[0] * p[1];
        a2 += c;
        cx += (p[0] + q[0]) * c;
        cy += (p[1] + q[1]) * c;
    }
    if a2 == 0.0 {
        return Some((0.0, [0.5, 0.5]));
    }
    Some(((a2 * 0.5).abs(), [cx / (3.0 * a2), cy / (3.0 * a2)]))
}

/// True when the triangle `t` (pixel-local) holds all four corners of the unit square.
#[inline]
fn covers_unit_square(t: &[[f64; 2]]) -> bool {
    let side = |a: [f64; 2], b: [f64; 2], p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
    let orient = side(t[0], t[1], t[2]);
    if orient == 0.0 {
        return false;
    }
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
        .iter()
        .all(|&p| (0..3).all(|e| side(t[e], t[(e + 1) % 3], p) * orient >= 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: [f64; 6] = [10.0, 20.0, 1.0, 0.0, 0.0, 1.0];

    #[test]
    fn a_triangle_covering_the_pixel_has_its_whole_area_and_centre() {
        let v = [[0.0, 0.0], [40.0, 0.0], [0.0, 40.0]];
        let (a, c) = clipped(&v, &UNIT).unwrap();
        assert!((a - 1.0).abs() < 1e-12 && (c[0] - 0.5).abs() < 1e-12 && (c[1] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_diagonal_cuts_the_pixel_in_half_and_the_two_halves_sum_to_one() {
        // The pixel's diagonal from (10, 20) to (11, 21) as the shared edge of two triangles.
        let lower = [[0.0, 10.0], [30.0, 40.0], [30.0, 0.0]];
        let upper = [[0.0, 10.0], [0.0, 40.0], [30.0, 40.0]];
        let (a, ca) = clipped(&lower, &UNIT).unwrap();
        let (b, _) = clipped(&upper, &UNIT).unwrap();
        assert!((a - 0.5).abs() < 1e-12 && (b - 0.5).abs() < 1e-12, "{a} {b}");
        // The lower-right half's centroid: (2/3, 1/3).
        assert!((ca[0] - 2.0 / 3.0).abs() < 1e-12 && (ca[1] - 1.0 / 3.0).abs() < 1e-12, "{ca:?}");
    }

    #[test]
    fn a_skewed_pixel_map_measures_area_in_pixels() {
        // A lens-scaled pixel: unit steps are 0.9 ideal px in x and 1.1 in y, sheared.
        let m = [0.0, 0.0, 0.9, 0.05, 0.02, 1.1];
        // The pixel's own image on the ideal plane, as two triangles: each half the pixel.
        let c = |x: f64, y: f64| [m[0] + m[2] * x + m[4] * y, m[1] + m[3] * x + m[5] * y];
        let (a, _) = clipped(&[c(0.0, 0.0), c(1.0, 0.0), c(1.0, 1.0)], &m).unwrap();
        assert!((a - 0.5).abs() < 1e-12, "{a}");
    }

    #[test]
    fn a_triangle_outside_has_no_area() {
        let (a, _) = clipped(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], &UNIT).unwrap();
        assert_eq!(a, 0.0);
    }

    #[test]
    fn a_triangle_inside_the_pixel_is_its_own_area_and_centroid() {
        let v = [[10.2, 20.1], [10.9, 20.3], [10.4, 20.8]];
        let (a, c) = clipped(&v, &UNIT).unwrap();
        let twice = (0.7 * 0.7 - 0.2 * 0.2f64).abs();
        assert!((a - twice / 2.0).abs() < 1e-12, "{a}");
        assert!((c[0] - 0.5).abs() < 1e-12 && (c[1] - 0.4).abs() < 1e-12, "{c:?}");
        // The same triangle nudged over the pixel's edge is clipped: less area.
        let w = v.map(|p| [p[0] + 0.15, p[1]]);
        assert!(clipped(&w, &UNIT).unwrap().0 < a);
    }
}
