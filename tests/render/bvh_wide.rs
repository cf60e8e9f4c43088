//! Our wide BVHs — 4-wide (`BvhLayout::Bvh4`, SSE) and 8-wide (`BvhLayout::Bvh8`, AVX2 with
//! a scalar fallback) — against brute force on random triangle soups, and against the
//! next narrower layout (obvhs's `Bvh2`, resp. `Bvh4`) on rays recorded from a satellite
//! frame: the closest `t` must be bit-identical, occlusion answers identical.
//! (`src/geometry/bvh8.rs`'s unit tests check that its AVX2 and scalar box tests agree bit
//! for bit.)

use glam::Vec3;
use hilcam_core::render::geometry::bvh::brute_force;
use hilcam_core::render::geometry::{Accel, BvhLayout, Hit, Ray, TriMesh};
use hilcam_core::render::sampling::Rng;

use crate::common;
use common::soup::{random_vec, soup, surface_point};

/// The test rays for a soup: from outside, from inside, axis-aligned (zero and negative-zero
/// direction components, grid origins), bounce-like from surfaces, and shadow-like
/// segments toward one far direction; a third of them with a finite `tmax`.
fn rays(m: &TriMesh, scale: f32, n: usize, seed: u64) -> Vec<(&'static str, Ray)> {
    let mut r = Rng::from_state(seed);
    let sun = Vec3::new(0.3, -0.5, 0.81).normalize();
    let axes = [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::new(-0.0, 1.0, 0.0), Vec3::new(1.0, -0.0, 1.0).normalize()];
    (0..n)
        .map(|i| {
            let tmax = if i % 3 == 0 { r.next_f32() * 2.0 * scale } else { f32::INFINITY };
            let (kind, origin, dir) = match i % 5 {
                0 => {
                    let o = random_vec(&mut r, 3.0 * scale);
                    ("outside", o, (random_vec(&mut r, scale) - o).normalize_or(Vec3::Z))
                }
                1 => ("inside", random_vec(&mut r, 0.8 * scale), random_vec(&mut r, 1.0).normalize_or(Vec3::X)),
                2 => {
                    let g = |r: &mut Rng| ((r.next_f32() * 16.0).floor() - 8.0) * scale / 8.0;
                    let mut o = Vec3::new(g(&mut r), g(&mut r), g(&mut r));
                    let d = axes[(i / 5) % axes.len()];
                    // Start outside along the ray's axis half the time.
                    if i % 2 == 0 {
                        o -= d * 2.0 * scale;
                    }
                    ("axis", o, d)
                }
                3 => {
                    let k = (r.next_f32() * m.indices.len() as f32) as usize % m.indices.len();
                    ("bounce", surface_point(m, k, &mut r), random_vec(&mut r, 1.0).normalize_or(Vec3::Y))
                }
                _ => {
                    let k = (r.next_f32() * m.indices.len() as f32) as usize % m.indices.len();
                    ("shadow", surface_point(m, k, &mut r), sun)
                }
            };
            (kind, Ray { origin, dir, tmax })
        })
        .collect()
}

/// The wide layouts under test, each with the layout it is compared with on a real mesh.
const WIDE: [(BvhLayout, BvhLayout); 2] = [(BvhLayout::Bvh4, BvhLayout::Bvh2), (BvhLayout::Bvh8, BvhLayout::Bvh4)];

#[test]
fn wide_layouts_match_brute_force_bit_for_bit_on_soups() {
    for (layout, _) in WIDE {
        matches_brute_force_on_soups(layout);
    }
}

