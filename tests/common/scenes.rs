//! Scene builders shared by the rendering tests.

use glam::{DVec3, Vec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::bsdf::BsdfSpec;
use hilcam_core::render::camera::CameraModel;
use hilcam_core::render::geometry::{BvhLayout, TriMesh};
use hilcam_core::render::integrator::RenderSettings;
use hilcam_core::scene::{Material, Scene, SceneParts};

/// The scene's camera at `width` × `height` pixels with the same field of view, principal
/// point offset `pp` (pixels).
pub fn scaled_camera(scene: &Scene, width: u32, height: u32, pp: [f64; 2]) -> CameraModel {
    let nav = &scene.camera;
    CameraModel {
        width,
        height,
        pitch_um: nav.pitch_um * f64::from(nav.width) / f64::from(width),
        focal_mm: nav.focal_mm,
        principal_point_px: pp,
    }
}

/// Every ray a `width`² frame of `scene` at `spp`, depth 4, cosine bounces, no roulette
/// traces: (closest-hit rays, shadow rays), for re-tracing them through another walk.
pub fn recorded_rays(
    scene: &Scene,
    width: u32,
    spp: u32,
) -> (Vec<hilcam_core::render::geometry::Ray>, Vec<hilcam_core::render::geometry::Ray>) {
    use hilcam_core::render::integrator::{RecordedRays, RenderSettings, SamplerKind};
    let cam = scaled_camera(scene, width, width, [0.0, 0.0]);
    let settings = RenderSettings {
        spp: hilcam_core::render::integrator::Spp::whole(spp),
        depth: 4,
        sampler: SamplerKind::Cosine,
        roulette: false,
        ..Default::default()
    };
    let mut buffers = hilcam_core::render::FrameBuffers::<RecordedRays>::default();
    let options = hilcam_core::render::RenderOptions::new(settings, 0);
    hilcam_core::render::render_into(&mut buffers, scene, &scene.view(&cam, &scene.pose), &options);
    let logs = buffers.take_ray_logs();
    let closest = logs.iter().flat_map(|l| l.closest.iter().copied()).collect();
    let shadow = logs.iter().flat_map(|l| l.shadow.iter().copied()).collect();
    (closest, shadow)
}

/// An axis-aligned square in the plane z = `z` (body frame), side `s`, centred at (cx, cy).
pub fn square(cx: f32, cy: f32, z: f32, s: f32, material: u32) -> TriMesh {
    let h = s * 0.5;
    TriMesh {
        positions: vec![
            Vec3::new(cx - h, cy - h, z),
            Vec3::new(cx + h, cy - h, z),
            Vec3::new(cx + h, cy + h, z),
            Vec3::new(cx - h, cy + h, z),
        ],
        indices: vec![[0, 2, 1], [0, 3, 2]],
        material: vec![material; 2],
    }
}

pub fn lambert(name: &str, rho: f32) -> Material {
    Material::new(
        name,
        toml::from_str::<BsdfSpec>(&format!("model = \"lambert\"\nrho = {rho}")).unwrap().build().unwrap(),
    )
}

pub fn camera(width: u32, height: u32, pitch_um: f64, focal_mm: f64) -> CameraModel {
    CameraModel { width, height, pitch_um, focal_mm, principal_point_px: [0.0, 0.0] }
}

pub fn scene(mesh: TriMesh, materials: Vec<Material>, cam: CameraModel, pose: Pose, render: RenderSettings) -> Scene {
    Scene::build(SceneParts {
        sensor: Default::default(),
        mesh,
        materials,
        sun_irradiance: 593.1,
        background: 0.0,
        camera: cam,
        pose,
        render,
        layout: BvhLayout::Bvh2,
        stars: None,
        planet: None,
        limits: Default::default(),
        texturing: None,
    })
}

/// Sun direction (camera frame) at incidence `deg` on a plate whose normal faces the camera.
pub fn sun_at_incidence(deg: f64) -> DVec3 {
    let t = deg.to_radians();
    DVec3::new(t.sin(), 0.0, -t.cos())
}

pub fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64
}

/// The pixels of a centred square image of half width `half_px` (pixels) lying `margin`
/// pixels or more inside its edges.
pub fn inner_pixels(img: &hilcam_core::render::film::RadianceImage, half_px: f64, margin: f64) -> Vec<f32> {
    let (cx, cy) = (img.width as f64 / 2.0, img.height as f64 / 2.0);
    let mut v = Vec::new();
    for row in 0..img.height {
        for col in 0..img.width {
            let (x, y) = (col as f64 + 0.5 - cx, row as f64 + 0.5 - cy);
            if x.abs() < half_px - margin && y.abs() < half_px - margin {
                v.push(img.get(col, row));
            }
        }
    }
    v
}

/// Irradiance at `p` (normal `n`) from a uniformly bright polygon `v` of radiance 1,
/// unoccluded: Lambert's formula, (1/2)·Σ γᵢ n·(Rᵢ × Rᵢ₊₁)/|Rᵢ × Rᵢ₊₁|.
pub fn polygon_irradiance(p: DVec3, n: DVec3, v: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for i in 0..v.len() {
        let (a, b) = ((v[i] - p).normalize(), (v[(i + 1) % v.len()] - p).normalize());
        sum += a.dot(b).clamp(-1.0, 1.0).acos() * n.dot(a.cross(b).normalize());
    }
    (0.5 * sum).abs()
}
