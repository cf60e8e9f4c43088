//! Closest hits eight rays at a time (`Accel::intersect_packet`, `geometry::closest_packet`):
//! every lane's `t` must be brute force's and the single-ray walk's bit for bit, and its
//! triangle the same one or one tied at exactly that `t`; on triangle soups (slivers,
//! zero-area and axis-aligned triangles; coherent primary-like packets, random ones, axis
//! and signed-zero directions, rays through vertices and edges, finite `tmax`) and on the
//! rays of a satellite frame.

use glam::Vec3;
use hilcam_core::render::geometry::bvh::brute_force;
use hilcam_core::render::geometry::{Accel, BvhLayout, Hit, Ray, TriMesh};
use hilcam_core::render::sampling::Rng;
use obvhs::{ray::Ray as ObRay, rt_triangle::RtTriangle};

use crate::common;
use common::soup::{random_vec, soup, surface_point};

const PACKET: usize = hilcam_core::render::geometry::shadow_packet::PACKET;

/// `t` of `ray` against triangle `i` of `mesh` by obvhs's own test (infinity for a miss).
fn t_of(mesh: &TriMesh, i: u32, ray: &Ray) -> f32 {
    let [a, b, c] = mesh.triangle(i as usize);
    let ob = ObRay::new(ray.origin.into(), ray.dir.into(), 0.0, ray.tmax);
    RtTriangle::new(a.into(), b.into(), c.into()).intersect(&ob)
}

/// The sign bit of an f32.
const SIGN: u32 = 1 << 31;

/// Same distance; `0.0` and `-0.0` count as one (the walks may meet tied zeros in another
/// order).
fn same_t(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0)
}

/// Checks one answer against brute force; returns whether the triangle differs by a tie.
fn check(mesh: &TriMesh, ray: &Ray, got: Option<Hit>, label: &str) -> bool {
    let want = brute_force::intersect(mesh, ray);
    match (got, want) {
        (None, None) => false,
        (Some(g), Some(w)) => {
            assert!(same_t(g.t, w.t), "{label}: t {} vs brute force {}", g.t, w.t);
            if g.tri == w.tri {
                return false;
            }
            // Another triangle at exactly the same distance: a tie, resolved in visit order.
            assert!(same_t(t_of(mesh, g.tri, ray), w.t), "{label}: triangle {} is not at t {}", g.tri, w.t);
            true
        }
        (g, w) => panic!("{label}: packet {g:?} vs brute force {w:?}"),
    }
}

/// A packet of `len` rays of kind `kind`: primary-like (neighbouring origins, nearly equal
/// directions toward the soup), random, along an axis or with `-0.0` components (shared
/// by all lanes or per lane), or through a triangle's vertex or edge midpoint.
fn packet(m: &TriMesh, scale: f32, kind: usize, len: usize, r: &mut Rng) -> Vec<Ray> {
    let tri = |r: &mut Rng| (r.next_f32() * m.indices.len() as f32) as usize % m.indices.len();
    let eye = random_vec(r, 1.0).normalize_or(Vec3::Z) * 3.0 * scale;
    let aim = random_vec(r, 0.5 * scale);
    (0..len)
        .map(|i| {
            let (origin, dir) = match kind % 5 {
                0 => {
                    let o = eye + random_vec(r, 1e-3 * scale);
                    (o, (aim + random_vec(r, 0.02 * scale) - o).normalize())
                }
                1 => (random_vec(r, 1.5 * scale), random_vec(r, 1.0).normalize_or(Vec3::X)),
                2 => {
                    let g = |r: &mut Rng| ((r.next_f32() * 16.0).floor() - 8.0) * scale / 8.0;
                    let axes = [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(-0.0, 1.0, 0.0), Vec3::new(0.6, -0.0, 0.8)];
                    let d = axes[(kind / 5 + if i % 2 == 0 { 0 } else { i }) % axes.len()];
                    (Vec3::new(g(r), g(r), g(r)) - d * 2.0 * scale, d)
                }
                3 => {
                    let [a, b, _] = m.triangle(tri(r));
                    let p = if r.next_f32() < 0.5 { a } else { a + (b - a) * 0.5 };
                    let d = random_vec(r, 1.0).normalize_or(Vec3::Y);
                    (p - d * scale * r.next_f32(), d)
                }
                _ => {
                    let p = surface_point(m, tri(r), r);
                    let o = eye + random_vec(r, 1e-2 * scale);
                    (o, (p - o).normalize())
                }
            };
            let tmax = if i % 4 == 3 { r.next_f32() * 4.0 * scale } else { f32::INFINITY };
            Ray { origin, dir, tmax }
        })
        .collect()
}