fn matches_brute_force_on_soups(layout: BvhLayout) {
    for (n, scale, seed) in [(40, 1.0, 1), (700, 1e-3, 2), (3000, 1.0, 3), (3000, 1e3, 4), (20_000, 50.0, 5)] {
        let mesh = soup(n, scale, seed);
        let accel = Accel::build(&mesh, layout);
        let mut hits = std::collections::BTreeMap::<&str, (u32, u32, u32)>::new();
        for (i, (kind, ray)) in rays(&mesh, scale, 5000, seed + 100).into_iter().enumerate() {
            let label = format!("{layout:?}: soup n {n} scale {scale} ray {i} ({kind}) {ray:?}");
            let got = accel.intersect(&ray);
            let want = brute_force::intersect(&mesh, &ray);
            let counts = hits.entry(kind).or_default();
            counts.0 += 1;
            match (got, want) {
                (Some(g), Some(w)) => {
                    counts.1 += 1;
                    assert_tie_or_same(&mesh, &ray, g, w, &label);
                }
                (None, None) => {}
                (g, w) => panic!("{label}: tree {g:?}, brute force {w:?}"),
            }
            let o = accel.occluded(&ray);
            counts.2 += o as u32;
            assert_eq!(o, brute_force::occluded(&mesh, &ray), "{label}: occluded");
        }
        // Each ray class must have exercised hits and misses, or the comparison is empty.
        for (kind, (rays, hit, occl)) in hits {
            assert!(hit > rays / 20 && hit < rays, "n {n} {kind}: {hit} hits of {rays}");
            assert!(occl >= hit, "n {n} {kind}: occluded {occl} < hits {hit}");
        }
    }
}

/// Same hit, or an exact tie: equal `t` (bits, except that `-0.0` and `0.0` tie), and the
/// reported `t` is that of the reported triangle.
fn assert_tie_or_same(mesh: &TriMesh, ray: &Ray, got: Hit, want: Hit, label: &str) -> bool {
    if got.tri == want.tri {
        assert_eq!(got.t.to_bits(), want.t.to_bits(), "{label}: t {} vs {}", got.t, want.t);
        assert_eq!(got, want, "{label}");
        return false;
    }
    assert!(got.t == want.t, "{label}: t {} (tri {}) vs {} (tri {})", got.t, got.tri, want.t, want.tri);
    if want.t != 0.0 {
        assert_eq!(got.t.to_bits(), want.t.to_bits(), "{label}");
    }
    assert_eq!(tri_t(mesh, got.tri, ray).to_bits(), got.t.to_bits(), "{label}: reported t is not its triangle's");
    true
}

/// `t` of one triangle (original index) under obvhs's test: ties are checked with it.
fn tri_t(mesh: &TriMesh, tri: u32, ray: &Ray) -> f32 {
    let [a, b, c] = mesh.triangle(tri as usize);
    let rt = obvhs::rt_triangle::RtTriangle::new(a.into(), b.into(), c.into());
    rt.intersect(&obvhs::ray::Ray::new(ray.origin.into(), ray.dir.into(), 0.0, ray.tmax))
}

#[test]
fn empty_and_single_leaf_meshes() {
    for (layout, _) in WIDE {
        empty_and_single_leaf(layout);
    }
}

fn empty_and_single_leaf(layout: BvhLayout) {
    let empty = TriMesh::default();
    let accel = Accel::build(&empty, layout);
    let ray = Ray { origin: Vec3::ZERO, dir: Vec3::X, tmax: f32::INFINITY };
    assert!(accel.intersect(&ray).is_none() && !accel.occluded(&ray));
    // Few triangles: the Bvh2 root is a leaf.
    let mesh = soup(3, 1.0, 9);
    let accel = Accel::build(&mesh, layout);
    let mut n = 0;
    for (_, ray) in rays(&mesh, 1.0, 2000, 10) {
        let want = brute_force::intersect(&mesh, &ray);
        n += want.is_some() as u32;
        assert_eq!(accel.intersect(&ray).map(|h| h.t.to_bits()), want.map(|h| h.t.to_bits()), "{ray:?}");
        assert_eq!(accel.occluded(&ray), brute_force::occluded(&mesh, &ray), "{ray:?}");
    }
    assert!(n > 100, "{n} hits");
}

#[test]
fn wide_layouts_match_the_narrower_on_satellite_rays() {
    for (layout, reference) in WIDE {
        matches_on_satellite_rays(layout, reference);
    }
}

