//! `hilcam bench sampling` / `hilcam bench glints`: the paper's Table 1 (uniform vs
//! cosine-weighted indirect sampling on fold planes) and its Fig. 7 glint case, with the
//! BRDF's own MIS sampling as a third column.
//!
//! The scene is the paper's §3.2 set-up: a fold plane (1 m-radius disk, normal +X) seen
//! along its normal by a far camera with a long focal length (nearly orthographic; the
//! disk fills the frame), a parallel sun at θi from the normal, a uniform sky (black by
//! default; [`PlaneCase::with_sky`]) that escaping rays collect. RMSE is the
//! absolute radiance error (W·sr⁻¹·m⁻²) over the pixels whose centre ray hits the disk,
//! against a converged reference of the same scene rendered as two independent halves, so
//! the reference's own noise is measured (`ref_noise`) rather than assumed.

use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::bsdf::{Bsdf, Lambert};
use hilcam_core::render::camera::{CameraModel, View};
use hilcam_core::render::film::RadianceImage;
use hilcam_core::render::geometry::{BvhLayout, TriMesh};
use hilcam_core::render::integrator::{RenderSettings, SamplerKind, Spp};
use hilcam_core::render::sampling::Sequence;
use hilcam_core::render::{RenderOptions, render};
use hilcam_core::scene::{Material, Scene, SceneParts};
use hilcam_core::sensor::SensorConfig;
use std::time::Instant;

/// Range from the camera to the disk centre (m): far enough to be nearly orthographic.
pub const RANGE_M: f64 = 1000.0;
/// Width of the field of view at the disk (m): the 2 m disk plus a small margin.
pub const FIELD_M: f64 = 2.1;
/// The paper's Lambert reflectance of the fold planes (§3.2).
pub const PAPER_RHO: f32 = 0.3717;
/// The paper's parallel-light irradiance (W/m²).
pub const PAPER_IRRADIANCE: f64 = 100.0;

/// One scene of the benchmark: a plane seen along its normal, and the disk-pixel mask.
pub struct PlaneCase {
    pub scene: Scene,
    pub camera: CameraModel,
    pub pose: Pose,
    /// True for pixels whose centre ray hits the mesh (the pixels the RMSE is taken over).
    pub mask: Vec<bool>,
}

impl PlaneCase {
    /// `mesh` is a plane with normal +X (e.g. [`hilcam_core::scene::fold::generate_plane`]); the camera
    /// looks along −X from `RANGE_M`, `size`×`size` pixels over `FIELD_M`; the sun is
    /// `theta_i_deg` from the normal (toward camera +X), the sky black.
    pub fn new(mesh: TriMesh, bsdf: Bsdf, irradiance: f64, theta_i_deg: f64, size: u32) -> PlaneCase {
        let pitch_um = 10.0;
        let focal_px = f64::from(size) * RANGE_M / FIELD_M;
        let camera = CameraModel {
            width: size,
            height: size,
            pitch_um,
            focal_mm: focal_px * pitch_um * 1e-3,
            principal_point_px: [0.0, 0.0],
        };
        let t = theta_i_deg.to_radians();
        // Body +X (the plane normal) → camera −Z: the plane faces the camera.
        let pose = Pose {
            position: DVec3::new(0.0, 0.0, RANGE_M),
            attitude: DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2),
            sun_dir: DVec3::new(t.sin(), 0.0, -t.cos()),
            ..Pose::ahead(RANGE_M)
        };
        let scene = Scene::build(SceneParts {
            mesh,
            materials: vec![Material::new("plane", bsdf)],
            sun_irradiance: irradiance,
            background: 0.0,
            camera: camera.clone(),
            sensor: SensorConfig::default(),
            pose,
            render: RenderSettings::default(),
            layout: BvhLayout::default(),
            stars: None,
            planet: None,
            limits: Default::default(),
            texturing: None,
        });
        let view =
            View::new(&camera, &pose, scene.frame_origin_body, scene.bounds).with_parts(Some(scene.parts.clone()));
        let mask = (0..size)
            .flat_map(|row| (0..size).map(move |col| (col, row)))
            .map(|(col, row)| {
                view.primary_ray(f64::from(col) + 0.5, f64::from(row) + 0.5)
                    .is_some_and(|r| scene.accel.intersect(&r).is_some())
            })
            .collect();
        PlaneCase { scene, camera, pose, mask }
    }

    /// The paper's Table 1 scene: Lambert 0.3717, 100 W/m² at θi = 10°.
    pub fn paper_lambert(mesh: TriMesh, size: u32) -> PlaneCase {
        PlaneCase::paper_lambert_lit(mesh, size, PAPER_IRRADIANCE, 0.0)
    }

    /// The paper's Table 1 scene with the sun irradiance `sun` (W/m²) and a uniform sky of
    /// radiance `sky` (W·sr⁻¹·m⁻²) collected by escaping rays: the reading of §3.2 / Fig. 2
    /// in which the source's "radiance 100" is also what an escaped ray accumulates.
    pub fn paper_lambert_lit(mesh: TriMesh, size: u32, sun: f64, sky: f64) -> PlaneCase {
        let bsdf = Bsdf::Lambert(Lambert::new(PAPER_RHO).expect("0.3717 is a valid albedo"));
        PlaneCase::new(mesh, bsdf, sun, 10.0, size).with_sky(sky)
    }

    /// This case with escaping rays collecting a uniform sky of radiance `sky`
    /// (W·sr⁻¹·m⁻²): the scene's background radiance.
    pub fn with_sky(mut self, sky: f64) -> PlaneCase {
        self.scene.background = sky as f32;
        self
    }

    /// Render with `settings`; returns the image and the wall time (s).
    pub fn render(&self, settings: &RenderSettings) -> (RadianceImage, f64) {
        let t0 = Instant::now();
        let view = self.scene.view(&self.camera, &self.pose);
        let (img, stats) = render(&self.scene, &view, &RenderOptions::new(*settings, 0));
        if stats.rays.nonfinite > 0 {
            tracing::warn!(nonfinite = stats.rays.nonfinite, "sampling bench: non-finite samples dropped");
        }
        (img, t0.elapsed().as_secs_f64())
    }

    /// Pixels in the mask.
    pub fn disk_pixels(&self) -> usize {
        self.mask.iter().filter(|m| **m).count()
    }
}

