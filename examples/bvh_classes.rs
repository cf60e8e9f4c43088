//! Per-ray-class cost of the BVH layouts on the rays of one frame: the frame is rendered
//! once with a ray recorder (closest-hit rays: bounces, plus primaries where they are traced;
//! any-hit rays: shadow), then the same rays are re-traced on one thread through each
//! layout in turn, alternating for `rounds` rounds; medians in ns per ray.
//!
//!     cargo run --release --example bvh_classes -- [scene] [spp] [depth] [rounds] [layouts]
//!
//! e.g. `... -- scenes/satellite_lambert.toml 4 4 7 bvh4,bvh8`.

use hilcam_core::render::geometry::{Accel, BvhLayout, Ray};
use hilcam_core::render::integrator::{RecordedRays, RenderSettings, SamplerKind};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene = args.first().map_or("scenes/satellite.toml", String::as_str);
    let spp = args.get(1).map_or(Ok(4), |s| s.parse())?;
    let depth = args.get(2).map_or(Ok(4), |s| s.parse())?;
    let rounds: usize = args.get(3).map_or(Ok(7), |s| s.parse())?;
    let layouts: Vec<BvhLayout> = args
        .get(4)
        .map_or("bvh4,bvh8", String::as_str)
        .split(',')
        .map(|s| {
            hilcam_core::scene::file::parse_name::<BvhLayout>(s).and_then(BvhLayout::check).map_err(anyhow::Error::msg)
        })
        .collect::<Result<_, _>>()?;
    let scene = hilcam_core::scene::file::load(std::path::Path::new(scene))?;
    let settings = RenderSettings {
        spp: hilcam_core::render::integrator::Spp::whole(spp),
        depth,
        sampler: SamplerKind::Cosine,
        roulette: false,
        ..Default::default()
    };
    let mut buffers = hilcam_core::render::FrameBuffers::<RecordedRays>::default();
    let options = hilcam_core::render::RenderOptions::new(settings, 0);
    hilcam_core::render::render_into(&mut buffers, &scene, &scene.view(&scene.camera, &scene.pose), &options);
    let logs = buffers.take_ray_logs();
    let closest: Vec<Ray> = logs.iter().flat_map(|l| l.closest.iter().copied()).collect();
    let shadow: Vec<Ray> = logs.iter().flat_map(|l| l.shadow.iter().copied()).collect();
    println!("{} closest-hit rays, {} shadow rays (spp {spp}, depth {depth})", closest.len(), shadow.len());
    let accels: Vec<Accel> = layouts.iter().map(|&l| Accel::build(&scene.mesh, l)).collect();
    let mut times = vec![(Vec::new(), Vec::new()); layouts.len()];
    for _ in 0..rounds.max(1) {
        for (a, t) in accels.iter().zip(&mut times) {
            let t0 = Instant::now();
            let hits = closest.iter().filter(|r| a.intersect(r).is_some()).count();
            t.0.push(t0.elapsed().as_secs_f64() * 1e9 / closest.len() as f64);
            let t0 = Instant::now();
            let occluded = shadow.iter().filter(|r| a.occluded(r)).count();
            t.1.push(t0.elapsed().as_secs_f64() * 1e9 / shadow.len() as f64);
            std::hint::black_box((hits, occluded));
        }
    }
    println!("{:<8} {:>14} {:>14}  (one thread, median of {rounds})", "layout", "closest ns/ray", "shadow ns/ray");
    for (l, (c, s)) in layouts.iter().zip(times) {
        println!("{:<8} {:>14.1} {:>14.1}", format!("{l:?}"), median(c), median(s));
    }
    Ok(())
}
