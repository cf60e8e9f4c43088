//! The path-tracing estimator for one camera sample (no threading here).
//!
//! Backward path tracing as in the paper's Eq. (1)/(2): at each surface interaction,
//! direct sunlight by next-event estimation (a shadow ray toward the parallel sun), then
//! one sampled reflected direction for indirect light, up to `depth` interactions
//! (depth 1 = direct only; Mitsuba's `max_depth` = depth + 1). Surfaces are two-sided:
//! the shading normal is flipped to face the incoming ray. Shading uses face normals.

use crate::render::bsdf::Bsdf;
use crate::render::geometry::{Hit, Ray};
use crate::render::planet::{Eclipse, PlacedPlanet};
use crate::render::sampling::{
    SampleSource, Sequence, ShadingBasis, UNIFORM_HEMISPHERE_PDF, cosine_hemisphere, uniform_hemisphere,
};
use crate::render::target::Target;
use crate::render::texture::{MipMap, Texturing};
use glam::Vec3;
use serde::Deserialize;

mod spp;
/// The same estimator run for many camera samples at once, in waves.
pub(in crate::render) mod waves;
pub use spp::{Spp, SppError};

/// How indirect directions are drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplerKind {
    /// Uniform over the hemisphere, pdf 1/(2π) (the paper's baseline).
    Uniform,
    /// Cosine-weighted, pdf cosθ/π (the paper's Eq. 3).
    #[default]
    Cosine,
    /// The BRDF's own importance sampling (specular lobe + cosine by MIS).
    Brdf,
}

/// Quality settings of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Camera samples per pixel (a fraction is shared out by a second stage).
    pub spp: Spp,
    /// Surface interactions per path (≥ 1).
    pub depth: u32,
    pub sampler: SamplerKind,
    /// Independent or low-discrepancy (Sobol) random numbers.
    pub sequence: Sequence,
    /// Russian roulette on low-throughput paths (from the second indirect bounce on).
    pub roulette: bool,
    /// Share the samples out by each pixel's estimated variance (`spp` is then the
    /// average; `render::adaptive`), instead of `spp` in every pixel.
    pub adaptive: bool,
    /// Whether samples are spent until each pixel is as good as the camera
    /// (`render::sensor_plan`), and the fraction `k` of the camera's noise that means.
    pub quality: QualityGoal,
    /// How a frame's pixel areas and light are integrated.
    pub method: Method,
    pub seed: u64,
}

/// How a frame is rendered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Monte Carlo path tracing: `spp` random positions per pixel, each a whole path.
    #[default]
    Path,
    /// Sub-pixel coverage by rasterisation, the sun's light per surface fragment, the
    /// diffuse parts' indirect light from a body-frame cache and the rest by `spp` paths
    /// per pixel (`render::hybrid`); an instant view without a planet, textures or
    /// emission (else the frame is path-traced).
    Hybrid,
}

/// What a frame's samples aim at: a fixed budget, or the camera's own noise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum QualityMode {
    /// `spp` samples per pixel (on average, when adaptive).
    #[default]
    Fixed,
    /// Each pixel gets samples until its Monte Carlo standard deviation, in electrons, is
    /// below `k` × the camera's temporal noise there; `spp` is then the frame's budget
    /// (the average over sampled pixels never exceeds it).
    Sensor,
}

/// [`QualityMode`] and the bound `k` (also what every frame's noise report measures
/// against, in either mode).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct QualityGoal {
    pub mode: QualityMode,
    /// Monte Carlo σ allowed as a fraction of the camera's temporal noise, in (0, 10].
    pub k: f32,
}

impl QualityGoal {
    pub const DEFAULT_K: f32 = 0.5;
    /// `quality = "fixed"` with the default k (the default).
    pub const FIXED: QualityGoal = QualityGoal { mode: QualityMode::Fixed, k: Self::DEFAULT_K };

    pub fn is_sensor(&self) -> bool {
        self.mode == QualityMode::Sensor
    }

    /// `k` checked: finite, in (0, 10].
    pub fn checked_k(k: f64) -> Result<f32, String> {
        if k.is_finite() && k > 0.0 && k <= 10.0 {
            Ok(k as f32)
        } else {
            Err(format!("the Monte Carlo noise bound k must be in (0, 10] (a fraction of the camera's noise), got {k}"))
        }
    }

    /// `k` from text (a `--sensor-k` flag), checked as [`QualityGoal::checked_k`].
    pub fn parse_k(s: &str) -> Result<f32, String> {
        let k: f64 = s.trim().parse().map_err(|_| format!("expected a number such as 0.5, got {s:?}"))?;
        Self::checked_k(k)
    }
}