/// Root-mean-square difference over the masked pixels (0 if the mask is empty).
pub fn rmse(a: &RadianceImage, b: &RadianceImage, mask: &[bool]) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for ((x, y), m) in a.data.iter().zip(&b.data).zip(mask) {
        if *m {
            let d = f64::from(*x) - f64::from(*y);
            s += d * d;
            n += 1;
        }
    }
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

/// A converged reference: two independent halves of `spp` each (seeds differ), averaged.
pub struct Reference {
    pub image: RadianceImage,
    /// The direct-sunlight part of `image` (depth 1, the same samples' pixel positions).
    pub direct: RadianceImage,
    /// RMS error of the averaged reference itself, estimated as rms(A − B)/2.
    pub noise: f64,
    /// Mean radiance of `image` over the disk pixels (the scale the RMSEs compare with).
    pub mean: f64,
    pub spp: u32,
    pub time_s: f64,
}

/// Render the reference with `sampler` and the Sobol sequence, `2 × half_spp` samples.
pub fn reference(case: &PlaneCase, sampler: SamplerKind, half_spp: u32, depth: u32) -> Reference {
    let s = |seed| RenderSettings {
        spp: Spp::whole(half_spp),
        depth,
        sampler,
        sequence: Sequence::Sobol,
        roulette: false,
        adaptive: false,
        quality: Default::default(),
        method: Default::default(),
        seed,
    };
    let (a, ta) = case.render(&s(1_000_001));
    let (b, tb) = case.render(&s(2_000_003));
    let noise = rmse(&a, &b, &case.mask) / 2.0;
    let direct = |seed| case.render(&RenderSettings { depth: 1, ..s(seed) }).0;
    let image = average(&a, &b);
    let disk: Vec<f64> = image.data.iter().zip(&case.mask).filter(|(_, m)| **m).map(|(v, _)| f64::from(*v)).collect();
    Reference {
        mean: disk.iter().sum::<f64>() / disk.len().max(1) as f64,
        image,
        direct: average(&direct(1_000_001), &direct(2_000_003)),
        noise,
        spp: 2 * half_spp,
        time_s: ta + tb,
    }
}

fn average(a: &RadianceImage, b: &RadianceImage) -> RadianceImage {
    let data = a.data.iter().zip(&b.data).map(|(x, y)| 0.5 * (x + y)).collect();
    RadianceImage { width: a.width, height: a.height, data }
}

fn minus(a: &RadianceImage, b: &RadianceImage) -> RadianceImage {
    let data = a.data.iter().zip(&b.data).map(|(x, y)| x - y).collect();
    RadianceImage { width: a.width, height: a.height, data }
}

/// One measured cell: a sampler at a sample count.
#[derive(Clone, Debug)]
pub struct Cell {
    pub sampler: SamplerKind,
    pub sequence: Sequence,
    pub spp: u32,
    pub rmse: f64,
    /// RMSE of the indirect part alone: image minus its direct-only twin (same seed and
    /// sequence, so the same pixel positions), against the reference's indirect part.
    /// Removes the pixel-footprint noise of the fold texture, which no sampler changes.
    pub rmse_indirect: f64,
    pub time_s: f64,
}