fn matches_on_satellite_rays(layout: BvhLayout, reference: BvhLayout) {
    let scene =
        hilcam_core::scene::file::load_with_layout(std::path::Path::new("scenes/satellite.toml"), Some(reference))
            .unwrap();
    // The navigation camera scaled to 96×96 px (same field of view).
    let (closest, shadow) = common::scenes::recorded_rays(&scene, 96, 1);
    assert!(closest.len() > 2000 && shadow.len() > 1000, "{} closest, {} shadow rays", closest.len(), shadow.len());
    let wide = Accel::build(&scene.mesh, layout);
    let (mut hits, mut ties) = (0, 0);
    for (i, ray) in closest.iter().enumerate() {
        let (a, b): (Option<Hit>, Option<Hit>) = (wide.intersect(ray), scene.accel.intersect(ray));
        assert_eq!(a.is_some(), b.is_some(), "closest ray {i} {ray:?}: {a:?} vs {b:?}");
        if let (Some(a), Some(b)) = (a, b) {
            hits += 1;
            ties += assert_tie_or_same(&scene.mesh, ray, a, b, &format!("closest ray {i} {ray:?}")) as u32;
        }
    }
    let mut occluded = 0;
    for (i, ray) in shadow.iter().enumerate() {
        let o = wide.occluded(ray);
        occluded += o as u32;
        assert_eq!(o, scene.accel.occluded(ray), "shadow ray {i} {ray:?}");
    }
    assert!(hits > 1000 && occluded > 0, "{hits} hits, {occluded} occluded");
    eprintln!(
        "{layout:?} vs {reference:?} on the satellite: {} closest rays, {hits} hits, {ties} exact ties; {} shadow rays, {occluded} occluded",
        closest.len(),
        shadow.len()
    );
    // Exact ties (a ray through a shared edge or vertex) are rare on a real mesh.
    assert!(ties * 200 <= hits, "{ties} ties of {hits} hits");
    // A sample against brute force too (the reference's answer is not ground truth by itself).
    for ray in closest.iter().step_by(closest.len() / 300) {
        match (wide.intersect(ray), brute_force::intersect(&scene.mesh, ray)) {
            (Some(g), Some(w)) => _ = assert_tie_or_same(&scene.mesh, ray, g, w, &format!("{ray:?}")),
            (None, None) => {}
            (g, w) => panic!("{layout:?} {ray:?}: tree {g:?}, brute force {w:?}"),
        }
    }
}

/// `[render] bvh = "bvh8"` selects the layout; without the key it is the default (`bvh8`);
/// `bvh4` stays selectable (in this, the lab build; without the `lab` feature it is refused
/// by name, which scripts/test.sh checks on the `--no-default-features` binary); every
/// layout's `name` is the name a scene file uses.
#[test]
fn scene_file_selects_bvh8() {
    let dir = tempfile::tempdir().unwrap();
    let put = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    put("p.obj", "mtllib p.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\n");
    put("p.mtl", "newmtl paint\nKd 0.5 0.5 0.5\n");
    let parts = |render: &str| {
        let text = format!(
            "[[mesh]]\nobj = \"p.obj\"\n[materials.paint]\nmodel = \"lambert\"\nrho = 0.5\n\
             [camera]\nwidth = 64\nheight = 48\npitch_um = 10.0\nfocal_mm = 20.0\n[render]\n{render}\n"
        );
        let path = put("s.toml", &text);
        hilcam_core::scene::file::parse(&path, &text).unwrap_or_else(|e| panic!("{e}"))
    };
    assert_eq!(parts("bvh = \"bvh8\"").layout, BvhLayout::Bvh8);
    assert_eq!(parts("bvh = \"bvh4\"").layout, BvhLayout::Bvh4);
    assert_eq!(parts("spp = 2").layout, BvhLayout::Bvh8);
    for layout in [BvhLayout::Bvh2, BvhLayout::Cwbvh, BvhLayout::Bvh4, BvhLayout::Bvh8] {
        assert_eq!(hilcam_core::scene::file::parse_name::<BvhLayout>(layout.name()), Ok(layout));
        assert!(layout.available(), "{layout:?}: the lab build has every layout");
    }
    // The built tree answers like brute force on the one triangle.
    let s = hilcam_core::scene::Scene::build(parts("bvh = \"bvh8\""));
    let [a, b, c] = s.mesh.triangle(0);
    let centre = (a + b + c) / 3.0;
    let ray = Ray { origin: centre + Vec3::Z, dir: -Vec3::Z, tmax: f32::INFINITY };
    let hit = s.accel.intersect(&ray);
    assert!(hit.is_some());
    assert_eq!(hit, brute_force::intersect(&s.mesh, &ray));
}

