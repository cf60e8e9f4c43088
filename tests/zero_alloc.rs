//! Rendering into reused buffers (`render_into`, what `FramePipeline::frame` does in
//! `hilcam serve` and replay) allocates nothing once the buffers have grown to the frame's
//! size, and reuse never carries anything from one frame into the next.
//!
//! A counting global allocator sees every allocation of this test binary, on every thread.

mod common;
use common::scenes::scaled_camera;
use glam::{DQuat, DVec3};
use hilcam_core::pose::Pose;
use hilcam_core::render::camera::View;
use hilcam_core::render::integrator::RenderSettings;
use hilcam_core::render::integrator::Spp;
use hilcam_core::render::sampling::Sequence;
use hilcam_core::render::{FrameBuffers, PrimaryVisibility, RenderOptions, render, render_into};
use hilcam_core::scene::Scene;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

struct Counting;

static ARMED: AtomicBool = AtomicBool::new(false);
static CALLS: AtomicU64 = AtomicU64::new(0);
static BYTES: AtomicU64 = AtomicU64::new(0);

fn count(size: usize) {
    if ARMED.load(Relaxed) {
        CALLS.fetch_add(1, Relaxed);
        BYTES.fetch_add(size as u64, Relaxed);
    }
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The counter is global: the tests of this binary take turns.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// (allocation calls, bytes) made while `f` runs.
fn allocations_during<R>(f: impl FnOnce() -> R) -> (R, u64, u64) {
    let (c0, b0) = (CALLS.load(Relaxed), BYTES.load(Relaxed));
    ARMED.store(true, Relaxed);
    let r = f();
    ARMED.store(false, Relaxed);
    (r, CALLS.load(Relaxed) - c0, BYTES.load(Relaxed) - b0)
}

#[test]
fn frames_into_reused_buffers_allocate_nothing_and_match_fresh_frames() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let scene: Scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    let camera = scaled_camera(&scene, 256, 256, [0.0, 0.0]);
    // The shipped pose, and one nearer and turned, so the frames cover different rows,
    // bands and pixels.
    let near = Pose {
        position: scene.pose.position * 0.7 + DVec3::new(1.0, -0.5, 0.0),
        attitude: scene.pose.attitude * DQuat::from_rotation_z(0.6),
        ..scene.pose
    };
    let poses = [scene.pose, near];
    let base = RenderSettings { spp: Spp::whole(4), depth: 4, roulette: false, ..scene.render };
    let settings = [
        RenderSettings { adaptive: true, sequence: Sequence::Sobol, ..base },
        RenderSettings { adaptive: false, sequence: Sequence::Sobol, ..base },
        RenderSettings { adaptive: true, sequence: Sequence::Independent, ..base },
    ];
    // Each pose through a pinhole and through the scene camera's lens (as `FramePipeline`
    // renders it): a lens's silhouette has per-row buffers of its own.
    let lens = scene.sensor.optics.distortion;
    assert!(lens.is_some(), "the shipped navigation camera has a lens");
    let views: Vec<View> = [None, lens]
        .iter()
        .flat_map(|&d| poses.iter().map(move |p| (d, p)))
        .map(|(d, p)| View::new(&camera, p, scene.frame_origin_body, scene.bounds).with_distortion(d))
        .collect();
    let cases: Vec<(usize, usize)> = (0..views.len()).flat_map(|v| (0..settings.len()).map(move |s| (v, s))).collect();
    // Rasterised primary hits, and traced ones (packets, leaf-box coverage).
    for primary in [PrimaryVisibility::Raster, PrimaryVisibility::Trace] {
        let fresh: Vec<Vec<f32>> = cases
            .iter()
            .map(|&(v, s)| render(&scene, &views[v], &RenderOptions::new(settings[s], 3).with_primary(primary)).0.data)
            .collect();

        // Called from outside a pool (as `hilcam serve`'s render thread does), rayon queues
        // each parallel loop (at most 8 per frame) on its global injector, which allocates one
        // block of 63 slots (1520 bytes) when the last one fills: its own bookkeeping. A round
        // of twelve frames queues at most 96 loops, so at most two blocks (measured: 1 or 2).
        // Anything of ours would be far larger.
        {
            let mut buffers = FrameBuffers::<()>::default();
            let all_frames = |buffers: &mut FrameBuffers| {
                for &(v, s) in &cases {
                    render_into(buffers, &scene, &views[v], &RenderOptions::new(settings[s], 3).with_primary(primary));
                }
            };
            all_frames(&mut buffers);
            all_frames(&mut buffers);
            for round in 0..3 {
                let (_, calls, bytes) = allocations_during(|| all_frames(&mut buffers));
                assert!(
                    calls <= 2 && bytes <= 2 * 1520,
                    "{primary:?}, outside a pool, round {round}: {calls} allocations, {bytes} bytes"
                );
            }
        }
        // Inside one `install` the loops run as jobs of the pool's own threads: nothing at all.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        pool.install(|| {
            let mut buffers = FrameBuffers::<()>::default();
            let frame = |v: usize, s: usize, buffers: &mut FrameBuffers| {
                render_into(buffers, &scene, &views[v], &RenderOptions::new(settings[s], 3).with_primary(primary))
            };
            // Warm-up: every case once grows the buffers to the largest frame (and shows
            // that the counter sees the renderer's allocations).
            let (_, warm_up_calls, warm_up_bytes) = allocations_during(|| {
                for &(v, s) in &cases {
                    frame(v, s, &mut buffers);
                }
            });
            assert!(warm_up_calls > 50 && warm_up_bytes > 1 << 20, "{warm_up_calls} calls, {warm_up_bytes} bytes");
            // Then every case again, interleaved so that each frame follows a different one.
            for (k, &(v, s)) in cases.iter().enumerate().chain(cases.iter().enumerate().rev()) {
                let (stats, calls, bytes) = allocations_during(|| frame(v, s, &mut buffers));
                assert!(stats.primary_rasterised == (primary == PrimaryVisibility::Raster), "case {k}: {stats:?}");
                assert!(stats.samples > 10_000, "case {k}: {stats:?}");
                assert_eq!(
                    (calls, bytes),
                    (0, 0),
                    "{primary:?}, case {k} (view {v}, settings {s}): allocations, bytes"
                );
                assert!(
                    buffers.image().data.iter().zip(&fresh[k]).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "case {k}: reused buffers changed the image"
                );
            }
        });
    }
}