impl Default for QualityGoal {
    fn default() -> Self {
        Self::FIXED
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            spp: Spp::whole(4),
            depth: 2,
            sampler: SamplerKind::Cosine,
            sequence: Sequence::Sobol,
            roulette: true,
            adaptive: true,
            quality: QualityGoal::default(),
            method: Method::Path,
            seed: 0,
        }
    }
}

impl RenderSettings {
    /// These settings with the given command-line or config overrides (spp and depth at
    /// least 1). One place for `render`, `replay` and `serve`.
    pub fn overridden(
        mut self,
        spp: Option<Spp>,
        depth: Option<u32>,
        sampler: Option<SamplerKind>,
        seed: Option<u64>,
    ) -> Self {
        if let Some(v) = spp {
            self.spp = v;
        }
        if let Some(v) = depth {
            self.depth = v.max(1);
        }
        self.sampler = sampler.unwrap_or(self.sampler);
        self.seed = seed.unwrap_or(self.seed);
        self
    }

    /// These settings with the quality mode and bound `k` overridden (`--quality`,
    /// `--sensor-k`, serve's `[render]`).
    pub fn with_quality(mut self, mode: Option<QualityMode>, k: Option<f32>) -> Self {
        self.quality.mode = mode.unwrap_or(self.quality.mode);
        self.quality.k = k.unwrap_or(self.quality.k);
        self
    }
}

/// Rays traced and samples discarded; summed over threads after a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays that reached the target's bounds and were traced through the BVH.
    pub primary: u64,
    pub shadow: u64,
    pub bounce: u64,
    /// Samples whose estimate was not finite (dropped, counted; should stay 0).
    pub nonfinite: u64,
}

impl RayCounts {
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.bounce
    }
    pub fn add(&mut self, o: &RayCounts) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.bounce += o.bounce;
        self.nonfinite += o.nonfinite;
    }
}

/// Sees every ray the estimator traces (benchmarks record them to re-trace the same rays
/// through the bare BVH). `()` sees nothing and compiles away.
pub trait RayLog {
    fn closest(&mut self, _ray: &Ray) {}
    fn shadow(&mut self, _ray: &Ray) {}
}

impl RayLog for () {}

/// Records rays for [`RayLog`].
#[derive(Default)]
pub struct RecordedRays {
    pub closest: Vec<Ray>,
    pub shadow: Vec<Ray>,
}

impl RayLog for RecordedRays {
    fn closest(&mut self, ray: &Ray) {
        self.closest.push(*ray);
    }
    fn shadow(&mut self, ray: &Ray) {
        self.shadow.push(*ray);
    }
}

/// What one surface interaction produces (see [`PathContext::scatter`]).
pub struct Scatter {
    /// Radiance the surface emits toward the path, times the throughput that reached it.
    pub emitted: f32,
    /// Shadow ray toward the sun, and the radiance it adds if nothing blocks it.
    pub shadow: Option<(Ray, f32)>,
    /// The path's next ray and throughput; `None` when the path ends here.
    pub next: Option<(Ray, f32)>,
}

/// Per-frame constants of the estimator.
pub struct PathContext<'a> {
    pub scene: &'a Target,
    /// Unit vector toward the sun, render frame.
    pub sun: Vec3,
    pub depth: u32,
    pub sampler: SamplerKind,
    /// False when no bounce can carry energy (depth 1 or all materials black).
    pub indirect: bool,
    pub roulette: bool,
    /// The planet behind the target in this frame (escaping rays may meet it; it may hide
    /// the sun).
    pub planet: Option<PlacedPlanet>,
    /// Where the camera is and how wide its pixels are, for texture footprints; `None`
    /// unless the target is textured (`render::texture`).
    pub footprint: Option<Footprint>,
}

/// A camera hit's pixel footprint: `|p − eye| · per_metre` is the pixel's width across
/// the ray at `p`, already scaled by `texture::spp_scale`.
#[derive(Clone, Copy, Debug)]
pub struct Footprint {
    /// The camera's centre, render frame.
    pub eye: Vec3,
    /// Pixel pitch / focal length (rad per pixel) × `max(1/8, 1/√spp)`.
    pub per_metre: f32,
}

impl<'a> PathContext<'a> {
    pub fn new(scene: &'a Target, sun: Vec3, settings: &RenderSettings) -> Self {
        let indirect = settings.depth > 1 && scene.any_reflective();
        PathContext {
            scene,
            sun,
            depth: settings.depth.max(1),
            sampler: settings.sampler,
            indirect,
            roulette: settings.roulette,
            planet: None,
            footprint: None,
        }
    }