/// Trees with unused slots (a few triangles, so nodes have fewer than W children) against
/// brute force, single rays and packets; and rays with a NaN coordinate, which pass every
/// slab test (empty slots included): they must find nothing and end, not restart at the
/// root (an empty slot once read as inner node 0 and the walk overflowed its stack).
#[test]
fn empty_slots_are_never_walked_into() {
    let nan_rays = [
        Ray { origin: Vec3::new(f32::NAN, 0.0, 0.0), dir: Vec3::X, tmax: f32::INFINITY },
        Ray { origin: Vec3::ZERO, dir: Vec3::new(f32::NAN, f32::NAN, f32::NAN), tmax: f32::INFINITY },
        Ray { origin: Vec3::splat(f32::NAN), dir: Vec3::splat(f32::NAN), tmax: f32::NAN },
        Ray { origin: Vec3::new(0.0, f32::INFINITY, 0.0), dir: Vec3::Z, tmax: f32::INFINITY },
    ];
    for layout in [BvhLayout::Bvh4, BvhLayout::Bvh8] {
        for (n, seed) in [(2, 21), (3, 22), (5, 23), (9, 24), (13, 25), (37, 26)] {
            let mesh = soup(n, 1.0, seed);
            let accel = Accel::build(&mesh, layout);
            let label = format!("{layout:?} with {n} triangles");
            let rays: Vec<Ray> = rays(&mesh, 1.0, 800, seed + 50).into_iter().map(|(_, r)| r).collect();
            let mut hits = 0;
            for ray in &rays {
                let want = brute_force::intersect(&mesh, ray);
                hits += want.is_some() as u32;
                assert_eq!(accel.intersect(ray).map(|h| h.t.to_bits()), want.map(|h| h.t.to_bits()), "{label} {ray:?}");
                assert_eq!(accel.occluded(ray), brute_force::occluded(&mesh, ray), "{label} {ray:?}");
            }
            assert!(hits > 20, "{label}: {hits} hits");
            // Packets of eight: closest hits of mixed rays, NaN lanes among them.
            for chunk in rays.chunks(8) {
                let mut mixed = chunk.to_vec();
                mixed[0] = nan_rays[chunk.len() % nan_rays.len()];
                let mut out = [None; 8];
                accel.intersect_packet(&mixed, &mut out);
                assert_eq!(out[0], None, "{label}: NaN lane hit");
                for (r, o) in mixed.iter().zip(&out).skip(1) {
                    let want = brute_force::intersect(&mesh, r).map(|h| h.t.to_bits());
                    assert_eq!(o.map(|h| h.t.to_bits()), want, "{label} packet {r:?}");
                }
            }
            // Shadow packets share a direction: finite ones toward the sun, and NaN ones.
            let sun = Vec3::new(0.3, -0.5, 0.81).normalize();
            let shadow: Vec<Ray> = rays.iter().map(|r| Ray { dir: sun, ..*r }).collect();
            for chunk in shadow.chunks(8) {
                let got = accel.occluded_packet(chunk);
                for (i, r) in chunk.iter().enumerate() {
                    assert_eq!(got >> i & 1 == 1, brute_force::occluded(&mesh, r), "{label} shadow {r:?}");
                }
                let nan: Vec<Ray> = chunk.iter().map(|r| Ray { dir: Vec3::splat(f32::NAN), ..*r }).collect();
                assert_eq!(accel.occluded_packet(&nan), 0, "{label}: NaN shadow rays occluded");
            }
            for ray in &nan_rays {
                assert_eq!(accel.intersect(ray), None, "{label} {ray:?}");
                assert!(!accel.occluded(ray), "{label} {ray:?}");
            }
        }
    }
}
