//! The hybrid frame (`method = "hybrid"`): sub-pixel coverage by rasterisation, the sun's
//! light per surface fragment, the diffuse parts' indirect light from a body-frame cache
//! ([`indirect_cache`]) and the rest of it by path tracing from `spp` coverage samples per
//! pixel.
//!
//! The pixel-area integral that a path tracer estimates with one random position per
//! sample — where edges, creases and glints make most of a low-spp frame's noise — is here
//! taken over 64 stratified positions per pixel ([`pattern`]) for the cost of an edge test
//! each ([`tile`]): each position finds its nearest triangle on the ideal image plane, the
//! pixel's positions are grouped by triangle into fragments, and the sun's light on each
//! fragment is evaluated once at the fragment's mean position ([`shade`]). Exact for flat
//! facets under a parallel sun up to the sampling of the pixel's area and the view
//! direction's change across a fragment (second order).
//!
//! Applies to an instant view (no motion over the exposure) with every vertex in front of
//! the camera and no planet, texture or emitting surface; otherwise [`render`] returns
//! None and the caller path-traces.

pub mod area;
pub mod caustics;
pub mod cells;
pub mod indirect_cache;
pub mod pattern;
mod sample_loops;
pub mod setup;
mod shade;
pub mod shadow;
pub mod tile;

use crate::render::camera::{PixelRect, View};
use crate::render::film::RadianceImage;
use crate::render::integrator::{PathContext, RayCounts, RenderSettings};
use crate::render::target::Target;
use rayon::prelude::*;
use setup::{Setup, TILE};
use tile::{Fragment, TileBuffers};

/// Buffers kept from frame to frame.
#[derive(Default)]
pub struct HybridBuffers {
    setup: Setup,
    /// The cells' sun classes, kept while the sun's direction in the body frame stays.
    shadows: shadow::ShadowMemo,
    /// The diffuse parts' indirect light per cell, kept likewise.
    indirect: indirect_cache::IndirectCache,
}

/// What a hybrid frame did.
#[derive(Clone, Copy, Debug, Default)]
pub struct HybridStats {
    pub rays: RayCounts,
    /// Triangles set up (inside the rectangle) and fragments shaded.
    pub triangles: u64,
    pub fragments: u64,
    /// Pixels of the rectangle where a triangle was found.
    pub covered_pixels: u64,
    /// Shadow rays spent classifying cells for a new sun direction (0 when held).
    pub classify_rays: u64,
    /// Covered pixels whose shares are exact areas (`tile::exact_shares`).
    pub exact_pixels: u64,
    /// Cell sides whose indirect light was estimated in this frame (0 once every cell
    /// the view reaches is kept), and the rays that took (also in `rays`).
    pub cache_cells: u64,
    pub cache_rays: u64,
    /// Photons followed from the sun for the cache's caustics (0 when held, or when no
    /// material is glossy).
    pub caustic_photons: u64,
}

/// Render `rect` of `view` into `img` (whose other pixels the caller has set). None when
/// the frame cannot be rasterised (see the module docs): nothing was written.
pub fn render(
    img: &mut RadianceImage,
    buffers: &mut HybridBuffers,
    target: &Target,
    view: &View,
    rect: PixelRect,
    settings: &RenderSettings,
    frame: u64,
) -> Option<HybridStats> {
    // Its fragments shade with each material's own BRDF and no emission: a textured or
    // emitting target is path-traced.
    if view.motion.is_some() || target.planet.is_some() || target.texturing.is_some() || target.any_emitting() {
        return None;
    }
    let HybridBuffers { setup, shadows, indirect } = buffers;
    if !setup.build(target, view, rect) {
        return None;
    }
    let setup = &*setup;
    let ctx = PathContext::new(target, view.sun, settings);
    let classify_rays = shadows.update(&ctx);
    let rest_settings = RenderSettings { depth: settings.depth.saturating_sub(1).max(1), ..*settings };
    let rest = PathContext::new(target, view.sun, &rest_settings);
    let rest = (settings.depth > 1 && ctx.indirect).then_some(&rest);
    if rest.is_some() {
        indirect.update(&ctx, settings);
    }
    let shader = shade::Shader {
        view,
        ctx: &ctx,
        rest,
        memo: shadows,
        cache: rest.map(|_| &*indirect),
        paths: settings.spp.floor(),
        seed: settings.seed,
        frame,
    };
    // Depth keys relative to the target's centre, scaled by its range² (≈ metres).
    let range = view.to_camera(target.bounds.centre).z.max(1e-3);
    let depth_key = (1.0 / range, range * range);
    let key = |row: u32, col: u32| view.pixel_key(row, col);
    let tri_of = |i: u32| setup.tris[i as usize].tri;
    let w = img.width as usize;
    let rows = &mut img.data[rect.row0 as usize * w..rect.row1 as usize * w];
    let stats = rows
        .par_chunks_mut(TILE as usize * w)
        .enumerate()
        .map_init(
            || (TileBuffers::default(), Vec::<Fragment>::new()),
            |(buf, frags), (ty, band)| {
                let mut st = HybridStats::default();
                for tx in 0..setup.tiles_x {
                    if tile::tile_list(setup, tx, ty as u32).is_empty() {
                        continue;
                    }
                    tile::rasterise(setup, tx, ty as u32, settings.seed, frame, &key, depth_key, buf);
                    let ([c0, c1], [r0, r1]) = tile::tile_pixels(setup, tx, ty as u32);
                    for row in r0..r1 {
                        for col in c0..c1 {
                            let p = ((row - r0) * TILE + (col - c0)) as usize;
                            if !buf.touched[p] {
                                continue;
                            }
                            frags.clear();
                            let background = tile::resolve(&buf.id[p], &buf.sx[p], &buf.sy[p], frags);
                            // Exact shares also find slivers in a pixel none of whose
                            // samples a triangle covers (an edge clipping its corner).
                            let exact = tile::exact_shares(setup, &buf.inside[p], &buf.map[p], frags);
                            if frags.is_empty() {
                                continue; // the caller's background stays
                            }
                            st.exact_pixels += u64::from(exact.is_some());
                            let background = exact.unwrap_or(background as f32 / pattern::SAMPLES as f32);
                            st.covered_pixels += 1;
                            st.fragments += frags.len() as u64;
                            let px = shade::PixelSamples {
                                ids: &buf.id[p],
                                sx: &buf.sx[p],
                                sy: &buf.sy[p],
                                map: &buf.map[p],
                            };
                            let v = shade::pixel(&shader, &tri_of, &px, frags, background, (row, col), &mut st.rays);
                            band[(row - rect.row0 - ty as u32 * TILE) as usize * w + col as usize] = v;
                        }
                    }
                }
                st
            },
        )
        .reduce(HybridStats::default, |mut a, b| {
            a.rays.add(&b.rays);
            a.fragments += b.fragments;
            a.covered_pixels += b.covered_pixels;
            a.exact_pixels += b.exact_pixels;
            a
        });
    let (cache_cells, cache_rays, caustic_photons) = indirect.take_counts();
    let mut rays = stats.rays;
    rays.bounce += cache_rays;
    Some(HybridStats {
        triangles: setup.tris.len() as u64,
        classify_rays,
        cache_cells,
        cache_rays,
        caustic_photons,
        rays,
        ..stats
    })
}
