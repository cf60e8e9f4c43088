//! What the renderer draws: the target's triangles in the render frame, their materials,
//! the sun's band irradiance and the background. Nothing here depends on the camera, the
//! sensor or the pose; a scene file adds those ([`crate::scene::Scene`]).

use crate::pose::Pose;
use crate::render::bsdf::Bsdf;
use crate::render::camera::{CameraModel, TargetBounds, View};
use crate::render::geometry::{Accel, BvhLayout, TriMesh};
use crate::render::planet::Planet;
use crate::render::stars::StarField;
use glam::{DVec3, Vec3};

/// A named material and its BRDF.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    pub bsdf: Bsdf,
}

/// Everything the renderer needs that does not change from frame to frame.
pub struct Target {
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
    /// Point stars behind the target (none unless a scene asks for them).
    pub stars: Option<StarField>,
    /// A planet behind the target (`render::planet`), if the scene has one.
    pub planet: Option<Planet>,
}

impl Target {
    /// Re-centre the mesh (body frame, metres) on its bounds, compute normals and bounds,
    /// build the BVH.
    pub fn build(
        mut mesh: TriMesh,
        materials: Vec<Material>,
        sun_irradiance: f64,
        background: f64,
        layout: BvhLayout,
    ) -> Target {
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
        Target {
            mesh,
            normals,
            materials,
            accel,
            frame_origin_body: centre,
            bounds: TargetBounds { centre: DVec3::ZERO, radius, min: min - 1e-6, max: max + 1e-6 },
            sun_irradiance: sun_irradiance as f32,
            background: background as f32,
            stars: None,
            planet: None,
        }
    }

    /// The target as `camera` sees it at `pose` (an ideal lens).
    pub fn view(&self, camera: &CameraModel, pose: &Pose) -> View {
        View::new(camera, pose, self.frame_origin_body, self.bounds)
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
