//! What the renderer draws: the target's triangles in the render frame, their materials,
//! the sun's band irradiance and the background. Nothing here depends on the camera, the
//! sensor or the pose; a scene file adds those ([`crate::scene::Scene`]).

use crate::pose::Pose;
use crate::render::bsdf::Bsdf;
use crate::render::camera::{CameraModel, PartSphere, TargetBounds, View};
use crate::render::geometry::parts::{self, Part};
use crate::render::geometry::spawn::TrianglePlane;
use crate::render::geometry::{Accel, BvhLayout, TriMesh};
use crate::render::planet::Planet;
use crate::render::stars::StarField;
use crate::render::texture::Texturing;
use glam::{DVec3, Vec3};

/// A named material: its BRDF and the radiance it emits.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: String,
    pub bsdf: Bsdf,
    /// Radiance the surface emits from both sides, W·sr⁻¹·m⁻² in the band (0: none).
    /// Seen by camera rays and by bounces; not sampled as a light (docs/brdf.md,
    /// "Emission").
    pub emission: f32,
}

impl Material {
    /// A material that emits nothing.
    pub fn new(name: impl Into<String>, bsdf: Bsdf) -> Self {
        Material { name: name.into(), bsdf, emission: 0.0 }
    }
}

/// The sphere about the centre of `part`'s box, over its vertices (render frame, whose
/// origin sits at `origin` in the mesh's frame), inflated as the whole target's.
fn part_sphere(mesh: &TriMesh, part: &Part, origin: DVec3) -> PartSphere {
    let centre = (part.lo + part.hi) * 0.5 - origin;
    let radius = part
        .triangles
        .iter()
        .flat_map(|&t| mesh.indices[t as usize])
        .map(|v| (mesh.positions[v as usize].as_dvec3() - centre).length())
        .fold(0.0, f64::max);
    PartSphere {
        centre,
        radius: radius * (1.0 + 1e-4) + 1e-6,
        min: part.lo - origin - 1e-6,
        max: part.hi - origin + 1e-6,
    }
}

/// Everything the renderer needs that does not change from frame to frame.
pub struct Target {
    /// Triangles in the render frame (body frame shifted by `frame_origin_body`).
    pub mesh: TriMesh,
    /// Unit geometric normal of each triangle (render frame, from the winding).
    pub normals: Vec<Vec3>,
    /// Each triangle's plane and coordinate scale: where rays leaving it start
    /// (`geometry::spawn`).
    pub planes: Vec<TrianglePlane>,
    pub materials: Vec<Material>,
    pub accel: Accel,
    /// Where the render frame's origin sits in the target body frame, metres.
    pub frame_origin_body: DVec3,
    pub bounds: TargetBounds,
    /// Bounding spheres of the target's spatially separate parts (`geometry::parts`),
    /// render frame; camera rays start where they first enter one. Empty when the target
    /// is one part (the rays then start on `bounds`, the same sphere).
    pub parts: std::sync::Arc<[PartSphere]>,
    /// Bounding radius of the largest part (the hybrid's cell size scales with it).
    pub detail_radius: f64,
    /// Sun band irradiance on a surface facing it, W/m².
    pub sun_irradiance: f32,
    /// Radiance of rays that escape, W·sr⁻¹·m⁻².
    pub background: f32,
    /// Point stars behind the target (none unless a scene asks for them).
    pub stars: Option<StarField>,
    /// A planet behind the target (`render::planet`), if the scene has one.
    pub planet: Option<Planet>,
    /// Base-colour textures and the triangles' UVs (`render::texture`); `None` unless a
    /// material is textured.
    pub texturing: Option<Box<Texturing>>,
}

impl Target {
    /// Re-centre the mesh (body frame, metres) on the bounds of its largest part, compute
    /// normals, planes and bounds, build the BVH.
    ///
    /// The render frame's origin is the centre of the largest spatially separate part's
    /// box (`geometry::parts`), not of the whole mesh's: a small body far away neither
    /// moves the origin nor coarsens the f32 coordinates of the main one.
    pub fn build(
        mut mesh: TriMesh,
        materials: Vec<Material>,
        sun_irradiance: f64,
        background: f64,
        layout: BvhLayout,
    ) -> Target {
        let split = parts::split(&mesh);
        let (lo, hi) = mesh.positions.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            let p = p.as_dvec3();
            (lo.min(p), hi.max(p))
        });
        let largest = split.iter().enumerate().max_by(|(i, a), (j, b)| {
            a.half_diagonal()
                .total_cmp(&b.half_diagonal())
                .then(a.triangles.len().cmp(&b.triangles.len()))
                .then(j.cmp(i))
        });
        let centre = match largest {
            None => DVec3::ZERO,
            Some(_) if split.len() == 1 => (lo + hi) * 0.5,
            Some((_, p)) => (p.lo + p.hi) * 0.5,
        };
        for p in &mut mesh.positions {
            *p = (p.as_dvec3() - centre).as_vec3();
        }
        let (min, max) =
            if mesh.positions.is_empty() { (DVec3::ZERO, DVec3::ZERO) } else { (lo - centre, hi - centre) };
        // One part: the sphere about the render origin (the box's centre); several: about
        // the whole box's centre.
        let whole = if split.len() > 1 { (min + max) * 0.5 } else { DVec3::ZERO };
        let radius = mesh.positions.iter().map(|p| (p.as_dvec3() - whole).length()).fold(0.0, f64::max);
        // Inflate a little so that rays start strictly outside every triangle.
        let radius = radius * (1.0 + 1e-4) + 1e-6;
        let spheres: Vec<PartSphere> =
            if split.len() > 1 { split.iter().map(|p| part_sphere(&mesh, p, centre)).collect() } else { Vec::new() };
        let detail_radius = match largest {
            Some((i, _)) if split.len() > 1 => spheres[i].radius,
            _ => radius,
        };
        let normals: Vec<Vec3> =
            (0..mesh.indices.len()).map(|i| mesh.face_normal_area2(i).normalize_or_zero()).collect();
        let planes = normals.iter().enumerate().map(|(i, &n)| TrianglePlane::of(&mesh, i, n)).collect();
        let accel = Accel::build(&mesh, layout);
        Target {
            mesh,
            normals,
            planes,
            materials,
            accel,
            frame_origin_body: centre,
            bounds: TargetBounds { centre: whole, radius, min: min - 1e-6, max: max + 1e-6 },
            parts: spheres.into(),
            detail_radius,
            sun_irradiance: sun_irradiance as f32,
            background: background as f32,
            stars: None,
            planet: None,
            texturing: None,
        }
    }

    /// The target as `camera` sees it at `pose` (an ideal lens).
    pub fn view(&self, camera: &CameraModel, pose: &Pose) -> View {
        View::new(camera, pose, self.frame_origin_body, self.bounds).with_parts(Some(self.parts.clone()))
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

    /// True when some surface emits light (a constant or a texture).
    pub fn any_emitting(&self) -> bool {
        self.materials.iter().any(|m| m.emission > 0.0)
    }
}