/// The sensor stage after a render (optics, PSF, detector, ADC) allocates its output
/// and a few working buffers per frame, but nothing per row or per pixel: the count does
/// not grow with the frame (the PSF's gather lists were one allocation per row and column).
#[test]
fn sensor_stage_allocates_per_frame_not_per_row() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let scene: Scene = hilcam_core::scene::file::load(std::path::Path::new("scenes/satellite.toml")).unwrap();
    assert!(scene.sensor.optics.psf.is_some(), "the shipped camera has a PSF");
    let calls_at = |size: u32| {
        let camera = scaled_camera(&scene, size, size, [0.0, 0.0]);
        let sensor = hilcam_core::sensor::Sensor::new(&camera, &scene.sensor).unwrap();
        let view = View::new(&camera, &scene.pose, scene.frame_origin_body, scene.bounds);
        let settings = RenderSettings { spp: Spp::whole(1), depth: 1, ..RenderSettings::default() };
        let (img, _) = render(&scene, &view, &RenderOptions::new(settings, 3).with_primary(PrimaryVisibility::Raster));
        // A single-thread pool: rayon's own job bookkeeping is not what is counted.
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        pool.install(|| {
            sensor.apply(&img, 1).unwrap();
            let (out, calls, bytes) = allocations_during(|| sensor.apply(&img, 2).unwrap());
            assert!(out.stats.mean_dn > 0.0, "{size}²: a black frame proves nothing");
            (calls, bytes)
        })
    };
    let (small, large) = (calls_at(128), calls_at(512));
    // Measured: 17 calls at either size (with per-row gather lists: 1033 and 4105).
    assert!(small.0 == large.0 && large.0 <= 24, "allocations per frame: {small:?} at 128², {large:?} at 512²");
}

/// Reused buffers clear only the rows the last frame wrote while the image size and the
/// background stay; a scene with another background (or a smaller frame) clears it all.
#[test]
fn reused_buffers_follow_a_change_of_background() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let path = std::path::Path::new("scenes/satellite.toml");
    let dark: Scene = hilcam_core::scene::file::load(path).unwrap();
    let mut lit: Scene = hilcam_core::scene::file::load(path).unwrap();
    lit.background = 0.25;
    let camera = scaled_camera(&dark, 96, 96, [0.0, 0.0]);
    let view = View::new(&camera, &dark.pose, dark.frame_origin_body, dark.bounds);
    let settings = RenderSettings { spp: Spp::whole(1), depth: 2, ..dark.render };
    let fresh = |s: &Scene| render(s, &view, &RenderOptions::new(settings, 0)).0.data;
    let (want_dark, want_lit) = (fresh(&dark), fresh(&lit));
    assert!(want_lit.iter().filter(|&&v| v == 0.25).count() > 96 * 96 / 2, "most of the frame is sky");
    let mut buffers = FrameBuffers::<()>::default();
    for (k, (scene, want)) in
        [(&dark, &want_dark), (&lit, &want_lit), (&lit, &want_lit), (&dark, &want_dark)].into_iter().enumerate()
    {
        render_into(&mut buffers, scene, &view, &RenderOptions::new(settings, 0));
        let got = &buffers.image().data;
        assert!(got.iter().zip(want).all(|(a, b)| a.to_bits() == b.to_bits()), "frame {k}: the reused image differs");
    }
}
