//! Shadow rays eight at a time (`Accel::occluded_packet`, `geometry::shadow_packet`): every
//! ray's answer must be the single-ray walk's and brute force's, on triangle soups (slivers,
//! zero-area and axis-aligned triangles; axis and signed-zero directions; rays grazing
//! vertices and edges exactly) and on the shadow rays of a satellite frame.

use glam::Vec3;
use hilcam_core::render::geometry::bvh::brute_force;
use hilcam_core::render::geometry::shadow_packet::{PACKET, avx2};
use hilcam_core::render::geometry::{Accel, BvhLayout, Ray, TriMesh};
use hilcam_core::render::sampling::Rng;

use crate::common;
use common::soup::{random_vec, soup, surface_point};

/// Directions shared by a packet: oblique, along the axes, with `-0.0` components.
fn directions(r: &mut Rng) -> Vec<Vec3> {
    let mut d = vec![
        Vec3::new(0.3, -0.5, 0.81).normalize(),
        Vec3::X,
        -Vec3::Z,
        Vec3::new(-0.0, 1.0, 0.0),
        Vec3::new(1.0, -0.0, 1.0).normalize(),
        Vec3::new(0.0, -0.6, 0.8),
    ];
    d.extend((0..10).map(|_| random_vec(r, 1.0).normalize_or(Vec3::Y)));
    d
}

/// Origins for rays along `d`: on surfaces (the shadow rays' case), anywhere, on a grid
/// (with axis directions: rays along box faces and triangle edges), and exactly through a
/// vertex or an edge point of a triangle (the triangle test's sign rule decides).
fn origin(m: &TriMesh, d: Vec3, scale: f32, kind: usize, r: &mut Rng) -> Vec3 {
    let tri = |r: &mut Rng| (r.next_f32() * m.indices.len() as f32) as usize % m.indices.len();
    match kind % 4 {
        0 => surface_point(m, tri(r), r),
        1 => random_vec(r, 1.5 * scale),
        2 => {
            let g = |r: &mut Rng| ((r.next_f32() * 16.0).floor() - 8.0) * scale / 8.0;
            Vec3::new(g(r), g(r), g(r)) - d * 2.0 * scale
        }
        _ => {
            let [a, b, _] = m.triangle(tri(r));
            let on_edge = if r.next_f32() < 0.5 { a } else { a + (b - a) * 0.5 };
            on_edge - d * (scale * r.next_f32())
        }
    }
}

#[test]
fn packets_answer_as_brute_force_on_soups() {
    eprintln!("AVX2 packet walk: {}", if avx2() { "on" } else { "off (scalar fallback tested)" });
    let mut r = Rng::from_state(77);
    for (n, scale, seed) in [(40, 1.0, 1), (700, 1e-3, 2), (3000, 1.0, 3), (3000, 1e3, 4), (20_000, 50.0, 5)] {
        let mesh = soup(n, scale, seed);
        let accel = Accel::build(&mesh, BvhLayout::Bvh4);
        let (mut rays_seen, mut blocked, mut packets) = (0u32, 0u32, 0u32);
        for d in directions(&mut r) {
            for p in 0..40 {
                let len = 1 + p % PACKET;
                let rays: Vec<Ray> = (0..len)
                    .map(|i| Ray {
                        origin: origin(&mesh, d, scale, p + i, &mut r),
                        dir: d,
                        tmax: if i % 3 == 0 { r.next_f32() * scale } else { f32::INFINITY },
                    })
                    .collect();
                let got = accel.occluded_packet(&rays);
                assert_eq!(got >> len, 0, "bits beyond the packet");
                for (i, ray) in rays.iter().enumerate() {
                    let want = brute_force::occluded(&mesh, ray);
                    let one = accel.occluded(ray);
                    let label = format!("soup n {n} scale {scale} dir {d:?} packet {p} ray {i} {ray:?}");
                    assert_eq!(one, want, "{label}: single-ray walk vs brute force");
                    assert_eq!(got >> i & 1 == 1, want, "{label}: packet vs brute force");
                    blocked += want as u32;
                    rays_seen += 1;
                }
                packets += 1;
            }
        }
        // Both answers must have been exercised.
        assert!(blocked > rays_seen / 10 && blocked < rays_seen * 9 / 10, "n {n}: {blocked} blocked of {rays_seen}");
        assert!(packets > 500);
    }
}

#[test]
fn mixed_directions_fall_back_to_single_rays() {
    let mesh = soup(500, 1.0, 8);
    let accel = Accel::build(&mesh, BvhLayout::Bvh4);
    let mut r = Rng::from_state(3);
    for _ in 0..200 {
        let rays: Vec<Ray> = (0..PACKET)
            .map(|_| Ray {
                origin: random_vec(&mut r, 1.5),
                dir: random_vec(&mut r, 1.0).normalize_or(Vec3::X),
                tmax: f32::INFINITY,
            })
            .collect();
        let got = accel.occluded_packet(&rays);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(got >> i & 1 == 1, brute_force::occluded(&mesh, ray), "{ray:?}");
        }
    }
    // Directions equal as numbers but not as bits (`0.0` vs `-0.0`): their reciprocals
    // differ in sign, so they must not share one walk.
    for _ in 0..200 {
        let rays: Vec<Ray> = (0..PACKET)
            .map(|i| Ray {
                origin: random_vec(&mut r, 1.5),
                dir: Vec3::new(if i % 2 == 0 { 0.0 } else { -0.0 }, 1.0, 0.0),
                tmax: f32::INFINITY,
            })
            .collect();
        let got = accel.occluded_packet(&rays);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(got >> i & 1 == 1, brute_force::occluded(&mesh, ray), "{ray:?}");
        }
    }
    assert_eq!(accel.occluded_packet(&[]), 0);
    let empty = Accel::build(&TriMesh::default(), BvhLayout::Bvh4);
    assert_eq!(empty.occluded_packet(&[Ray { origin: Vec3::ZERO, dir: Vec3::X, tmax: f32::INFINITY }]), 0);
}

#[test]
fn packets_answer_as_single_rays_on_satellite_shadow_rays() {
    let scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    let (_, shadow) = common::scenes::recorded_rays(&scene, 128, 3);
    assert!(shadow.len() > 5000, "{} shadow rays", shadow.len());
    let mut blocked = 0;
    for chunk in shadow.chunks(PACKET) {
        let got = scene.accel.occluded_packet(chunk);
        for (i, ray) in chunk.iter().enumerate() {
            let want = scene.accel.occluded(ray);
            assert_eq!(got >> i & 1 == 1, want, "{ray:?}");
            blocked += want as u32;
        }
    }
    assert!(blocked > 0, "no shadow ray was blocked");
    eprintln!("satellite: {} shadow rays in packets, {blocked} blocked", shadow.len());
}
