//! A loaded scene: triangles in the render frame, materials, sun, background, and the
//! defaults (camera, pose, render settings) that let one file render on its own.

pub mod file;
pub mod fold;
pub mod limits;
pub mod obj;

use crate::pose::Pose;
use crate::render::bsdf::Bsdf;
use crate::render::camera::{CameraModel, TargetBounds};
use crate::render::geometry::{Accel, BvhLayout, SunShadowCache, TriMesh};
use crate::render::integrator::RenderSettings;
use crate::sensor::SensorConfig;
use glam::{DVec3, Vec3};

pub use file::{SceneError, load};

/// Default band irradiance of the sun, W/m² over 0.45–0.75 µm (the paper's value).
pub const SOLAR_BAND_IRRADIANCE: f64 = 593.1;

/// A named material and its BRDF.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    pub bsdf: Bsdf,
}

/// Everything the renderer needs that does not change from frame to frame.
pub struct Scene {
    /// Triangles in the render frame (body frame shifted by `frame_origin_body`).
    pub mesh: TriMesh,
    /// Unit geometric normal of each triangle (render frame, from the winding).
    pub normals: Vec<Vec3>,
    pub materials: Vec<Material>,
    pub accel: Accel,
    /// Where the render frame's origin sits in the target body frame, metres.
    pub frame_origin_body: DVec3,
    pub bounds: TargetBounds,
    /// Sun band irradiance on a surface facing it, W/m².
    pub sun_irradiance: f32,
    /// Radiance of rays that escape, W·sr⁻¹·m⁻².
    pub background: f32,
    pub camera: CameraModel,
    /// The camera's optics and detector (all effects off by default).
    pub sensor: SensorConfig,
    pub pose: Pose,
    pub render: RenderSettings,
    /// Shadow-ray structure for the current sun direction (off by default; built when a
    /// sun direction repeats, rebuilt when it moves in the render frame).
    pub sun_shadow: SunShadowCache,
}

/// What a scene is made of before the acceleration structure is built.
pub struct SceneParts {
    /// Triangles in the target body frame, metres.
    pub mesh: TriMesh,
    pub materials: Vec<Material>,
    pub sun_irradiance: f64,
    pub background: f64,
    pub camera: CameraModel,
    pub sensor: SensorConfig,
    pub pose: Pose,
    pub render: RenderSettings,
    pub layout: BvhLayout,
}

impl Scene {
    /// Re-centre the mesh on its bounds, compute normals and bounds, build the BVH.
    pub fn build(parts: SceneParts) -> Scene {
        let SceneParts { mut mesh, materials, sun_irradiance, background, camera, sensor, pose, render, layout } =
            parts;
        let (lo, hi) = mesh.positions.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            let p = p.as_dvec3();
            (lo.min(p), hi.max(p))
        });
        let centre = if mesh.positions.is_empty() { DVec3::ZERO } else { (lo + hi) * 0.5 };
        for p in &mut mesh.positions {
            *p = (p.as_dvec3() - centre).as_vec3();
        }
        let radius = mesh.positions.iter().map(|p| p.as_dvec3().length()).fold(0.0, f64::max);
        // Inflate a little so that rays start strictly outside every triangle.
        let radius = radius * (1.0 + 1e-4) + 1e-6;
        let normals = (0..mesh.indices.len()).map(|i| mesh.face_normal_area2(i).normalize_or_zero()).collect();
        let accel = Accel::build(&mesh, layout);
        let (min, max) =
            if mesh.positions.is_empty() { (DVec3::ZERO, DVec3::ZERO) } else { (lo - centre, hi - centre) };
        Scene {
            mesh,
            normals,
            materials,
            accel,
            frame_origin_body: centre,
            bounds: TargetBounds { centre: DVec3::ZERO, radius, min: min - 1e-6, max: max + 1e-6 },
            sun_irradiance: sun_irradiance as f32,
            background: background as f32,
            camera,
            sensor,
            pose,
            render,
            sun_shadow: SunShadowCache::default(),
        }
    }

    /// Material of triangle `tri`.
    #[inline]
    pub fn material_of(&self, tri: u32) -> &Material {
        &self.materials[self.mesh.material[tri as usize] as usize]
    }

    /// True when some material reflects light (indirect bounces can carry energy).
    pub fn any_reflective(&self) -> bool {
        self.materials.iter().any(|m| !m.bsdf.is_black())
    }
}