    /// This context with the texture footprint of `view`'s pixels at `settings.spp`
    /// (untextured targets: none; without it camera hits look up the finest level). The pinhole's pixel angle at the boresight is
    /// used for every pixel (a lens's distortion changes it by its few per cent).
    pub fn with_view(self, view: &crate::render::camera::View, settings: &RenderSettings) -> Self {
        let footprint = self.scene.texturing.as_ref().map(|_| Footprint {
            eye: view.origin.as_vec3(),
            per_metre: (1.0 / view.focal_px()) as f32 * crate::render::texture::spp_scale(settings.spp.get()),
        });
        PathContext { footprint, ..self }
    }

    /// This context with `planet` behind the target.
    pub fn with_planet(self, planet: Option<PlacedPlanet>) -> Self {
        PathContext { planet, ..self }
    }

    /// Radiance arriving along `ray`, which left the target: the planet's where it meets
    /// it, else the background.
    #[inline]
    pub fn escaped(&self, ray: &Ray) -> f32 {
        match &self.planet {
            None => self.scene.background,
            Some(p) => p.radiance_of_ray(ray).unwrap_or(self.scene.background),
        }
    }

    /// Whether the sun reaches `p` past the planet (the target's own shadows aside).
    #[inline]
    fn sun_reaches(&self, p: Vec3) -> bool {
        match &self.planet {
            None => true,
            Some(planet) => match planet.eclipse {
                Eclipse::Lit => true,
                Eclipse::Dark => false,
                Eclipse::Partial => !planet.hides_sun(p.as_dvec3()),
            },
        }
    }

