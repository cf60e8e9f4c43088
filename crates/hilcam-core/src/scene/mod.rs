//! A loaded scene: triangles in the render frame, materials, sun, background, and the
//! defaults (camera, pose, render settings) that let one file render on its own.

pub mod authored;
mod base64;
pub mod camera_file;
pub mod file;
pub mod fold;
pub mod gltf;
pub mod limits;
pub mod material_entry;
mod mesh_entries;
pub mod model;
pub mod mtl;
pub mod mtl_bsdf;
pub mod obj;
pub mod obj_faces;
pub mod planet;
mod scene_error;
pub mod texture_file;
mod textures;

use crate::pose::Pose;
use crate::render::camera::CameraModel;
use crate::render::geometry::{BvhLayout, TriMesh};
use crate::render::integrator::RenderSettings;
use crate::render::stars::StarField;
use crate::render::target::Target;
use crate::sensor::SensorConfig;

pub use crate::render::target::Material;
pub use file::{SceneError, load};
pub use mesh_entries::load_model;

/// Default band irradiance of the sun, W/m² over 0.45–0.75 µm (the paper's value).
pub const SOLAR_BAND_IRRADIANCE: f64 = 593.1;

/// A scene file, loaded: the target the renderer draws and the defaults (camera, sensor,
/// pose, render settings) that let one file render on its own. Dereferences to its
/// [`Target`], so `scene.mesh` and `render(&scene, …)` read as before.
pub struct Scene {
    pub target: Target,
    pub camera: CameraModel,
    /// The camera's optics and detector (all effects off by default).
    pub sensor: SensorConfig,
    pub pose: Pose,
    pub render: RenderSettings,
    /// `[limits]`: the largest pose range and mesh scale.
    pub limits: limits::SceneLimits,
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
    /// Point stars behind the target (`[stars]`).
    pub stars: Option<StarField>,
    /// A planet behind the target (`[planet]`), if any.
    pub planet: Option<crate::render::planet::Planet>,
    /// `[limits]` (default: [`limits::SceneLimits::default`]).
    pub limits: limits::SceneLimits,
    /// Base-colour textures and the UVs of the mesh's triangles, if a material is textured.
    pub texturing: Option<crate::render::texture::Texturing>,
}

impl Scene {
    /// Build the target (re-centred mesh, normals, bounds, BVH) and keep the defaults.
    pub fn build(parts: SceneParts) -> Scene {
        let SceneParts {
            mesh,
            materials,
            sun_irradiance,
            background,
            camera,
            sensor,
            pose,
            render,
            layout,
            stars,
            planet,
            limits,
            texturing,
        } = parts;
        let mut target = Target::build(mesh, materials, sun_irradiance, background, layout);
        target.stars = stars;
        target.planet = planet;
        target.texturing = texturing.map(Box::new);
        Scene { target, camera, sensor, pose, render, limits }
    }

    /// The gate every pose of this scene passes, from every input: its `[limits]`
    /// range and its planet's radius (a pose may move the planet only if there is one).
    pub fn pose_limits(&self) -> crate::pose::validate::PoseLimits {
        self.limits.pose_limits(self.target.planet.map(|p| p.radius_m))
    }

    /// The scene's planet moved to `pose`'s planet centre when the pose carries one
    /// (checked by the pose gate), else the scene's planet as it stands.
    pub fn planet_at(&self, pose: &Pose) -> Option<crate::render::planet::Planet> {
        let p = self.target.planet?;
        Some(match pose.planet_centre {
            Some(c) => crate::render::planet::Planet { centre_cam: c, ..p },
            None => p,
        })
    }
}

impl std::ops::Deref for Scene {
    type Target = Target;
    fn deref(&self) -> &Target {
        &self.target
    }
}

impl std::ops::DerefMut for Scene {
    fn deref_mut(&mut self) -> &mut Target {
        &mut self.target
    }
}