/// Render `case` with each sampler at each sample count and measure the RMSE against
/// `reference`. `keep` receives each image (for the figure grid).
#[allow(clippy::too_many_arguments)]
pub fn sweep(
    case: &PlaneCase,
    reference: &Reference,
    samplers: &[SamplerKind],
    spps: &[u32],
    sequence: Sequence,
    depth: u32,
    seed: u64,
    mut keep: impl FnMut(SamplerKind, u32, &RadianceImage),
) -> Vec<Cell> {
    let mut out = Vec::new();
    let ref_indirect = minus(&reference.image, &reference.direct);
    let direct: Vec<RadianceImage> = spps
        .iter()
        .map(|&spp| {
            case.render(&RenderSettings {
                spp: Spp::whole(spp),
                depth: 1,
                sampler: SamplerKind::Cosine,
                sequence,
                roulette: false,
                adaptive: false,
                quality: Default::default(),
                method: Default::default(),
                seed,
            })
            .0
        })
        .collect();
    for &sampler in samplers {
        for (k, &spp) in spps.iter().enumerate() {
            let settings = RenderSettings {
                spp: Spp::whole(spp),
                depth,
                sampler,
                sequence,
                roulette: false,
                adaptive: false,
                quality: Default::default(),
                method: Default::default(),
                seed,
            };
            let (img, time_s) = case.render(&settings);
            let e = rmse(&img, &reference.image, &case.mask);
            let ei = rmse(&minus(&img, &direct[k]), &ref_indirect, &case.mask);
            tracing::debug!(?sampler, spp, rmse = e, rmse_indirect = ei, time_s, "sampling bench cell");
            keep(sampler, spp, &img);
            out.push(Cell { sampler, sequence, spp, rmse: e, rmse_indirect: ei, time_s });
        }
    }
    out
}

/// The RMSE of `sampler` at `spp` in `cells`.
pub fn rmse_of(cells: &[Cell], sampler: SamplerKind, spp: u32) -> Option<f64> {
    cells.iter().find(|c| c.sampler == sampler && c.spp == spp).map(|c| c.rmse)
}

/// The indirect-part RMSE of `sampler` at `spp` in `cells`.
pub fn rmse_indirect_of(cells: &[Cell], sampler: SamplerKind, spp: u32) -> Option<f64> {
    cells.iter().find(|c| c.sampler == sampler && c.spp == spp).map(|c| c.rmse_indirect)
}

/// Relative reduction `(base − x)/base` in percent.
pub fn reduction_pct(base: f64, x: f64) -> f64 {
    if base > 0.0 { 100.0 * (base - x) / base } else { f64::NAN }
}

/// `sampler`'s RMSE at wall time `t`, interpolated log–log on its (time, RMSE) points
/// (sorted by time); extrapolated from the nearest two points outside their range.
pub fn rmse_at_time(cells: &[Cell], sampler: SamplerKind, t: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = cells
        .iter()
        .filter(|c| c.sampler == sampler && c.time_s > 0.0 && c.rmse > 0.0)
        .map(|c| (c.time_s.ln(), c.rmse.ln()))
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    if pts.len() < 2 {
        return pts.first().map(|p| p.1.exp());
    }
    let lt = t.ln();
    let k = pts.windows(2).position(|w| lt <= w[1].0).unwrap_or(pts.len() - 2);
    let (a, b) = (pts[k], pts[k + 1]);
    let f = if b.0 > a.0 { (lt - a.0) / (b.0 - a.0) } else { 0.0 };
    Some((a.1 + f * (b.1 - a.1)).exp())
}

/// Tile 8-bit previews into one grayscale image: `rows[r][c]`, all scaled by `scale`
/// (radiance mapped to white), with a `gap`-pixel black border between tiles.
pub fn image_grid(rows: &[Vec<RadianceImage>], scale: f32, gap: u32) -> image::GrayImage {
    let (tw, th) = rows.first().and_then(|r| r.first()).map_or((0, 0), |i| (i.width, i.height));
    let ncol = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let (w, h) = (ncol * (tw + gap) + gap, rows.len() as u32 * (th + gap) + gap);
    let mut out = image::GrayImage::new(w, h);
    for (r, row) in rows.iter().enumerate() {
        for (c, img) in row.iter().enumerate() {
            let (x0, y0) = (gap + c as u32 * (tw + gap), gap + r as u32 * (th + gap));
            for y in 0..img.height.min(th) {
                for x in 0..img.width.min(tw) {
                    let v = (img.get(x, y) / scale).clamp(0.0, 1.0);
                    out.put_pixel(x0 + x, y0 + y, image::Luma([(v * 255.0).round() as u8]));
                }
            }
        }
    }
    out
}

/// Name of a sampler as in the tables.
pub fn sampler_name(s: SamplerKind) -> &'static str {
    match s {
        SamplerKind::Uniform => "uniform",
        SamplerKind::Cosine => "cosine",
        SamplerKind::Brdf => "brdf",
    }
}

