//! OBJ faces of more than three vertices. tobj cuts each into a fan from its first vertex,
//! which covers the polygon only when every fan triangle turns the same way (a convex
//! face, or a concave one whose first vertex sees all the others); otherwise the fan folds
//! over itself and covers the wrong area, without a word. Such faces are noted here by
//! file and line, so the author can triangulate them in the exporter.

use glam::DVec3;

/// Notes about the first this many folded faces of a file, then a count of the rest.
const MAX_NOTES: usize = 5;

/// A note for each face of `text` (file name `file`) whose fan from its first vertex folds.
pub fn folded_fan_notes(file: &str, text: &str) -> Vec<String> {
    let mut positions: Vec<DVec3> = Vec::new();
    let mut folded: Vec<(usize, usize)> = Vec::new(); // (line, vertices)
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f64> = words.take(3).filter_map(|w| w.parse().ok()).collect();
                positions.push(if c.len() == 3 { DVec3::new(c[0], c[1], c[2]) } else { DVec3::NAN });
            }
            Some("f") => {
                let n = positions.len() as i64;
                // A vertex is `v`, `v/vt`, `v//vn` or `v/vt/vn`; negative counts back.
                let face: Option<Vec<DVec3>> = words
                    .map(|w| {
                        let k: i64 = w.split('/').next()?.parse().ok()?;
                        let at = if k > 0 { k - 1 } else { n + k };
                        positions.get(usize::try_from(at).ok()?).copied()
                    })
                    .collect();
                // Faces tobj refuses (bad indices) are its error to report.
                if let Some(p) = face.filter(|p| p.len() > 3)
                    && fan_folds(&p)
                {
                    folded.push((i + 1, p.len()));
                }
            }
            _ => {}
        }
    }
    let mut notes: Vec<String> = folded
        .iter()
        .take(MAX_NOTES)
        .map(|(line, n)| {
            format!(
                "face of {n} vertices is concave at its first vertex: the fan it is cut into folds over \
                 itself and covers the wrong area (triangulate it in the exporter): {file}:{line}"
            )
        })
        .collect();
    if folded.len() > MAX_NOTES {
        notes.push(format!("{} more such faces in {file}", folded.len() - MAX_NOTES));
    }
    notes
}

/// Whether the fan (p₀, pᵢ, pᵢ₊₁) of polygon `p` has a triangle turning against the
/// polygon's own normal (Newell's, robust for a slightly non-planar face).
fn fan_folds(p: &[DVec3]) -> bool {
    let normal: DVec3 = (0..p.len()).map(|i| p[i].cross(p[(i + 1) % p.len()])).sum();
    let scale = normal.length();
    if scale.is_nan() || scale <= 0.0 || scale.is_infinite() {
        return false; // degenerate (or not finite): nothing to fold
    }
    (1..p.len() - 1).any(|i| (p[i] - p[0]).cross(p[i + 1] - p[0]).dot(normal) < -1e-9 * scale * scale)
}

#[cfg(test)]
mod tests {
    use super::folded_fan_notes;

    /// An L-shaped hexagon; `start` rotates which vertex comes first.
    fn l_shape(start: usize) -> String {
        let v = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n";
        let f: Vec<String> = (0..6).map(|k| ((start + k) % 6 + 1).to_string()).collect();
        format!("{v}f {}\n", f.join(" "))
    }

    #[test]
    fn an_l_shape_folds_only_from_a_corner_that_does_not_see_all_others() {
        // From (0,0) every vertex is visible: the fan covers the L.
        assert!(folded_fan_notes("l.obj", &l_shape(0)).is_empty());
        // From (2,0) the notch's corner (1,1) turns the fan back.
        let notes = folded_fan_notes("l.obj", &l_shape(1));
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("face of 6 vertices") && notes[0].ends_with("l.obj:7"), "{}", notes[0]);
    }

    #[test]
    fn negative_and_slashed_indices_resolve_and_convex_faces_pass() {
        let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4/1/1 -3/2/1 -2//1 -1\nf 1 2 3\n";
        assert!(folded_fan_notes("q.obj", obj).is_empty());
        // Out-of-range indices are tobj's to refuse, not a note (nor a panic).
        assert!(folded_fan_notes("q.obj", "v 0 0 0\nf 1 2 3 9\nf -9 1 1 1\n").is_empty());
    }

    #[test]
    fn many_folded_faces_are_noted_five_times_then_counted() {
        let mut obj = l_shape(1);
        for _ in 0..7 {
            obj.push_str("f 2 3 4 5 6 1\n");
        }
        let notes = folded_fan_notes("m.obj", &obj);
        assert_eq!(notes.len(), 6, "{notes:?}");
        assert_eq!(notes[5], "3 more such faces in m.obj");
    }
}
