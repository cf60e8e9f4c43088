//! The BVH (both obvhs layouts) against a brute-force loop over all triangles.

use glam::Vec3;
use hilcam_core::render::geometry::bvh::brute_force;
use hilcam_core::render::geometry::{Accel, BvhLayout, Ray, TriMesh};
use hilcam_core::render::sampling::Rng;

fn random_vec(r: &mut Rng, scale: f32) -> Vec3 {
    (Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 2.0 - 1.0) * scale
}

/// A triangle soup: random triangles of mixed sizes in a 2 m box, some nearly degenerate.
fn soup(n: usize, seed: u64) -> TriMesh {
    let mut r = Rng::from_state(seed);
    let mut m = TriMesh::default();
    for i in 0..n {
        let c = random_vec(&mut r, 1.0);
        let size = if i % 10 == 0 { 0.5 } else { 0.05 };
        let a = c + random_vec(&mut r, size);
        let b = c + random_vec(&mut r, size);
        // Every 50th triangle is a sliver: its third vertex almost on the first edge.
        let d = if i % 50 == 0 { a + (b - a) * 0.5 + random_vec(&mut r, 1e-6) } else { c + random_vec(&mut r, size) };
        let base = m.positions.len() as u32;
        m.positions.extend([a, b, d]);
        m.indices.push([base, base + 1, base + 2]);
        m.material.push(0);
    }
    m
}

#[test]
fn closest_hit_and_occlusion_match_brute_force() {
    let mesh = soup(3000, 1);
    let mut r = Rng::from_state(2);
    for layout in [BvhLayout::Bvh2, BvhLayout::Cwbvh, BvhLayout::Bvh4, BvhLayout::Bvh8] {
        let accel = Accel::build(&mesh, layout);
        let (mut hits, mut occl) = (0, 0);
        for i in 0..4000 {
            // Mix: rays from outside toward the box, rays from inside in random directions,
            // and finite-length (shadow-like) segments.
            let origin = if i % 2 == 0 { random_vec(&mut r, 3.0) } else { random_vec(&mut r, 0.8) };
            let target = random_vec(&mut r, 1.0);
            let dir = (target - origin).normalize_or(Vec3::Z);
            let tmax = if i % 3 == 0 { r.next_f32() * 2.0 } else { f32::INFINITY };
            let ray = Ray { origin, dir, tmax };
            let got = accel.intersect(&ray);
            let want = brute_force::intersect(&mesh, &ray);
            match (got, want) {
                (Some(g), Some(w)) => {
                    hits += 1;
                    assert!((g.t - w.t).abs() <= 1e-6 * w.t.max(1.0), "{layout:?} ray {i}: t {} vs {}", g.t, w.t);
                    // Equal t with a different triangle is a legitimate tie only.
                    if g.tri != w.tri {
                        assert_eq!(g.t, w.t, "{layout:?} ray {i}: tri {} vs {}", g.tri, w.tri);
                    }
                }
                (None, None) => {}
                (g, w) => panic!("{layout:?} ray {i}: bvh {g:?}, brute force {w:?}"),
            }
            let o = accel.occluded(&ray);
            assert_eq!(o, brute_force::occluded(&mesh, &ray), "{layout:?} ray {i}: occlusion");
            occl += o as u32;
        }
        assert!(hits > 1000 && occl > 1000, "{layout:?}: the test must exercise hits ({hits}) and occlusion ({occl})");
    }
}

#[test]
fn empty_mesh_never_hits() {
    let accel = Accel::build(&TriMesh::default(), BvhLayout::Bvh2);
    let ray = Ray { origin: Vec3::ZERO, dir: Vec3::X, tmax: f32::INFINITY };
    assert!(accel.intersect(&ray).is_none() && !accel.occluded(&ray));
}
