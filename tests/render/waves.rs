//! The tile renderer traces paths wave by wave; this checks it against the plain
//! per-sample estimator (`PathContext::radiance`, one path traced to the end), computed
//! here pixel by pixel: the same bytes and the same shadow and bounce rays, for both random-number
//! sequences, every sampler, roulette on and off, several samples per pixel, on the
//! shipped satellite (several materials, glossy lobes, self-shadowing, inter-reflection).

use hilcam_core::render::camera::{CameraModel, View};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::integrator::{PathContext, RayCounts, RenderSettings, SamplerKind};
use hilcam_core::render::sampling::{PerSample, Rng, Sequence, SobolStream};
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::Scene;

fn per_sample_reference<S: PerSample>(
    scene: &Scene,
    cam: &CameraModel,
    settings: &RenderSettings,
    frame: u64,
) -> (RadianceImage, RayCounts) {
    let view = View::new(cam, &scene.pose, scene.frame_origin_body, scene.bounds);
    let ctx = PathContext::new(scene, view.sun, settings);
    let mut img = RadianceImage::new(cam.width, cam.height, scene.background);
    let mut counts = RayCounts::default();
    for row in 0..cam.height {
        for col in 0..cam.width {
            let pixel = u64::from(row) * u64::from(cam.width) + u64::from(col);
            let mut sum = 0.0f32;
            for s in 0..settings.spp.floor() {
                let mut rng = S::for_sample(settings.seed, frame, pixel, s);
                let j = rng.next_2d();
                let ray = view.primary_ray(f64::from(col) + f64::from(j.x), f64::from(row) + f64::from(j.y));
                let v = match ray {
                    Some(ray) => ctx.radiance(ray, &mut rng, &mut counts, &mut ()),
                    None => scene.background,
                };
                if v.is_finite() {
                    sum += v;
                }
            }
            img.data[(row * cam.width + col) as usize] = sum * (1.0 / settings.spp.floor() as f32);
        }
    }
    (img, counts)
}

#[test]
fn waves_give_the_same_bytes_as_tracing_sample_by_sample() {
    let scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    // The navigation camera scaled to 72×56 px (same field of view, off-square on purpose).
    let nav = &scene.camera;
    let cam = CameraModel {
        width: 72,
        height: 56,
        pitch_um: nav.pitch_um * f64::from(nav.width) / 72.0,
        focal_mm: nav.focal_mm,
        principal_point_px: [0.0, 0.0],
    };
    let cases = [
        (Sequence::Sobol, SamplerKind::Brdf, true, 3, 4),
        (Sequence::Independent, SamplerKind::Cosine, false, 2, 3),
        (Sequence::Sobol, SamplerKind::Uniform, true, 1, 1),
        (Sequence::Independent, SamplerKind::Brdf, true, 5, 2),
    ];
    for (sequence, sampler, roulette, spp, depth) in cases {
        let settings = RenderSettings {
            spp: Spp::whole(spp),
            depth,
            sampler,
            sequence,
            roulette,
            adaptive: false,
            quality: hilcam_core::render::integrator::QualityGoal::FIXED,
            method: Default::default(),
            seed: 11,
        };
        let (img, stats) = render(&scene, &scene.view(&cam, &scene.pose), &RenderOptions::new(settings, 7));
        let (reference, counts) = match sequence {
            Sequence::Independent => per_sample_reference::<Rng>(&scene, &cam, &settings, 7),
            Sequence::Sobol => per_sample_reference::<SobolStream>(&scene, &cam, &settings, 7),
        };
        let label = format!("{sequence:?} {sampler:?} roulette {roulette} spp {spp} depth {depth}");
        assert!(counts.total() > 1000, "{label}: the target must be in view ({counts:?})");
        // Pixels outside the target box's image are skipped (their rays would miss it), so
        // the renderer traces fewer primary rays; every other ray must be the same.
        assert!(stats.rays.primary <= counts.primary && stats.rays.primary > 0, "{label}");
        assert_eq!(stats.rays.shadow, counts.shadow, "{label}");
        assert_eq!(stats.rays.bounce, counts.bounce, "{label}");
        for (i, (a, b)) in img.data.iter().zip(&reference.data).enumerate() {
            assert_eq!(a.to_bits(), b.to_bits(), "{label}: pixel ({}, {}): {a} vs {b}", i % 72, i / 72);
        }
    }
}