    /// Whether anything blocks `ray` (a shadow ray).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.scene.accel.occluded(ray)
    }

    /// [`PathContext::occluded`] for up to eight shadow rays toward the sun at once (bit
    /// `i`: ray `i` is blocked); the same answers.
    #[inline]
    pub fn occluded_packet(&self, rays: &[Ray]) -> u32 {
        self.scene.accel.occluded_packet(rays)
    }

    /// Where a ray leaving point `p` of triangle `tri` starts, on the side of `n_out`
    /// (`±` the triangle's normal): on the triangle's plane, moved off it by a few ulps of
    /// the triangle's own coordinates (`geometry::spawn`) — nothing else in the scene and
    /// nothing of the ray that found `p` enters.
    #[inline]
    pub(in crate::render) fn spawn(&self, p: Vec3, tri: u32, n_face: Vec3, n_out: Vec3) -> Vec3 {
        self.scene.planes[tri as usize].spawn(p, n_face, n_out)
    }

    /// Radiance arriving along `ray` (a primary ray), W·sr⁻¹·m⁻²: one path, traced to
    /// the end. The tile renderer (`crate::render`) runs the same steps wave by wave.
    #[inline]
    pub fn radiance<L: RayLog, S: SampleSource>(
        &self,
        ray: Ray,
        rng: &mut S,
        counts: &mut RayCounts,
        log: &mut L,
    ) -> f32 {
        self.radiance_after(ray, 0, 1.0, 0.0, rng, counts, log)
    }

    /// [`PathContext::radiance`] from surface interaction `first` on, for a path that
    /// arrives along `ray` with throughput `beta` having gathered `l` so far (a caller
    /// that made the earlier interactions itself).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn radiance_after<L: RayLog, S: SampleSource>(
        &self,
        mut ray: Ray,
        first: u32,
        mut beta: f32,
        mut l: f32,
        rng: &mut S,
        counts: &mut RayCounts,
        log: &mut L,
    ) -> f32 {
        let scene = self.scene;
        for bounce in first..self.depth {
            if bounce == 0 {
                counts.primary += 1;
            } else {
                counts.bounce += 1;
            }
            log.closest(&ray);
            let Some(hit) = scene.accel.intersect(&ray) else {
                l += beta * self.escaped(&ray);
                break;
            };
            let sc = self.scatter(&ray, &hit, beta, bounce, rng);
            l += sc.emitted;
            if let Some((shadow, contribution)) = sc.shadow {
                counts.shadow += 1;
                log.shadow(&shadow);
                if !self.occluded(&shadow) {
                    l += contribution;
                }
            }
            match sc.next {
                Some((next, b)) => (ray, beta) = (next, b),
                None => break,
            }
        }
        l
    }

    /// One surface interaction of a path with throughput `beta` arriving along `ray`:
    /// the shadow ray toward the sun with the radiance it adds if unoccluded (next-event
    /// estimation: the sun is a delta light, so this is the whole direct estimate), and
    /// the path's next ray and throughput, if it goes on.
    #[inline(always)]
    pub fn scatter<S: SampleSource>(&self, ray: &Ray, hit: &Hit, beta: f32, bounce: u32, rng: &mut S) -> Scatter {
        let wo = -ray.dir;
        let mut n = hit.normal;
        if n.dot(wo) < 0.0 {
            n = -n;
        }
        let p = ray.origin + ray.dir * hit.t;
        let material = &self.scene.materials[hit.material as usize];
        let own = &material.bsdf;
        // A texture's value here: camera hits prefilter over the pixel's footprint on the
        // surface, √(area) of its projection (width / √cosθ); bounces take the finest level.
        let texel = |tx: &Texturing, mip: &MipMap| {
            let width = self.footprint.filter(|_| bounce == 0).map(|f| {
                let cos = hit.normal.dot(wo).abs().max(1e-3);
                (p - f.eye).length() * f.per_metre / cos.sqrt()
            });
            tx.value_at(mip, hit.tri, self.scene.mesh.triangle(hit.tri as usize), p, width)
        };
        let texturing = self.scene.texturing.as_deref();
        let mut emitted = 0.0;
        if material.emission > 0.0 {
            let scale = match texturing.and_then(|t| Some((t, t.emission_of(hit.material)?))) {
                None => 1.0,
                Some((tx, mip)) => texel(tx, mip),
            };
            emitted = beta * material.emission * scale;
        }
        let textured;
        let bsdf = match texturing {
            None => own,
            Some(tx) => {
                let base = tx.base_of(hit.material).map(|mip| texel(tx, mip));
                let rm = tx.roughness_metallic_of(hit.material);
                if base.is_none() && rm.is_none() {
                    own
                } else {
                    let mut b = base.map_or(*own, |v| own.with_base(v));
                    // Only GGX has a roughness and a metallic weight.
                    if let (Some(rm), Bsdf::Ggx(g)) = (rm, &b) {
                        let r = rm.roughness.map(|mip| texel(tx, mip));
                        let m = rm.metallic.map(|mip| texel(tx, mip));
                        b = Bsdf::Ggx(g.with_roughness_metallic(r, m, rm.coating));
                    }
                    textured = b;
                    &textured
                }
            }
        };
        let origin = self.spawn(p, hit.tri, hit.normal, n);
        // A normal map tilts the shading frame; the geometric side `n` still decides what
        // the sun and a bounce can reach. The back face shades with the mirrored normal.
        let shading = texturing.and_then(|tx| {
            let corners = self.scene.mesh.triangle(hit.tri as usize);
            let front = tx.shading_normal(hit.material, hit.tri, corners, hit.normal, |mip| texel(tx, mip))?;
            Some(if n == hit.normal { front } else { -front })
        });
        let basis = ShadingBasis::from_normal(shading.unwrap_or(n));
        let wo_l = basis.to_local(wo);

        let mut shadow = None;
        if n.dot(self.sun) > 0.0 && self.sun_reaches(origin) {
            let f_cos = bsdf.eval_cos(wo_l, basis.to_local(self.sun));
            if f_cos > 0.0 {
                let ray = Ray { origin, dir: self.sun, tmax: f32::INFINITY };
                shadow = Some((ray, beta * f_cos * self.scene.sun_irradiance));
            }
        }
        if !self.indirect || bounce + 1 == self.depth || bsdf.is_black() {
            return Scatter { emitted, shadow, next: None };
        }
        let u = rng.next_2d();
        let (wi_l, weight) = match self.sampler {
            SamplerKind::Uniform => {
                let wi = uniform_hemisphere(u);
                (wi, bsdf.eval_cos(wo_l, wi) / UNIFORM_HEMISPHERE_PDF)
            }
            SamplerKind::Cosine => {
                let wi = cosine_hemisphere(u);
                (wi, bsdf.cosine_weight(wo_l, wi))
            }
            SamplerKind::Brdf => match bsdf.sample(wo_l, u, rng.next_1d()) {
                Some(s) if s.pdf > 0.0 => (s.wi, s.f_cos / s.pdf),
                _ => return Scatter { emitted, shadow, next: None },
            },
        };
        let mut beta = beta * weight;
        if beta <= 0.0 || !beta.is_finite() {
            return Scatter { emitted, shadow, next: None };
        }
        let dir = basis.to_world(wi_l);
        // Above the shading normal but into the surface: the path ends (pbrt's rule).
        if shading.is_some() && dir.dot(n) <= 0.0 {
            return Scatter { emitted, shadow, next: None };
        }
        // Russian roulette from the second indirect bounce on: a path whose throughput
        // fell below 1 survives with probability `beta` and carries 1 afterwards —
        // unbiased, and low-throughput paths stop costing rays.
        if self.roulette && bounce >= 1 && beta < 1.0 {
            if rng.next_1d() >= beta {
                return Scatter { emitted, shadow, next: None };
            }
            beta = 1.0;
        }
        Scatter { emitted, shadow, next: Some((Ray { origin, dir, tmax: f32::INFINITY }, beta)) }
    }
}