#[test]
fn packets_find_brute_force_closest_hits_on_soups() {
    let mut r = Rng::from_state(41);
    for (n, scale, seed) in [(40, 1.0, 11), (700, 1e-3, 12), (3000, 1.0, 13), (3000, 1e3, 14), (20_000, 50.0, 15)] {
        let mesh = soup(n, scale, seed);
        let accel = Accel::build(&mesh, BvhLayout::Bvh8);
        let (mut rays_seen, mut hits, mut ties, mut walk_misses) = (0u32, 0u32, 0u32, 0u32);
        for p in 0..600 {
            let len = 1 + p % PACKET;
            let rays = packet(&mesh, scale, p, len, &mut r);
            let mut got = [None; PACKET];
            accel.intersect_packet(&rays, &mut got);
            for (i, ray) in rays.iter().enumerate() {
                let label = format!("soup n {n} scale {scale} packet {p} ray {i} {ray:?}");
                let one = accel.intersect(ray);
                assert_eq!(one.map(|h| h.t.to_bits() & !SIGN), got[i].map(|h| h.t.to_bits() & !SIGN), "{label}");
                if one.map(|h| h.t.to_bits() & !SIGN)
                    == brute_force::intersect(&mesh, ray).map(|h| h.t.to_bits() & !SIGN)
                {
                    ties += u32::from(check(&mesh, ray, got[i], &label));
                } else {
                    // The walks' shared limit (`bvh8`): a flat box met exactly at its edge
                    // can be missed by the slab test's rounding; the packet must agree.
                    walk_misses += 1;
                }
                hits += u32::from(got[i].is_some());
                rays_seen += 1;
            }
        }
        assert!(walk_misses * 200 <= rays_seen, "n {n}: {walk_misses} rays where the walk misses brute force's hit");
        // Both answers must have been exercised.
        assert!(hits > rays_seen / 5 && hits < rays_seen * 9 / 10, "n {n}: {hits} hits of {rays_seen}");
        eprintln!("soup n {n}: {rays_seen} rays, {hits} hits, {ties} tied triangles, {walk_misses} walk misses");
    }
}

#[test]
fn packets_match_single_rays_on_a_satellite_frame() {
    let scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite_lambert.toml")).unwrap();
    assert!(scene.accel.walks_packets() || !hilcam_core::render::geometry::shadow_packet::avx2());
    let (closest, _) = common::scenes::recorded_rays(&scene, 128, 4);
    assert!(closest.len() > 15_000, "{} closest-hit rays", closest.len());
    let (mut hits, mut ties) = (0u32, 0u32);
    for chunk in closest.chunks(PACKET) {
        let mut got = [None; PACKET];
        scene.accel.intersect_packet(chunk, &mut got);
        for (ray, g) in chunk.iter().zip(got) {
            let one = scene.accel.intersect(ray);
            match (g, one) {
                (None, None) => {}
                (Some(g), Some(o)) => {
                    assert!(same_t(g.t, o.t), "{ray:?}: packet {g:?} vs single ray {o:?}");
                    ties += u32::from(g.tri != o.tri);
                    hits += 1;
                }
                _ => panic!("{ray:?}: packet {g:?} vs single ray {one:?}"),
            }
        }
    }
    assert!(hits > 8000, "{hits} hits");
    // A tie needs two triangles at bit-identical distances: a ray exactly through an edge.
    assert!(ties * 1000 <= hits, "{ties} tied triangles in {hits} hits");
    eprintln!("satellite: {} rays in packets, {hits} hits, {ties} tied triangles", closest.len());
}

#[test]
fn other_layouts_answer_ray_by_ray() {
    let mesh = soup(2000, 1.0, 21);
    let mut r = Rng::from_state(5);
    for layout in [BvhLayout::Bvh2, BvhLayout::Bvh4, BvhLayout::Cwbvh] {
        let accel = Accel::build(&mesh, layout);
        assert!(!accel.walks_packets(), "{layout:?}");
        for p in 0..200 {
            let rays = packet(&mesh, 1.0, p, 1 + p % PACKET, &mut r);
            let mut got = [None; PACKET];
            accel.intersect_packet(&rays, &mut got);
            for (i, ray) in rays.iter().enumerate() {
                assert_eq!(got[i], accel.intersect(ray), "{layout:?} packet {p} ray {i}");
            }
        }
    }
    let empty = Accel::build(&TriMesh::default(), BvhLayout::Bvh8);
    let mut got = [Some(Hit { tri: 0, t: 1.0, normal: Vec3::Z, material: 0 }); 1];
    empty.intersect_packet(&[Ray { origin: Vec3::ZERO, dir: Vec3::X, tmax: f32::INFINITY }], &mut got);
    assert_eq!(got[0], None);
}
