//! The renderer's integration tests, one binary (each binary links the whole crate, so
//! one link instead of one per file): geometry and BVHs, BSDFs and samplers, the pixel
//! loop, shadows and silhouettes, fold surfaces, the sensor model.
//! `cargo test --test render`; one file: `cargo test --test render bvh_wide::`.

#[path = "../common/mod.rs"]
mod common;

mod adaptive;
mod analytic;
mod bsdf;
mod bvh;
mod bvh_wide;
mod closest_packet;
mod emission;
mod extremes;
mod fold;
mod ggx;
mod gltf;
mod hybrid;
mod hybrid_cache;
mod hybrid_caustics;
mod limits;
mod mc_noise;
mod mc_ptc;
mod mc_sensor;
mod mc_variance;
mod mis;
mod motion;
mod mtl;
mod numerics;
mod obj_faces;
mod planet;
mod primary_raster;
mod rig;
mod sensor;
mod sensor_fused;
mod sensor_noise;
mod shadow_packet;
mod silhouette;
mod stars;
mod sun_shadow;
mod texture;
mod texture_pbr;
mod trade;
mod truth;
mod waves;
mod window;