/// Name of a sequence as in the tables.
pub fn sequence_name(s: Sequence) -> &'static str {
    match s {
        Sequence::Independent => "independent",
        Sequence::Sobol => "sobol",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(sampler: SamplerKind, spp: u32, rmse: f64, time_s: f64) -> Cell {
        Cell { sampler, sequence: Sequence::Independent, spp, rmse, rmse_indirect: rmse, time_s }
    }

    #[test]
    fn rmse_over_mask_only() {
        let a = RadianceImage { width: 2, height: 1, data: vec![1.0, 100.0] };
        let b = RadianceImage { width: 2, height: 1, data: vec![4.0, 0.0] };
        assert_eq!(rmse(&a, &b, &[true, false]), 3.0);
        assert_eq!(rmse(&a, &b, &[false, false]), 0.0);
    }

    #[test]
    fn time_interpolation_is_log_log() {
        // RMSE ∝ t^−½: at t = 4 between (1, 2) and (16, 0.5) the answer is 1.
        let cells = [cell(SamplerKind::Cosine, 1, 2.0, 1.0), cell(SamplerKind::Cosine, 16, 0.5, 16.0)];
        let r = rmse_at_time(&cells, SamplerKind::Cosine, 4.0).unwrap();
        assert!((r - 1.0).abs() < 1e-12, "{r}");
        // Beyond the range: extrapolated on the same line.
        let r = rmse_at_time(&cells, SamplerKind::Cosine, 64.0).unwrap();
        assert!((r - 0.25).abs() < 1e-12, "{r}");
        assert!(rmse_at_time(&cells, SamplerKind::Uniform, 4.0).is_none());
    }

    #[test]
    fn flat_disk_direct_only_matches_lambert() {
        // Depth 1 on a flat disk: every disk pixel is ρ·E·cosθi/π exactly (no noise).
        let case = PlaneCase::paper_lambert(hilcam_core::scene::fold::disk::reference_disk(), 16);
        let s = RenderSettings { spp: Spp::whole(2), depth: 1, roulette: false, ..Default::default() };
        let (img, _) = case.render(&s);
        let want = f64::from(PAPER_RHO) * PAPER_IRRADIANCE * 10f64.to_radians().cos() / std::f64::consts::PI;
        let n = case.disk_pixels();
        // A 2.1 m field over 16 px: the disk covers ≈ π/4·(2/2.1)² of the frame.
        assert!(n > 150 && n < 200, "{n}");
        assert_interior_pixels(&case, &img.data, want, 1e-3);
    }

    /// Every interior pixel of a 16×16 disk render (all 8 neighbours on the disk too, so
    /// covered entirely) is within `rel` of `want`; more than 100 of them are checked.
    fn assert_interior_pixels(case: &PlaneCase, img: &[f32], want: f64, rel: f64) {
        let inside = |c: i32, r: i32| (0..16).contains(&c) && (0..16).contains(&r) && case.mask[(r * 16 + c) as usize];
        let mut checked = 0;
        for r in 0..16 {
            for c in 0..16 {
                if (-1..=1).all(|dr| (-1..=1).all(|dc| inside(c + dc, r + dr))) {
                    let v = f64::from(img[(r * 16 + c) as usize]);
                    assert!((v - want).abs() < rel * want, "pixel ({c}, {r}): {v} vs {want}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 100, "{checked}");
    }

    #[test]
    fn sky_lights_escaping_rays_of_the_bench_scene() {
        // Flat disk, sun 100 W/m² at 10° and sky L: a fully covered pixel sees
        // ρ·E·cosθi/π + ρ·L. Cosine sampling of a Lambert plate under a uniform sky has zero
        // variance (f·cos/pdf = ρ), so with depth 2 every interior pixel is exact.
        let (sun, sky) = (100.0, 50.0);
        let rho = f64::from(PAPER_RHO);
        let want = rho * sun * 10f64.to_radians().cos() / std::f64::consts::PI + rho * sky;
        assert_eq!(PlaneCase::paper_lambert(hilcam_core::scene::fold::disk::reference_disk(), 8).scene.background, 0.0);
        let case = PlaneCase::paper_lambert_lit(hilcam_core::scene::fold::disk::reference_disk(), 16, sun, sky);
        assert_eq!(case.scene.background, sky as f32);
        let s = RenderSettings {
            spp: Spp::whole(4),
            depth: 2,
            sampler: SamplerKind::Cosine,
            sequence: Sequence::Independent,
            roulette: false,
            adaptive: false,
            quality: Default::default(),
            method: Default::default(),
            seed: 5,
        };
        let (img, _) = case.render(&s);
        assert_interior_pixels(&case, &img.data, want, 1e-4);
    }
}
