//! Where a ray first crosses a sphere, in f64 without cancellation: a planet 1e7 m away
//! seen from a ray that starts a metre from the target's centre.
//!
//! The textbook `b² − c` loses every digit when the sphere is far and large (both terms
//! ~1e14 m², their difference the square of a few metres near the limb). As in pbrt-v4
//! (and "Ray Tracing Gems", ch. 7), the discriminant is `r² − |f⊥|²` written
//! `(r − |f⊥|)(r + |f⊥|)`, with `f⊥` the part of the origin's offset across the ray; the near
//! root is `c / q` with `q = −b + √disc` (no difference of near-equal numbers), and
//! `c = |f|² − r²` is `(|f| − r)(|f| + r)`.

use glam::DVec3;

/// Where a ray starting at `o` along the unit vector `d` meets the sphere (centre `c`,
/// radius `r`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Crossing {
    /// The ray misses the sphere (or it lies behind the origin), or an input is not finite.
    Miss,
    /// The ray enters the sphere at distance `t` (> 0).
    Enters(f64),
    /// The origin lies inside (or on) the sphere.
    Inside,
}

/// The first crossing of the ray `o + t·d` (`d` unit) with the sphere of centre `c`,
/// radius `r`.
#[inline]
pub fn first_crossing(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Crossing {
    let f = o - c;
    let fl = f.length();
    let outside = (fl - r) * (fl + r); // |f|² − r²
    if !outside.is_finite() {
        return Crossing::Miss;
    }
    if outside <= 0.0 {
        return Crossing::Inside;
    }
    let b = f.dot(d);
    if b.is_nan() || b >= 0.0 {
        return Crossing::Miss; // the centre is behind (or beside) the origin: the sphere too
    }
    let h = (f - b * d).length(); // the line's distance from the centre
    let disc = (r - h) * (r + h);
    if disc.is_nan() || disc < 0.0 {
        return Crossing::Miss;
    }
    let q = -b + disc.sqrt(); // > 0: the far root, without cancellation
    Crossing::Enters(outside / q)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_a_unit_sphere_where_the_algebra_says() {
        let c = DVec3::new(0.0, 0.0, 5.0);
        assert_eq!(first_crossing(DVec3::ZERO, DVec3::Z, c, 1.0), Crossing::Enters(4.0));
        assert_eq!(first_crossing(DVec3::ZERO, -DVec3::Z, c, 1.0), Crossing::Miss);
        assert_eq!(first_crossing(DVec3::ZERO, DVec3::X, c, 1.0), Crossing::Miss);
        assert_eq!(first_crossing(c, DVec3::X, c, 1.0), Crossing::Inside);
        // A ray 0.6 off the centre line: enters at z = 5 − 0.8.
        match first_crossing(DVec3::new(0.6, 0.0, 0.0), DVec3::Z, c, 1.0) {
            Crossing::Enters(t) => assert!((t - 4.2).abs() < 1e-15, "{t}"),
            x => panic!("{x:?}"),
        }
        assert_eq!(first_crossing(DVec3::splat(f64::NAN), DVec3::Z, c, 1.0), Crossing::Miss);
    }

    #[test]
    fn earth_seen_from_orbit_keeps_its_metres() {
        // Earth's radius, centre 6771 km away (400 km altitude). A ray grazing 10 m inside
        // the limb: the tangent distance is √(D² − R²) and the chord's half-length
        // √(R² − h²); the near crossing is their difference, ~1.13e5 m short of the
        // tangent point. Within a millimetre (the expected value's own f64 rounding on
        // numbers of 1e6 m is ~1e-9 m; the margin is for the direction's).
        let (r, dist) = (6.371e6_f64, 6.771e6_f64);
        let h = r - 10.0;
        let tangent = (dist * dist - r * r).sqrt();
        // Direction at angle asin(h / D) from the centre line.
        let s = h / dist;
        let d = DVec3::new(s, 0.0, (1.0 - s * s).sqrt());
        let c = DVec3::new(0.0, 0.0, dist);
        let along = (dist * dist - h * h).sqrt(); // distance to the foot of the perpendicular
        let expected = along - (r * r - h * h).sqrt();
        let Crossing::Enters(t) = first_crossing(DVec3::ZERO, d, c, r) else { panic!("miss") };
        assert!((t - expected).abs() < 1e-6 * 1e3, "t {t} expected {expected}");
        assert!(t < tangent);
        // The crossing lies on the sphere to a micrometre per megametre.
        let p = d * t;
        assert!(((p - c).length() - r).abs() < 1e-2, "{}", (p - c).length() - r);
    }
}
